"""The flight predictor: the paper's proposed first model (§VII), which
makes the watching throw unnecessary. A physics model of the separation
with a learned residual; nothing is simulated at planning time.

What it predicts: the object's state at the end of the throw
(free_time_s, the object in free flight), from the object's geometry and
mass properties and the scenario's throw.

The model (rigid ride): the object lies still on the open palm at the
toss's start pose (its rest pose, station.start_pose.start_poses: the object's
static equilibrium on the palm, found by the same relaxation every
episode starts from; the throw's initial condition, which on a robot is
the object's pose in the open hand before the throw, seen, not
predicted),
rides on the palm as one rigid body with it, and leaves it as the brake's
deceleration passes g (palm_toss.separation_s) with the palm's velocity
and angular velocity at that instant (palm_toss.palm_twist_at, from the
toss's designed palm motion, not the arm's simulated one); then it flies
free (planning/free_flight.propagate: gravity and Euler's equations) to
free_time_s. The palm toss was designed for this (no finger touches the
object, every contact unloads at once).

The residual: the training objects' mean deviation of their watched
states (`regrasp-drake dataset` stores each one's state at free_time_s)
from the model, in the centre of mass's position and velocity, the
orientation (a rotation vector in W) and the angular velocity (in W); it
absorbs what the model leaves out (the arm's tracking of the palm's
motion, the roll's centripetal terms at separation).

How well it predicts (`regrasp-drake train-flight`'s report,
models/flight_predictor.json.report.json; docs/results.md, "First throw"):
the rigid ride alone, no fitted number, puts the state at free_time_s of
the 5 Table 1 and 6 held-out objects within 0.5 mm, 4 mm/s, 0.1° of axis
and 0.05 rad/s of spin of the watched one. The model it replaces (a ridge
regression on three object features, with the orientation and the spin
the training means) erred 2–13 mm, 7–67 mm/s, 1–17° of axis and
0.3 rad/s there: it did not know how an object rests on the palm (Table
1's rows 1–3 lie with their axis tilted 14.5°) and mixed the spin of the
objects that roll about their axis on the palm into everyone's.

Stored as JSON (numbers only): nothing is unpickled when it is loaded.
"""

import math
from pathlib import Path

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis, Quaternion
from pydrake.math import RotationMatrix

from regrasp_drake import atomic_io
from regrasp_drake import progress as progress_lines
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.input_files import load_json, load_tagged_json
from regrasp_drake.planning.free_flight import (
    as_watched,
    central_inertia,
    propagate,
    sampled_flight,
)
from regrasp_drake.station import throw
from regrasp_drake.station.palm_toss import (
    TossDesign,
    palm_twist_at,
    separation_s,
)
from regrasp_drake.station.start_pose import start_poses
from regrasp_drake.station.throw import free_time_s
from regrasp_drake.throw_catch import plan_catch, watch, with_release
from regrasp_drake.world.objects import load_catalogue

_FORMAT = "regrasp_drake.FlightPredictor/3"
# The residual's groups, their rows in _targets and their bounds in a saved
# predictor (load): the shipped ones are below 1 mm, 5 mm/s, 0.02 rad and
# 0.05 rad/s.
RESIDUALS = {"p_Cm_m": (slice(0, 3), 0.1),
             "v_Cm_m_per_s": (slice(3, 6), 1.0),
             "rotation_W_rad": (slice(6, 9), 0.5),
             "w_W_rad_per_s": (slice(9, 12), 5.0)}


def _toss_design(scenario) -> TossDesign:
    if not throw.is_toss(scenario.throw):
        raise field_error("throw.kind", scenario.throw.kind,
                          "'palm_toss' (the flight predictor models the "
                          "palm toss's release)")
    return TossDesign.of(scenario.throw.toss)


def rigid_ride_state(scenario, obj) -> np.ndarray:
    """The model's state of the object at free_time_s (13 rows, as logged):
    riding rigidly on the palm from its rest pose until separation_s, then
    in free flight."""
    design = _toss_design(scenario)
    X_WP0, X_WO0 = start_poses(scenario, obj)
    t_sep = separation_s(design, scenario.gravity_m_per_s2)
    X_WP, w_W, v_WP = palm_twist_at(design, X_WP0, t_sep)
    X_WO = X_WP @ X_WP0.inverse() @ X_WO0
    v_WO = v_WP + np.cross(w_W, X_WO.translation() - X_WP.translation())
    state = np.concatenate([X_WO.rotation().ToQuaternion().wxyz(),
                            X_WO.translation(), w_W, v_WO])
    settle = scenario.throw.settle_s
    return propagate(state, [settle + t_sep, free_time_s(scenario)],
                     p_OCm=obj.p_OCm, I_CmCm_O=central_inertia(obj),
                     gravity_W=[0.0, 0.0, -scenario.gravity_m_per_s2])[:, -1]


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


def _targets(obj, state, R_model: RotationMatrix) -> np.ndarray:
    """p_Cm, v_Cm, the rotation vector of R_WO relative to R_model, and
    w_WO, all in W."""
    R = _R(state[:4])
    p_OCm_W = R.matrix() @ obj.p_OCm
    w = np.asarray(state[7:10], float)
    return np.concatenate([state[4:7] + p_OCm_W,
                           state[10:13] + np.cross(w, p_OCm_W),
                           _rotvec(R @ R_model.inverse()), w])


def _state(obj, targets, R_model: RotationMatrix) -> np.ndarray:
    """The 13-row state of _targets' values (their inverse)."""
    R = _from_rotvec(targets[6:9]) @ R_model
    p_OCm_W = R.matrix() @ obj.p_OCm
    w = targets[9:12]
    return np.concatenate([R.ToQuaternion().wxyz(), targets[0:3] - p_OCm_W,
                           w, targets[3:6] - np.cross(w, p_OCm_W)])


def _residual(scenario, obj, state) -> np.ndarray:
    """The watched state's deviation from the model's, as _targets."""
    model = rigid_ride_state(scenario, obj)
    R_model = _R(model[:4])
    return (_targets(obj, state, R_model) - _targets(obj, model, R_model))


class FlightPredictor:
    """Predicts an object's free-flight state at free_time_s(scenario)."""

    def __init__(self, data: dict):
        self._d = data
        self._residual = np.concatenate(
            [np.asarray(data["residual"][k], float) for k in RESIDUALS])

    # ---- fitting -------------------------------------------------------
    @staticmethod
    def fit(objects, states, *, scenario) -> "FlightPredictor":
        """objects: ObjectSpecs; states: their 13-row free-flight states at
        free_time_s(scenario) (quaternion, p_WO, w_WO, v_WO). The residual
        is the mean of their deviations from the rigid ride."""
        mean = np.mean([_residual(scenario, o, s)
                        for o, s in zip(objects, states)], axis=0)
        return FlightPredictor({
            "format": _FORMAT, "model": "rigid ride",
            "t_free_s": free_time_s(scenario),
            "separation_s": separation_s(_toss_design(scenario),
                                         scenario.gravity_m_per_s2),
            "residual": {k: [float(x) for x in mean[rows]]
                         for k, (rows, _) in RESIDUALS.items()},
            "trained_on": [o.name for o in objects]})

    # ---- prediction ----------------------------------------------------
    def t_free_s(self) -> float:
        return float(self._d["t_free_s"])

    def residual(self) -> dict:
        """The fitted residual, by group (RESIDUALS' keys): 3 numbers each."""
        return {k: list(v) for k, v in self._d["residual"].items()}

    def check_scenario(self, scenario) -> None:
        """InputError, naming the field, when the predictor was fitted for
        another throw than the scenario's."""
        for field, value, expected in (
                ("t_free_s", self.t_free_s(), free_time_s(scenario)),
                ("separation_s", self._d["separation_s"], separation_s(
                    _toss_design(scenario), scenario.gravity_m_per_s2))):
            if abs(value - expected) > 1e-9:
                raise field_error(f"flight predictor: {field}", value,
                                  f"{expected:.6g} s, the scenario's throw "
                                  "(fit it on this scenario's data set: "
                                  "`regrasp-drake train-flight`)")

    def predict_state(self, obj, scenario) -> np.ndarray:
        """The predicted 13-row state at t_free_s (check_scenario first)."""
        self.check_scenario(scenario)
        model = rigid_ride_state(scenario, obj)
        R_model = _R(model[:4])
        return _state(obj, _targets(obj, model, R_model) + self._residual,
                      R_model)

    def predict_flight(self, obj, scenario, duration_s: float = 1.6):
        """The predicted flight, sampled at the sensors' period: (t, states)
        like a watched episode's logs."""
        return sampled_flight(self.predict_state(obj, scenario),
                              self.t_free_s(), obj, scenario, duration_s)

    def as_watched(self, obj, scenario):
        """The predicted flight in the shape plan_catch reads (.logs.t,
        .logs.object_state)."""
        return as_watched(*self.predict_flight(obj, scenario))

    def plan(self, obj, scenario, ik):
        """plan_catch on the predicted flight, with its state at the
        release time kept as the plan's release_state (`with_release`, as
        for a watched flight; none when the flight has no sample then): the
        catching throw compares its own release with it and corrects the
        palm (`throw_catch.release_correction`). InputError when the
        predicted flight has no reachable catch point."""
        flight = self.as_watched(obj, scenario)
        return with_release(plan_catch(scenario, obj, ik, flight), scenario,
                            flight)

    # ---- files ---------------------------------------------------------
    def save(self, path) -> Path:
        path = Path(path)
        atomic_io.write_json(path, self._d, indent=None)
        return path

    @staticmethod
    def load(path) -> "FlightPredictor":
        """The predictor saved at path; InputError naming the file and the
        field for a file that is not one (read within the limits of
        input_files: size, nesting, finite numbers)."""
        path = Path(path)
        data = load_tagged_json(path, "flight predictor file", _FORMAT,
                                "regrasp-drake train-flight")
        for key in ("t_free_s", "separation_s"):
            t = data.get(key)
            if type(t) not in (int, float) or not 0 < t < 10:
                raise field_error(f"{path}: {key}", t, "a time in (0, 10) s")
        residual = data.get("residual")
        if not isinstance(residual, dict) or set(residual) != set(RESIDUALS):
            raise field_error(f"{path}: residual", residual,
                              f"an object with the keys {list(RESIDUALS)}")
        for key, (_, bound) in RESIDUALS.items():
            v = residual[key]
            if not (isinstance(v, list) and len(v) == 3
                    and all(type(x) in (int, float) and math.isfinite(x)
                            and abs(x) <= bound for x in v)):
                raise field_error(f"{path}: residual.{key}", v,
                                  f"3 finite numbers within ±{bound:g}")
        return FlightPredictor(data)


def flight_errors(predicted_plan, actual_plan, predicted_flight=None,
                  actual_flight=None) -> dict:
    """Catch position (mm), v_catch (m/s), catch time (ms) and axis (deg)
    differences between the plans. With both flights (watched-episode
    shaped), also where the predicted flight has the object at the actual
    plan's catch moment: its horizontal offset (mm) and axis (deg) there,
    which is what the waiting hand would meet."""
    a, b = predicted_plan.catch_point, actual_plan.catch_point
    out = {"position_mm": round(1000 * float(np.linalg.norm(a.p_WO - b.p_WO)), 1),
           "v_catch_m_per_s": round(abs(a.v_catch - b.v_catch), 3),
           "time_ms": round(1000 * abs(a.t_s - b.t_s), 1),
           "axis_deg": round(_angle_deg(a.y_W, b.y_W), 2)}
    if predicted_flight is not None and actual_flight is not None:
        x_p = _sample_at(predicted_flight, b.t_s)
        x_a = _sample_at(actual_flight, b.t_s)
        out["offset_at_catch_mm"] = round(
            1000 * float(np.linalg.norm(x_p[4:6] - x_a[4:6])), 1)
        out["axis_at_catch_deg"] = round(_angle_deg(
            _R(x_p[:4]).matrix()[:, 1], _R(x_a[:4]).matrix()[:, 1]), 2)
    return out


def state_errors(obj, predicted_state, actual_state) -> dict:
    """How far a predicted free-flight state (13, as logged) is from the
    actual one, component by component: the centre of mass's position (mm)
    and velocity (m/s), the object's axis y_O (deg) and whole orientation
    (deg, the angle of the rotation between them), and the angular velocity
    (rad/s, the norm of the difference, in W). The catch plan's errors
    (flight_errors) follow from these through the free flight."""
    out = {}
    R_p, R_a = _R(predicted_state[:4]), _R(actual_state[:4])
    t_p, t_a = _targets(obj, predicted_state, R_a), _targets(obj, actual_state, R_a)
    out["release_position_mm"] = round(
        1000 * float(np.linalg.norm(t_p[0:3] - t_a[0:3])), 1)
    out["release_velocity_m_per_s"] = round(
        float(np.linalg.norm(t_p[3:6] - t_a[3:6])), 3)
    out["release_axis_deg"] = round(_angle_deg(R_p.matrix()[:, 1],
                                               R_a.matrix()[:, 1]), 2)
    out["release_orientation_deg"] = round(math.degrees(
        (R_p @ R_a.inverse()).ToAngleAxis().angle()), 2)
    out["release_spin_rad_per_s"] = round(float(np.linalg.norm(
        np.asarray(predicted_state[7:10]) - actual_state[7:10])), 2)
    return out


def _angle_deg(a, b) -> float:
    return math.degrees(math.acos(min(1.0, abs(float(np.asarray(a) @ b)))))


def _sample_at(watched, t_s):
    k = int(np.argmin(np.abs(watched.logs.t - t_s)))
    return watched.logs.object_state[:, k]


def _compare(scenario, obj, ik, predicted, actual) -> dict:
    """flight_errors between two watched-shaped flights, or the error when
    either has no reachable catch point."""
    row = {}
    try:
        actual_plan = plan_catch(scenario, obj, ik, actual)
    except InputError as e:
        return {"error": f"actual flight: {e}"}
    try:
        predicted_plan = plan_catch(scenario, obj, ik, predicted)
    except InputError as e:
        return {"error": f"predicted flight: {e}"}
    row |= flight_errors(predicted_plan, actual_plan, predicted, actual)
    return row


def cross_validate(objects, states, scenario, ik, *,
                   progress=None) -> list[dict]:
    """Leave-one-geometry-out cross-validation: for each training geometry,
    the predictor fitted on the other geometries' objects plans the catch
    of that geometry's objects; the actual flight is the recorded state
    propagated (planning/free_flight.py, 1–2 mm from Drake's flight). One
    row per object, as flight_errors."""
    t0 = free_time_s(scenario)
    rows = []
    with progress_lines.bar(len(objects), "cross-validation", "objects",
                            enabled=progress is not None) as shown:
        for geometry in sorted({o.geometry for o in objects}):
            train = [(o, s) for o, s in zip(objects, states)
                     if o.geometry != geometry]
            predictor = FlightPredictor.fit([o for o, _ in train],
                                            [s for _, s in train],
                                            scenario=scenario)
            for obj, state in zip(objects, states):
                if obj.geometry != geometry:
                    continue
                actual = as_watched(*sampled_flight(state, t0, obj, scenario))
                row = {"object": obj.name, "geometry": geometry} | _compare(
                    scenario, obj, ik, predictor.as_watched(obj, scenario),
                    actual)
                row |= state_errors(
                    obj, predictor.predict_state(obj, scenario), state)
                rows.append(row)
                shown.update()
                if progress is not None:
                    progress_lines.say(f"cv {obj.name}: {row}", progress)
    return rows


def summarize(rows) -> dict:
    """Mean and maximum of each error over the rows with a plan, and how
    many rows had a reachable plan on both flights."""
    planned = [r for r in rows if "error" not in r]
    keys = ("position_mm", "axis_deg", "v_catch_m_per_s", "time_ms",
            "offset_at_catch_mm", "axis_at_catch_deg", "release_position_mm",
            "release_velocity_m_per_s", "release_axis_deg",
            "release_orientation_deg", "release_spin_rad_per_s")
    out = {"objects": len(rows), "planned": len(planned)}
    for k in keys:
        values = [r[k] for r in planned if k in r]
        if values:
            out[k] = {"mean": round(float(np.mean(values)), 3),
                      "max": round(float(np.max(values)), 3)}
    return out


# The bounds of a free-flight state's p_WO (m), w_WO (rad/s) and v_WO (m/s),
# by their first row; its quaternion is a unit one within 0.05 (a logged
# state's is within 0.01).
_STATE_BOUNDS = ((4, 3.0), (7, 200.0), (10, 50.0))


def dataset_flights(data_dir) -> tuple[list, list]:
    """The data set's training flights: (ObjectSpecs, their free-flight
    states at free_time_s), one per object in name order (an object's other
    catch points, <object>@k, share its watched throw)."""
    data_dir = Path(data_dir)
    plans = sorted(p for p in (data_dir / "plans").glob("*.json")
                   if "@" not in p.stem)
    catalogue = load_catalogue() if plans else {}
    objects, states = [], []
    for path in plans:
        entry = load_json(path)
        if not isinstance(entry, dict) or "free_flight" not in entry:
            raise InputError(f"{path}: free_flight missing (a data set from "
                             "an older version: run `regrasp-drake dataset` "
                             "again)")
        try:
            state = np.asarray(entry["free_flight"]["state"], float)
            ok = (state.shape == (13,) and isinstance(entry["object"], str)
                  and abs(np.linalg.norm(state[:4]) - 1.0) <= 0.05
                  and all(np.abs(state[k:k + 3]).max() <= bound
                          for k, bound in _STATE_BOUNDS))
        except (KeyError, TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise InputError(f"{path}: free_flight.state or object malformed, "
                             "expected 13 numbers (a unit quaternion, p_WO "
                             "within ±3 m, w_WO within ±200 rad/s, v_WO "
                             "within ±50 m/s) and an object name")
        if entry["object"] not in catalogue:
            raise field_error(f"{path}: object", entry["object"],
                              "an object of the catalogue")
        objects.append(catalogue[entry["object"]])
        states.append(state)
    return objects, states


def train_from_dataset(data_dir, scenario, out, *, ik, eval_objects=(),
                       progress=None) -> dict:
    """Fits the predictor on the data set's free-flight states (every
    training object's), writes it to `out`, and reports its
    leave-one-geometry-out cross-validation and its errors on
    `eval_objects` (ObjectSpecs never trained on), each watched once to know
    its true flight: catch position (mm), v_catch (m/s), catch time (ms),
    axis (degrees), and the offset and axis at the actual catch moment;
    and, for both, the predicted state after the throw against the actual
    one (state_errors, the release_* fields; for the evaluation objects
    also the rigid ride's alone, without the residual). Also writes the report
    (report_path: <out>.report.json)."""
    objects, states = dataset_flights(data_dir)
    if len(objects) < 10:
        raise InputError(f"{data_dir}: {len(objects)} flights, expected at "
                         "least 10 to fit the flight predictor")
    predictor = FlightPredictor.fit(objects, states, scenario=scenario)
    predictor.save(out)
    cv_rows = cross_validate(objects, states, scenario, ik,
                             progress=progress)
    rows = []
    t0 = free_time_s(scenario)
    for obj in progress_lines.iterate(eval_objects, len(eval_objects),
                                      "evaluation", "objects",
                                      enabled=progress is not None):
        watched = watch(scenario, obj, ik)
        row = {"object": obj.name, "set": obj.set} | _compare(
            scenario, obj, ik, predictor.as_watched(obj, scenario), watched)
        k = int(np.argmin(np.abs(watched.logs.t - t0)))
        if abs(watched.logs.t[k] - t0) < 1e-9:  # a flight logged then
            actual = watched.logs.object_state[:, k]
            row |= state_errors(obj, predictor.predict_state(obj, scenario),
                                actual)
            row["rigid_ride_only"] = state_errors(
                obj, rigid_ride_state(scenario, obj), actual)
        rows.append(row)
        if progress is not None:
            progress_lines.say(f"{obj.name}: {row}", progress)
    report = {"trained_on": len(objects), "model": "rigid ride",
              "residual": predictor.residual(),
              "cross_validation": {"summary": summarize(cv_rows),
                                   "objects": cv_rows},
              "evaluation": {"summary": summarize(rows), "objects": rows}}
    atomic_io.write_json(report_path(out), report)
    return report


def report_path(out) -> Path:
    """Where train_from_dataset writes the report of the predictor at out."""
    return Path(str(out) + ".report.json")
