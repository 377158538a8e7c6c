"""The achieved grasp at the shipped catch step against a finer one: two
runs of benchmarks/regrasp_targets.py (the same objects, targets and mode,
the second with a finer `catch_time_step_s`), compared pair by pair.

    .venv/bin/python benchmarks/regrasp_targets.py --modes first-throw \\
        --max-throws 1 --objects table1-row1 ... --out out/landing/fine \\
        --scenario-text '{catch_time_step_s: 0.00025}'
    .venv/bin/python benchmarks/landing_convergence.py \\
        models/results/landing_first_throw.jsonl out/landing/fine.jsonl \\
        [--out models/results/landing_convergence.json]

For each pair in both: the outcome and the achieved grasp (offset, tilt) in
each, whether the verdict (in the target grasp or not) is the same, and
whether a grasp held in both agrees within --offset-mm and --tilt-deg (the
issue's 5 mm and 5 degrees). Prints a table and the counts; writes JSON.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import sys
from pathlib import Path

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError
from regrasp_drake.map_rows import read_rows


def _key(row) -> tuple:
    return (row["object"], row["target"]["kind"], row["target"]["offset_mm"],
            row["mode"])


def compare(coarse: dict, fine: dict, offset_mm: float,
            tilt_deg: float) -> dict:
    """The pairs of `coarse` and `fine` ({key: row}) that both hold, each
    with both runs' outcome and grasp, and the counts."""
    pairs = []
    for key in sorted(set(coarse) & set(fine)):
        a, b = coarse[key], fine[key]
        if a["stopped"] == "refused":
            continue
        row = {"object": key[0], "target": f"{key[1]}:{key[2]:+.0f}",
               "success": [a["success"], b["success"]],
               "grasp": [a.get("achieved_grasp"), b.get("achieved_grasp")]}
        ga, gb = row["grasp"]
        if ga and gb:
            row["d_offset_mm"] = round(abs(ga["offset_mm"] - gb["offset_mm"]),
                                       2)
            row["d_tilt_deg"] = round(abs(ga["tilt_deg"] - gb["tilt_deg"]), 2)
            row["within"] = (ga["axis"] == gb["axis"]
                             and row["d_offset_mm"] <= offset_mm
                             and row["d_tilt_deg"] <= tilt_deg)
        else:
            row["within"] = ga is None and gb is None
        pairs.append(row)
    return {"pairs": pairs, "compared": len(pairs),
            "same_verdict": sum(p["success"][0] == p["success"][1]
                                for p in pairs),
            "grasp_within": sum(p["within"] for p in pairs),
            "tolerance": {"offset_mm": offset_mm, "tilt_deg": tilt_deg}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("coarse", type=Path, help="rows at the shipped step")
    parser.add_argument("fine", type=Path, help="rows at the finer step")
    parser.add_argument("--offset-mm", type=float, default=5.0)
    parser.add_argument("--tilt-deg", type=float, default=5.0)
    parser.add_argument("--out", type=Path,
                        help="the comparison's JSON (default: not written)")
    args = parser.parse_args(argv)
    for name in ("coarse", "fine"):
        path = getattr(args, name)
        if not path.is_file():
            print(f"landing_convergence: error: {name}: {path} is not a "
                  "file, expected regrasp_targets.py's rows (JSON lines)",
                  file=sys.stderr)
            return 2
    try:
        result = compare(read_rows(args.coarse, key=_key),
                         read_rows(args.fine, key=_key), args.offset_mm,
                         args.tilt_deg)
    except (InputError, KeyError, TypeError) as e:
        print(f"landing_convergence: error: {e}, expected "
              "regrasp_targets.py's rows", file=sys.stderr)
        return 2
    if not result["compared"]:
        print("landing_convergence: error: the two files share no pair, "
              "expected runs over the same objects and targets",
              file=sys.stderr)
        return 2

    def shown(grasp):
        return ("not held" if grasp is None else
                f"{grasp['axis']:8s} {grasp['offset_mm']:+6.1f} mm "
                f"{grasp['tilt_deg']:4.1f}°")

    for p in result["pairs"]:
        print(f"{p['object']:24s} {p['target']:8s} "
              f"{shown(p['grasp'][0]):26s} {shown(p['grasp'][1]):26s} "
              f"{'same' if p['success'][0] == p['success'][1] else 'DIFF'} "
              f"{'within' if p['within'] else 'apart'}")
    print(f"same verdict: {result['same_verdict']} of {result['compared']}; "
          f"grasp within {args.offset_mm:g} mm and {args.tilt_deg:g}°: "
          f"{result['grasp_within']} of {result['compared']}")
    if args.out:
        atomic_io.write_json(args.out, result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
