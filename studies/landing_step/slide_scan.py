"""Where holdout-dumbbell-d150 comes to rest under flip +30 against the palm's
place along its axis (FINDINGS §18): X's pick (cell (7, 1), the palm turning
with the pitch) caught from the predicted flight's plan moved by each shift,
at the rehearsal's steps (the shipped ones) and at the finer judge's, the
palm corrected at the release as the throw corrects it
(`rehearsal.catches`). JSON to
models/results/landing_step/d150_flip30_slide_scan.json.

    .venv/bin/python studies/landing_step/slide_scan.py
"""
import regrasp_drake  # noqa: F401, I001 (first: it pins NumPy's kernels)
import torch

from regrasp_drake import atomic_io
from regrasp_drake.learning import rehearsal as rh
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.throw_catch import shifted_along_axis
from regrasp_drake.world.objects import resolve_object

FINER = ("{plant_config: {time_step: 0.000125}, landing_time_step_s: "
         "0.00003125, target_catch_time_step_s: 0.000125}")
SHIFTS_MM = (0.0, -2.0, -4.0, -5.0, -6.0, -7.0, -8.0, -9.0, -14.0, -18.8)
CELL = (7, 1)


def main() -> None:
    torch.set_num_threads(1)
    target = Target("flip", 30.0)
    shipped = with_target(load_scenario(), target)
    obj = resolve_object(name="holdout-dumbbell-d150")
    ik = ArmIk(shipped.directives)
    plan = FlightPredictor.load(MODELS_DIR / "flight_predictor.json").plan(
        obj, shipped, ik)
    steps = {"shipped": rh.rehearsal_scenario(
                 rh.mode_scenario(shipped, "pitch")),
             "finer": rh.mode_scenario(
                 with_target(load_scenario(text=FINER), target), "pitch")}
    rows = []
    for label, scenario in steps.items():
        for mm in SHIFTS_MM:
            moved = shifted_along_axis(plan, 1e-3 * mm, ik)
            r = rh.catches(scenario, obj, ik, moved, [CELL])[0]
            rows.append({"steps": label, "palm_shift_mm": mm,
                         "in_target": bool(r.success),
                         "grasp": r.achieved_grasp})
            print(rows[-1], flush=True)
    atomic_io.write_json(MODELS_DIR / "results" / "landing_step"
                         / "d150_flip30_slide_scan.json",
                         {"object": obj.name, "target": "flip:+30",
                          "cell": list(CELL), "mode": "pitch", "rows": rows})


if __name__ == "__main__":
    main()
