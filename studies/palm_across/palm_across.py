"""Under the centre of mass or under the grasp piece? The success maps with
the palm placed across the object's axis at catch.palm_across_com_fraction
1 (the shipped data set), 0.5 and 0, summarized from stored results (no
simulation).

    .venv/bin/python studies/palm_across/palm_across.py
        [--out studies/palm_across/palm_across.json]

The stored results (how they were made: FINDINGS.md beside this script):
- models/dataset/maps.npz: fraction 1, every training object;
- studies/palm_across/palm_across/f05/maps.npz: fraction 0.5, the 10 training
  objects whose centre of mass lies 20 mm or more off the grasp piece's
  axis (|r_cm|);
- studies/palm_across/palm_across/f0/: fraction 0, every training object (maps.npz),
  the network trained on it (catch_mlp_report.json), Table 1 with it
  (table1.json: watch first; table1_ar.json: at release) and the success
  maps of table1 rows 4 and 5 (table1-row*.jsonl).

Counts the catching cells per group of training objects by |r_cm| (0, below
20 mm, 20 mm or more), for each fraction stored, and lists Table 1.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake.learning.dataset import object_of
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.world.objects import load_catalogue

HERE = Path(__file__).parent / "palm_across"
MAPS = {1.0: MODELS_DIR / "dataset" / "maps.npz",
        0.5: HERE / "f05" / "maps.npz",
        0.0: HERE / "f0" / "maps.npz"}
R_CM_BIG_M = 0.02


def _maps(path: Path) -> dict:
    with np.load(path) as data:
        return dict(zip(data["objects"].tolist(), data["caught"]))


def group_of(r_cm: float) -> str:
    if r_cm == 0.0:
        return "r_cm = 0"
    return "|r_cm| < 20 mm" if abs(r_cm) < R_CM_BIG_M else "|r_cm| >= 20 mm"


def summarize(maps_by_fraction: dict, r_cm: dict) -> dict:
    """Per group and fraction: the maps, their catching cells and the maps
    that catch somewhere, over the entries every fraction has."""
    common = set.intersection(*(set(m) for m in maps_by_fraction.values()))
    out = {}
    for group in ("r_cm = 0", "|r_cm| < 20 mm", "|r_cm| >= 20 mm"):
        entries = sorted(e for e in common if group_of(r_cm[object_of(e)]) == group)
        if not entries:
            continue
        out[group] = {"maps": len(entries), "by_fraction": {
            str(f): {"catching_cells": int(sum(m[e].sum() for e in entries)),
                     "maps_catching": int(sum(m[e].any() for e in entries)),
                     "median_cells": float(np.median([m[e].sum() for e in entries]))}
            for f, m in maps_by_fraction.items()}}
    return out


def table1(path: Path) -> list:
    return [{"object": r["object"], "throws": r["throws"], "caught": r["caught"],
             "start_cell": r["start_cell"]} for r in json.loads(path.read_text())]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=HERE.with_suffix(".json"))
    args = p.parse_args(argv)
    missing = [str(path) for path in MAPS.values() if not path.is_file()]
    if missing:
        print(f"palm_across: error: {missing[0]}: no such file, expected the "
              "stored maps of the module's docstring", file=sys.stderr)
        return 2
    r_cm = {name: spec.r_cm for name, spec in load_catalogue().items()}
    maps = {f: _maps(path) for f, path in MAPS.items()}
    result = {
        "all_fractions": summarize(maps, r_cm),
        "fractions_1_and_0": summarize({1.0: maps[1.0], 0.0: maps[0.0]}, r_cm),
        "network_fraction_0": json.loads(
            (HERE / "f0" / "catch_mlp_report.json").read_text())["repeated_splits"],
        "table1_fraction_0": {"watch_first": table1(HERE / "f0" / "table1.json"),
                              "at_release": table1(HERE / "f0" / "table1_ar.json")},
        "table1_maps_fraction_0": {
            row: sum(json.loads(line)["outcome"] == "caught" for line in
                     (HERE / "f0" / f"{row}.jsonl").read_text().splitlines())
            for row in ("table1-row4", "table1-row5")},
    }
    for key in ("all_fractions", "fractions_1_and_0"):
        for group, g in result[key].items():
            cells = ", ".join(f"{f}: {v['catching_cells']}"
                              for f, v in g["by_fraction"].items())
            print(f"{key:18s} {group:16s} {g['maps']:3d} maps, catching cells {cells}")
    for mode, rows in result["table1_fraction_0"].items():
        print(f"Table 1 at fraction 0, {mode}: " + ", ".join(
            f"{r['throws']}{'' if r['caught'] else ' (not caught)'}" for r in rows))
    print("catching cells of table1 rows 4, 5 at fraction 0:",
          result["table1_maps_fraction_0"])
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
