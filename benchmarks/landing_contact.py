"""The contact law through a target catch's landing, at several plant steps.

    .venv/bin/python benchmarks/landing_contact.py [--cases NAME:KIND:MM ...]
        [--steps null 0.00025 0.000125 0.0000625]
        [--json out/landing_contact.json]

Each case is the first-throw catch of `regrasp-drake regrasp --object NAME
--target KIND --offset-mm MM --first-throw --max-throws 1`, run once per
landing step (`landing_time_step_s`; "null": the catch's 1 ms step
throughout, the design before the landing's step). A Simulator monitor,
set on every simulator the episode runs in (the throw's, the catch's, the
landing's), reads the plant's contact results after every step; it changes
nothing in the simulation. For the object's point contacts with the palm
(its pads) from its first touch of the palm after the throw (the landing)
to --window-ms after, it
prints:

- `law`: the contact force against the point-contact law the scenario sets,
  fn / (k·x), k the two geometries' stiffnesses in series (as Drake
  combines them), x the depth, over the contacts at rest along their normal
  (|separation speed| < 0.01 m/s, where Hunt–Crossley's damping adds under
  10 % at the scenario's 10 s/m) that carry more than 0.5 N by the law:
  the median and the 10th percentile (1: the contact the scenario
  describes; a contact the step does not resolve carries far less);
- `depth_mm`: the deepest penetration;
- `spin`: the object's rate about the palm's x (across the palm), [rad/s],
  the step before its first touch, its largest in the window, and at the
  window's end;
- the verdict and the achieved grasp.

Drake's reference for the law: multibody/plant/multibody_plant.h
(DiscreteContactApproximation; Hunt–Crossley) and
geometry/proximity_properties.h (point_contact_stiffness). Writes JSON.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import sys

import numpy as np
import torch
from pydrake.systems.framework import EventStatus

from regrasp_drake import atomic_io
from regrasp_drake.episode import episode as episode_module
from regrasp_drake.errors import InputError
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import learn
from regrasp_drake.paths import MODELS_DIR, OUT_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.world.objects import resolve_object

# The landings that the step decided (issue 60): a cylinder flat
# across a row of pads, a flip with spin, a light object that sank.
DEFAULT_CASES = ["holdout-dumbbell-d300:keep:-30",
                 "holdout-scraper-d180:flip:0",
                 "holdout-mallet-d280:flip:-30",
                 "table1-row2:flip:0"]


class ContactRecorder:
    """Simulator monitors that record the object's contacts, one per
    simulator the episode runs in."""

    def __init__(self, window_s: float):
        self.window_s = window_s
        self.t_touch = None
        self.flying = False  # the object has left the palm (the throw)
        self.rows = []    # (t, k, depth, fn, v_sep) per point contact
        self.spin = []    # (t, rate about the palm's x)

    def attach(self, simulator, episode) -> None:
        station = episode.station
        plant, body = station.plant, station.object_body
        palm = plant.GetFrameByName("palm_surface", station.hand)
        inspector = station.scene_graph.model_inspector()
        palm_body = plant.GetBodyByName("palm", station.hand).index()

        def stiffness(geometry_id):
            return inspector.GetProximityProperties(geometry_id).GetProperty(
                "material", "point_contact_stiffness")

        def monitor(root_context):
            t = root_context.get_time()
            if self.t_touch is not None and t > self.t_touch + self.window_s:
                return EventStatus.Succeeded()
            pc = plant.GetMyContextFromRoot(root_context)
            results = plant.get_contact_results_output_port().Eval(pc)
            touching = []
            for i in range(results.num_point_pair_contacts()):
                info = results.point_pair_contact_info(i)
                a, b = info.bodyA_index(), info.bodyB_index()
                if {a, b} != {body.index(), palm_body}:
                    continue
                pair = info.point_pair()
                k1, k2 = stiffness(pair.id_A), stiffness(pair.id_B)
                fn = float(np.dot(info.contact_force(), pair.nhat_BA_W))
                touching.append((t, k1 * k2 / (k1 + k2), pair.depth, abs(fn),
                                 info.separation_speed()))
            if not touching and t > 0.0:
                self.flying = True
            if not self.flying:
                return EventStatus.Succeeded()  # before the release
            if touching and self.t_touch is None:
                self.t_touch = t
            self.rows += touching
            R_WP = palm.CalcPoseInWorld(pc).rotation().matrix()
            w = plant.EvalBodySpatialVelocityInWorld(pc, body).rotational()
            w_palm = palm.CalcSpatialVelocityInWorld(pc).rotational()
            self.spin.append((t, float((R_WP.T @ (w - w_palm))[0])))
            return EventStatus.Succeeded()

        simulator.set_monitor(monitor)

    def figures(self) -> dict:
        if self.t_touch is None:
            return {"touched": False}
        rows = np.array(self.rows)
        _, k, x, fn, v_sep = rows.T
        expected = k * x
        loaded = (expected > 0.5) & (np.abs(v_sep) < 0.01)
        ratio = fn[loaded] / expected[loaded]
        t, spin = np.array(self.spin).T
        before = spin[np.searchsorted(t, self.t_touch) - 1]
        end = min(np.searchsorted(t, self.t_touch + self.window_s), len(t) - 1)
        after = spin[end]
        during = spin[np.searchsorted(t, self.t_touch):end + 1]
        peak = during[np.argmax(np.abs(during))]
        return {"touched": True, "t_touch": round(self.t_touch, 5),
                "contacts": int(loaded.sum()),
                "law_median": round(float(np.median(ratio)), 3)
                if ratio.size else None,
                "law_p10": round(float(np.percentile(ratio, 10)), 3)
                if ratio.size else None,
                "depth_mm": round(1e3 * float(x.max()), 3),
                "spin_before": round(float(before), 2),
                "spin_after": round(float(after), 2),
                "spin_peak": round(float(peak), 2)}


def run_case(name, kind, offset_mm, step, *, model, ik, predictor,
             window_s) -> dict:
    scenario = load_scenario(text="{landing_time_step_s: %s}" % step)
    scenario = with_target(scenario, Target(kind, offset_mm))
    recorder = ContactRecorder(window_s)
    initialize, continue_with = (episode_module.initialize,
                                 episode_module.continue_with)

    def initialize_recorded(diagram, scenario):
        simulator = initialize(diagram, scenario)
        recorder.attach(simulator, diagram)
        return simulator

    def continue_recorded(simulator, episode, other, scenario):
        target = continue_with(simulator, episode, other, scenario)
        recorder.attach(target, other)
        return target

    episode_module.initialize = initialize_recorded
    episode_module.continue_with = continue_recorded
    try:
        # No throw kept from another case: each is simulated here, recorded.
        episode_module.THROWS.clear()
        result = learn(scenario, resolve_object(name=name), model, ik=ik,
                       max_throws=1, progress=None,
                       flight_predictor=predictor)
    finally:
        episode_module.initialize = initialize
        episode_module.continue_with = continue_with
    g = result.as_dict()["achieved_grasp"]
    return {"case": f"{name}:{kind}:{offset_mm:+g}", "landing_step": step,
            "success": result.success,
            "grasp": None if g is None else
            f"{g['kind']} {g['offset_mm']:+.1f} mm {g['tilt_deg']:.1f}°"
            } | recorder.figures()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=DEFAULT_CASES)
    parser.add_argument("--steps", nargs="+",
                        default=["null", "0.00025", "0.000125", "0.0000625"])
    parser.add_argument("--window-ms", type=float, default=60.0)
    parser.add_argument("--json", default=str(OUT_DIR / "landing_contact.json"))
    args = parser.parse_args(argv)
    try:
        cases = []
        for text in args.cases:
            name, kind, mm = text.split(":")
            cases.append((name, kind, float(mm)))
    except ValueError:
        print(f"landing_contact: error: --cases: got {text!r}, expected "
              "NAME:KIND:MM", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    scenario = load_scenario()
    model = load_weights(MODELS_DIR / scenario.catch.weights)[0]
    predictor = FlightPredictor.load(MODELS_DIR / "flight_predictor.json")
    ik = ArmIk(scenario.directives)
    rows = []
    print(f"{'case':34} {'landing step':>12} {'law med/p10':>12} "
          f"{'depth mm':>8} {'spin before→peak→after':>22}  verdict")
    for name, kind, mm in cases:
        for step in args.steps:
            try:
                row = run_case(name, kind, mm, step, model=model, ik=ik,
                               predictor=predictor,
                               window_s=args.window_ms / 1e3)
            except InputError as e:
                print(f"landing_contact: error: {e}", file=sys.stderr)
                return 2
            rows.append(row)
            law = (f"{row['law_median']}/{row['law_p10']}"
                   if row.get("law_median") is not None else "-")
            spin = (f"{row['spin_before']:+.1f}→{row['spin_peak']:+.1f}→"
                    f"{row['spin_after']:+.1f}" if row["touched"] else "-")
            print(f"{row['case']:34} {step:>12} {law:>12} "
                  f"{row.get('depth_mm', '-'):>8} {spin:>22}  "
                  f"{'in target' if row['success'] else 'missed'}, "
                  f"{row['grasp']}", flush=True)
            atomic_io.write_json(args.json, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
