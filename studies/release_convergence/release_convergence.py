"""How far the watching throw is converged in the plant's time step, for the
shipped throw and others; from stored `timestep_study.py --flights-only`
results (no simulation).

    .venv/bin/python studies/release_convergence/release_convergence.py \
        [--flights studies/timestep_convergence/timestep_flights.json \
                    studies/timestep_convergence/timestep_flights_hold08.json] \
        [--out studies/release_convergence/release_convergence.json]

Each flights file holds, per object, the watching throw at a coarse and a
fine step (1 and 0.25 ms) and each step's shift from the finest: of the
object's angular velocity in its own frame when the throw ends (w_O, rad/s),
of the planned catch point (mm) and of the catch moment (ms). Per file, over
the objects both steps planned: the median and mean spin shift, how many
catch points moved at most 10 mm, 10-30 mm and more (the hand absorbs
0-22 mm: studies/catch_tolerance/catch_tolerance.json), and how many are caught 8 ms or
more apart (two sensor samples). A release that is converged in the step
would shift little; the hand's tolerance is the scale that matters.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, check_output_path, field_error

TIMESTEP = Path(__file__).resolve().parents[1] / "timestep_convergence"
FLIGHTS = (TIMESTEP / "timestep_flights.json",
           TIMESTEP / "timestep_flights_hold08.json")


def summarize(flights: dict) -> dict:
    """The module docstring's figures for one flights file's contents."""
    steps = flights.get("steps_ms")
    objects = flights.get("objects")
    if not isinstance(objects, dict) or not steps or len(steps) < 2:
        raise field_error("flights", f"keys {sorted(flights)}",
                          "timestep_study.py --flights-only output with "
                          "'steps_ms' (2 or more) and 'objects'")
    coarse = f"{max(steps):g}"
    spin, moved, late = [], [], []
    for name, s in objects.items():
        shift = s["shift_from_finest"][coarse]
        if shift.get("catch_p_mm") is None:  # a step with no plan
            continue
        spin.append(shift["w_O_rad_per_s"])
        moved.append(shift["catch_p_mm"])
        late.append(abs(shift["catch_t_ms"]))
    spin, moved, late = map(np.array, (spin, moved, late))
    return {"scenario": flights.get("scenario"),
            "steps_ms": [max(steps), min(steps)],
            "objects": len(objects), "planned_at_both": len(spin),
            "spin_shift_rad_per_s": {"median": round(float(np.median(spin)), 3),
                                     "mean": round(float(spin.mean()), 3)},
            "catch_point_moved_mm": {
                "median": round(float(np.median(moved)), 1),
                "at_most_10": int(np.sum(moved <= 10)),
                "10_to_30": int(np.sum((moved > 10) & (moved <= 30))),
                "over_30": int(np.sum(moved > 30))},
            "caught_8_ms_or_more_apart": int(np.sum(late >= 8))}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--flights", nargs="+", type=Path, default=list(FLIGHTS))
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_suffix(".json"))
    args = parser.parse_args(argv)
    try:
        check_output_path("--out", args.out)
        result = {}
        for path in args.flights:
            try:
                flights = json.loads(path.read_text())
            except (OSError, ValueError) as e:
                raise field_error("--flights", str(path), f"a readable JSON "
                                  f"file ({type(e).__name__})") from None
            try:
                result[path.name] = summarize(flights)
            except InputError as e:
                raise InputError(f"{path}: {e}") from None
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    for name, r in result.items():
        m = r["catch_point_moved_mm"]
        print(f"{name} ({r['scenario'] or 'shipped'}): {r['planned_at_both']}"
              f" objects; spin shift median {r['spin_shift_rad_per_s']['median']}"
              f" mean {r['spin_shift_rad_per_s']['mean']} rad/s; catch point "
              f"median {m['median']} mm, <=10 mm {m['at_most_10']}, 10-30 "
              f"{m['10_to_30']}, >30 {m['over_30']}; caught >= 8 ms apart "
              f"{r['caught_8_ms_or_more_apart']}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
