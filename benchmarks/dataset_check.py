"""A data set generated again against the shipped one: how long it took, and
whether it is the same, cell for cell.

    .venv/bin/regrasp-drake dataset --workers 2 --out /tmp/ds   # about 1 h
    .venv/bin/python benchmarks/dataset_check.py /tmp/ds
        [--shipped models/dataset] [--out benchmarks/dataset_check.json]

Compares every entry's plan (features and catch plan), every cell's
outcome and the object's final position (the count of differing cells per
entry, and, apart, the cells whose outcome differs) (and its ending, grid.ending,
where both rows record a drop reason: rows written before episodes
recorded it have none), then
samples.csv and maps.npz, and copies the generated set's timing from its
provenance.json (every run that computed entries there: wall time,
workers, code version and numeric kernels). Writes the JSON; exits 1 when
the sets differ.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError, check_output_path
from regrasp_drake.grid import ending, read_rows
from regrasp_drake.learning.provenance import git_version
from regrasp_drake.paths import MODELS_DIR, REPO_DIR



def _plan(path: Path) -> dict:
    data = json.loads(path.read_text())
    return {k: data.get(k) for k in ("usable", "features", "plan", "reason")}


def _cells(path: Path) -> dict:
    """{cell: (outcome, final position, ending or None)}: rows written before
    episodes recorded their drop reason have no ending to compare."""
    return {cell: (row["outcome"], row["p_WO_final"],
                   ending(row) if "drop_reason" in row else None)
            for cell, row in read_rows(path).items()}


def _same(a, b) -> bool:
    """Two cells agree: outcome and final position, and their endings
    where both rows have one."""
    if a is None or b is None:
        return a is b
    return a[:2] == b[:2] and (a[2] is None or b[2] is None or a[2] == b[2])


def _shown(path: Path) -> str:
    """A directory of the repository as `path (commit …)`: what it held
    then; another directory as it is."""
    try:
        relative = Path(path).resolve().relative_to(REPO_DIR)
    except ValueError:
        return str(path)
    return f"{relative} (commit {git_version()})"


def compare(generated: Path, shipped: Path) -> dict:
    """What differs between two data set directories (see the module)."""
    for d in (generated, shipped):
        if not (d / "provenance.json").is_file():
            raise InputError(f"{d}: no provenance.json, expected a finished "
                             "data set (regrasp-drake dataset --out)")
    names = sorted(p.stem for p in (shipped / "plans").glob("*.json"))
    mine = sorted(p.stem for p in (generated / "plans").glob("*.json"))
    differing_plans, differing_cells, cells, without_ending = [], {}, 0, 0
    other_outcomes = {}  # entry -> cells whose outcome differs
    for name in names:
        if name not in mine:
            continue
        if _plan(generated / "plans" / f"{name}.json") != _plan(
                shipped / "plans" / f"{name}.json"):
            differing_plans.append(name)
        a = _cells(generated / "cells" / f"{name}.jsonl")
        b = _cells(shipped / "cells" / f"{name}.jsonl")
        cells += len(b)
        without_ending += sum(v[2] is None for v in b.values())
        bad = sorted(str(c) for c in set(a) | set(b)
                     if not _same(a.get(c), b.get(c)))
        if bad:
            differing_cells[name] = bad
        outcomes = sorted(str(c) for c in set(a) | set(b)
                          if (a.get(c) or (None,))[0] != (b.get(c) or (None,))[0])
        if outcomes:
            other_outcomes[name] = outcomes
    with np.load(generated / "maps.npz") as x, np.load(shipped / "maps.npz") as y:
        maps_equal = all(np.array_equal(x[k], y[k]) for k in y.files)
    samples_equal = ((generated / "samples.csv").read_bytes()
                     == (shipped / "samples.csv").read_bytes())
    provenance = json.loads((generated / "provenance.json").read_text())
    return {
        "generated": str(generated), "shipped": _shown(shipped),
        "entries": len(names), "entries_missing": sorted(set(names) - set(mine)),
        "entries_extra": sorted(set(mine) - set(names)),
        "cells_compared": cells,
        # Shipped rows without a drop reason: compared by outcome and final
        # position only.
        "shipped_cells_without_ending": without_ending,
        "plans_differing": differing_plans,
        "cells_differing": {name: len(c) for name, c in differing_cells.items()},
        # The outcome alone (a final position a few µm off, or one bit, is a
        # differing cell above): how many cells, and which differ.
        "cells_same_outcome": cells - sum(map(len, other_outcomes.values())),
        "cells_with_another_outcome": other_outcomes,
        "maps_npz_equal": maps_equal, "samples_csv_equal": samples_equal,
        "identical": (not differing_plans and not differing_cells
                      and maps_equal and samples_equal
                      and set(mine) == set(names)),
        "runs": provenance.get("runs"),
        "wall_s": sum(r.get("wall_s") or 0 for r in provenance.get("runs", [])),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("generated", type=Path,
                   help="the data set directory generated again")
    p.add_argument("--shipped", type=Path, default=MODELS_DIR / "dataset")
    p.add_argument("--out", type=Path,
                   default=REPO_DIR / "benchmarks" / "dataset_check.json")
    args = p.parse_args(argv)
    try:
        check_output_path("--out", args.out)
        result = compare(args.generated, args.shipped)
    except InputError as e:
        print(f"dataset_check.py: error: {e}", file=sys.stderr)
        return 2
    atomic_io.write_json(args.out, result)
    minutes = result["wall_s"] / 60
    print(f"{result['entries']} entries, {result['cells_compared']} cells: "
          f"{'identical' if result['identical'] else 'DIFFERENT'}, "
          f"{result['cells_same_outcome']} the same outcome; "
          f"generated in {minutes:.1f} min ({len(result['runs'] or [])} "
          f"run(s)); wrote {args.out}")
    return 0 if result["identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
