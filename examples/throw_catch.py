"""Throw a Table 1 object, watch its flight, and catch it with the shipped
planner's parameters; save the replay.

    .venv/bin/python examples/throw_catch.py [--object table1-row2]
        [--object-file examples/my_object.yaml] [--out out/throw_catch.html]
        [--target flip] [--offset-mm 0]

The learning phase cut to one catch attempt (`rd.regrasp` with
max_throws=2): throw 1 watches; the offline stage plans the catch; the
target's shipped planner picks the cell (h_catch, h_down): under a grasp
target the chooser that won its judging on unseen geometries
(models/planner_<target>.json: the learned planner, the best constant cell
or the paper's network; docs/planner.md), under `any` the paper's trained
network from (v_catch, h_cm, r_cm, d_obj, v_conv), quantized to its grid
cell; throw 2 catches, corrected at its release. Writes throw_catch.html
(the Meshcat replay of both throws, self-contained) and throw_catch.png
(the sensors of throw 2 over time) in out/ (at the top of the repository,
git-ignored; ./out when installed; --out elsewhere), and prints the
outcome and, last, the verdict on the target grasp (default flip, +0 mm:
end over end, the palm under the centre of mass; planning/grasp.py):
"flip, +0 mm: in the target grasp (held flip, +1 mm, tilt 13°)", or
"missed" and why ("keep, +0 mm: missed, tilted 27° > 20° (held keep,
+0 mm, tilt 27°)").
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake as rd  # noqa: I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

from regrasp_drake.errors import InputError
from regrasp_drake.paths import OUT_DIR


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", help="a catalogue object (default "
                        "table1-row2), or with --object-file one of the file's")
    parser.add_argument("--object-file", type=Path,
                        help="your own objects (its first unless --object)")
    parser.add_argument("--out", type=Path, default=OUT_DIR / "throw_catch.html")
    parser.add_argument("--target", default="flip",
                        choices=("keep", "flip", "turn", "any"),
                        help="the grasp to end in (default flip)")
    parser.add_argument("--offset-mm", type=float, default=0.0,
                        help="the palm centre along the object's axis from "
                             "its centre of mass, mm (default 0)")
    args = parser.parse_args()
    try:
        obj = rd.load_object(
            args.object or (None if args.object_file else "table1-row2"),
            file=args.object_file)
        run = rd.regrasp(obj, rd.Target(args.target, args.offset_mm),
                         max_throws=2, library=None, progress=None)
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    run.save_replay(args.out)
    run.plot(args.out.with_suffix(".png"))
    print(json.dumps(run.episode.summary() | {
        "network_output": [round(x, 4) for x in run.learning.raw_prediction],
        "chosen_by": run.learning.planner,
        "plan": run.plan.as_dict()}, indent=1))
    print(f"replay: {args.out}  sensors: {args.out.with_suffix('.png')}")
    # Last, the verdict first: in the target grasp, or missed and why.
    print(run.regrasp_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
