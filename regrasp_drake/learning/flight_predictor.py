"""The flight predictor: the paper's proposed first network (§VII), which
makes the watching throw unnecessary.

What it learns: the object's state just after the throw (at the end of the
arm's throw trajectory, when the object is in free flight), from the object's
known mass properties. Inputs (standardized): mass (kg), h_cm and r_cm (m),
density d_obj (kg/m³), and the central principal moments of inertia in the
object frame, Ixx, Iyy, Izz (kg·m²). Outputs: the centre of mass's position
and velocity, the orientation (a rotation vector relative to the training
objects' mean orientation) and the angular velocity. The model is ridge
regression on the inputs and their pairwise products, fitted on the
training objects' watched flights (`regrasp-drake dataset` stores each
one's state at that moment).

What it does not learn: the free flight itself, which is physics (gravity
and Euler's equations, planning/free_flight.py), propagated from the
predicted state. The catch point and v_catch then come from the predicted
flight exactly as from a watched one. No simulator runs at planning time.

Stored as JSON (numbers only): nothing is unpickled when it is loaded.
"""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis, Quaternion
from pydrake.math import RotationMatrix

from regrasp_drake.errors import InputError
from regrasp_drake.planning.free_flight import propagate

INPUT_NAMES = ("mass", "h_cm", "r_cm", "d_obj", "Ixx", "Iyy", "Izz")
_FORMAT = "regrasp_drake.FlightPredictor"


def free_time_s(scenario) -> float:
    """The moment the predicted state is for: the end of the throw, [s]."""
    return scenario.throw.settle_s + scenario.throw.knot_times_s[-1]


def central_inertia(obj) -> np.ndarray:
    """The object's rotational inertia about its centre of mass, in O."""
    M = obj.spatial_inertia()
    return M.Shift(M.get_com()).CalcRotationalInertia().CopyToFullMatrix3()


def object_inputs(obj) -> np.ndarray:
    I_O = central_inertia(obj)
    return np.array([obj.mass, obj.h_cm, obj.r_cm, obj.d_obj,
                     I_O[0, 0], I_O[1, 1], I_O[2, 2]], float)


def _expand(x):
    """Inputs, their pairwise products and squares (standardized inputs)."""
    n = len(x)
    products = [x[i] * x[j] for i in range(n) for j in range(i, n)]
    return np.concatenate([[1.0], x, products])


def _R(quaternion_wxyz):
    q = np.asarray(quaternion_wxyz, float)
    return RotationMatrix(Quaternion(q / np.linalg.norm(q)))


def _rotvec(R: RotationMatrix) -> np.ndarray:
    aa = R.ToAngleAxis()
    return aa.axis() * aa.angle()


def _from_rotvec(r) -> RotationMatrix:
    angle = float(np.linalg.norm(r))
    if angle < 1e-15:
        return RotationMatrix()
    return RotationMatrix(AngleAxis(angle, np.asarray(r) / angle))


class FlightPredictor:
    """Predicts an object's free-flight state at free_time_s(scenario)."""

    def __init__(self, data: dict):
        self._d = data
        self._mean = np.asarray(data["input_mean"])
        self._std = np.asarray(data["input_std"])
        self._W = np.asarray(data["weights"])
        self._R_ref = RotationMatrix(np.asarray(data["R_ref"]))

    # ---- fitting -------------------------------------------------------
    @staticmethod
    def fit(objects, states, *, t_free_s: float, ridge: float = 1e-3
            ) -> "FlightPredictor":
        """objects: ObjectSpecs; states: their 13-row free-flight states at
        t_free_s (quaternion, p_WO, w_WO, v_WO)."""
        X = np.array([object_inputs(o) for o in objects])
        mean, std = X.mean(axis=0), X.std(axis=0)
        std = np.where(std > 1e-12, std, 1.0)
        R_ref = _mean_rotation([_R(s[:4]) for s in states])
        Y = np.array([_targets(o, s, R_ref) for o, s in zip(objects, states)])
        A = np.array([_expand((x - mean) / std) for x in X])
        # Ridge: (AᵀA + λI) W = AᵀY, the intercept unpenalized.
        penalty = ridge * np.eye(A.shape[1])
        penalty[0, 0] = 0.0
        W = np.linalg.solve(A.T @ A + penalty, A.T @ Y)
        return FlightPredictor({
            "format": _FORMAT, "inputs": list(INPUT_NAMES),
            "t_free_s": t_free_s, "ridge": ridge,
            "input_mean": mean.tolist(), "input_std": std.tolist(),
            "weights": W.tolist(), "R_ref": R_ref.matrix().tolist(),
            "trained_on": [o.name for o in objects]})

    # ---- prediction ----------------------------------------------------
    def t_free_s(self) -> float:
        return float(self._d["t_free_s"])

    def predict_state(self, obj) -> np.ndarray:
        """The predicted 13-row state at t_free_s."""
        y = _expand((object_inputs(obj) - self._mean) / self._std) @ self._W
        p_Cm, v_Cm, r, w = y[0:3], y[3:6], y[6:9], y[9:12]
        R = _from_rotvec(r) @ self._R_ref
        p_OCm_W = R.matrix() @ obj.p_OCm
        state = np.empty(13)
        state[:4] = R.ToQuaternion().wxyz()
        state[4:7] = p_Cm - p_OCm_W
        state[7:10] = w
        state[10:13] = v_Cm - np.cross(w, p_OCm_W)
        return state

    def predict_flight(self, obj, scenario, duration_s: float = 1.6):
        """The predicted flight, sampled at the sensors' period: (t, states)
        like a watched episode's logs."""
        period = scenario.sensors.period_s
        t0 = self.t_free_s()
        t = t0 + period * np.arange(int(duration_s / period) + 1)
        states = propagate(self.predict_state(obj), t, p_OCm=obj.p_OCm,
                           I_CmCm_O=central_inertia(obj),
                           gravity_W=[0.0, 0.0, -scenario.gravity_m_per_s2])
        return t, states

    def as_watched(self, obj, scenario):
        """The predicted flight in the shape plan_catch reads (.logs.t,
        .logs.object_state)."""
        t, states = self.predict_flight(obj, scenario)
        return SimpleNamespace(logs=SimpleNamespace(t=t, object_state=states))

    # ---- files ---------------------------------------------------------
    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self._d) + "\n")
        return path

    @staticmethod
    def load(path) -> "FlightPredictor":
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: no such flight predictor file (run "
                             "`regrasp-drake train-flight` first)")
        try:
            data = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise InputError(f"{path}: not a flight predictor file ({e})") \
                from None
        if not isinstance(data, dict) or data.get("format") != _FORMAT:
            raise InputError(f"{path}: not a flight predictor file (format "
                             "tag missing)")
        n_in = len(INPUT_NAMES)
        n_terms = 1 + n_in + n_in * (n_in + 1) // 2
        try:
            W = np.asarray(data["weights"], float)
            ok = (W.shape == (n_terms, 12) and len(data["input_mean"]) == n_in
                  and len(data["input_std"]) == n_in
                  and np.asarray(data["R_ref"], float).shape == (3, 3)
                  and np.all(np.isfinite(W)) and float(data["t_free_s"]) > 0)
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise InputError(f"{path}: weights: malformed (expected a "
                             f"{n_terms}×12 finite matrix and its "
                             "normalization)")
        return FlightPredictor(data)


def _targets(obj, state, R_ref: RotationMatrix) -> np.ndarray:
    R = _R(state[:4])
    p_OCm_W = R.matrix() @ obj.p_OCm
    w = state[7:10]
    p_Cm = state[4:7] + p_OCm_W
    v_Cm = state[10:13] + np.cross(w, p_OCm_W)
    r = _rotvec(R @ R_ref.inverse())
    return np.concatenate([p_Cm, v_Cm, r, w])


def _mean_rotation(rotations) -> RotationMatrix:
    """The chordal mean of rotations (projected mean of their matrices)."""
    M = np.mean([R.matrix() for R in rotations], axis=0)
    u, _, vt = np.linalg.svd(M)
    R = u @ vt
    if np.linalg.det(R) < 0:
        u[:, -1] *= -1
        R = u @ vt
    return RotationMatrix(R)


def flight_errors(predicted_plan, actual_plan) -> dict:
    """Catch position (mm), v_catch (m/s) and catch time (ms) differences."""
    a, b = predicted_plan.catch_point, actual_plan.catch_point
    return {"position_mm": round(1000 * float(np.linalg.norm(a.p_WO - b.p_WO)), 1),
            "v_catch_m_per_s": round(abs(a.v_catch - b.v_catch), 3),
            "time_ms": round(1000 * abs(a.t_s - b.t_s), 1),
            "axis_deg": round(math.degrees(math.acos(min(1.0, abs(
                float(a.y_W @ b.y_W))))), 2)}


def train_from_dataset(data_dir, scenario, out, *, ik, eval_objects=(),
                       ridge: float = 1e-3, progress=None) -> dict:
    """Fits the predictor on the data set's free-flight states (every
    training object's), writes it to `out`, and reports its errors on
    `eval_objects` (ObjectSpecs never trained on), each watched once to know
    its true flight: catch position (mm), v_catch (m/s), catch time (ms),
    axis (degrees). Also writes the report as <out>.report.json."""
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    data_dir = Path(data_dir)
    plans = sorted((data_dir / "plans").glob("*.json"))
    objects, states = [], []
    for path in plans:
        entry = json.loads(path.read_text())
        if "free_flight" not in entry:
            raise InputError(f"{path}: free_flight missing (a data set from "
                             "an older version: run `regrasp-drake dataset` "
                             "again)")
        objects.append(resolve_object(name=entry["object"]))
        states.append(np.asarray(entry["free_flight"]["state"], float))
    if len(objects) < 10:
        raise InputError(f"{data_dir}: {len(objects)} flights, expected at "
                         "least 10 to fit the flight predictor")
    predictor = FlightPredictor.fit(objects, states,
                                    t_free_s=free_time_s(scenario),
                                    ridge=ridge)
    predictor.save(out)
    rows = []
    for obj in eval_objects:
        row = {"object": obj.name, "set": obj.set}
        try:
            actual = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
            predicted = plan_catch(scenario, obj, ik,
                                   predictor.as_watched(obj, scenario))
            row |= flight_errors(predicted, actual)
        except InputError as e:
            row["error"] = str(e)
        rows.append(row)
        if progress is not None:
            print(f"{obj.name}: {row}", file=progress, flush=True)
    report = {"trained_on": len(objects), "ridge": ridge,
              "inputs": list(INPUT_NAMES), "evaluation": rows}
    Path(str(out) + ".report.json").write_text(json.dumps(report, indent=1)
                                              + "\n")
    return report
