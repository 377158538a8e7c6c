"""Does the choice of catch point matter? The success maps of an object's
best-ranked catch points side by side, from stored maps only (no
simulation).

    .venv/bin/python studies/catch_points/catch_points.py
        [--out studies/catch_points/catch_points.json]

1. The training objects (models/dataset: up to four catch points each, the
   best-ranked reachable moments of the watched flight at least 30 ms apart,
   `throw_catch.plan_catches`): the mean share of catching cells at each
   rank, and what picking one catch point per object by a rule would give:
   the highest (latest-ranked) or lowest point, the slowest or fastest
   v_catch, the least tilted axis, and the best point of each object (an
   oracle: no rule can do better). Then a learned rule: a ridge regression
   (penalty 1 on standardized inputs) of the share of catching cells on the
   catch point's v_catch, height and tilt, fitted leave-one-object-out
   (the object's every catch point held out), picks the point with the
   highest prediction.
2. The Table 1 objects' four catch points (studies/catch_points/catch_points/cells/
   <object>[@k].jsonl and plans/, written by `regrasp-drake dataset
   --objects table1-row1 ... --catch-points 4 --out studies/catch_points/catch_points`):
   the catching cells at each point, its moment, v_catch and tilt.

Prints a summary and writes the JSON.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, check_output_path
from regrasp_drake.grid import read_rows
from regrasp_drake.paths import MODELS_DIR

HERE = Path(__file__).parent / "catch_points"
INPUTS = ("v_catch", "z", "tilt")  # the learned rule's inputs
RIDGE = 1.0


def entries(data_dir: Path, maps: dict) -> list[dict]:
    """One dict per entry of data_dir/plans with a map in `maps` ({entry:
    share of catching cells}): object, rank, v_catch, z, tilt, t_s, share."""
    out = []
    for path in sorted((data_dir / "plans").glob("*.json")):
        d = json.loads(path.read_text())
        if path.stem not in maps or not d.get("usable"):
            continue
        cp = d["plan"]["catch_point"]
        out.append({"entry": path.stem, "object": d["object"],
                    "rank": int(d["catch_point"]), "v_catch": cp["v_catch"],
                    "z": cp["p_WO"][2], "tilt": cp["tilt"], "t_s": cp["t_s"],
                    "share": maps[path.stem]})
    return out


def training_maps() -> dict:
    with np.load(MODELS_DIR / "dataset" / "maps.npz", allow_pickle=False) as d:
        return {str(n): float(m.mean()) for n, m in zip(d["objects"],
                                                         d["caught"])}


def pick_rules(rows: list[dict]) -> dict:
    """The mean share of catching cells of the point each rule picks."""
    by_object = {}
    for r in rows:
        by_object.setdefault(r["object"], []).append(r)
    rules = {
        "rank 1 (shipped)": lambda rs: min(rs, key=lambda r: r["rank"]),
        "highest": lambda rs: max(rs, key=lambda r: r["z"]),
        "lowest": lambda rs: min(rs, key=lambda r: r["z"]),
        "slowest v_catch": lambda rs: max(rs, key=lambda r: r["v_catch"]),
        "least tilted": lambda rs: min(rs, key=lambda r: r["tilt"]),
        "best (oracle)": lambda rs: max(rs, key=lambda r: r["share"]),
    }
    out = {name: round(float(np.mean([rule(rs)["share"]
                                      for rs in by_object.values()])), 3)
           for name, rule in rules.items()}
    learned = []
    for name, rs in by_object.items():
        train = [r for r in rows if r["object"] != name]
        X = np.array([[r[k] for k in INPUTS] for r in train])
        mean, std = X.mean(axis=0), X.std(axis=0)
        A = np.column_stack([np.ones(len(X)), (X - mean) / std])
        penalty = RIDGE * np.eye(A.shape[1])
        penalty[0, 0] = 0.0
        w = np.linalg.solve(A.T @ A + penalty,
                            A.T @ np.array([r["share"] for r in train]))
        B = np.column_stack([np.ones(len(rs)), (np.array(
            [[r[k] for k in INPUTS] for r in rs]) - mean) / std])
        learned.append(rs[int(np.argmax(B @ w))]["share"])
    out["learned (leave-one-object-out)"] = round(float(np.mean(learned)), 3)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, default=HERE.with_suffix(".json"))
    args = p.parse_args(argv)
    try:
        check_output_path("--out", args.out)
    except InputError as e:
        print(f"catch_points: error: {e}", file=sys.stderr)
        return 2
    if not (HERE / "cells").is_dir():
        print(f"catch_points: error: {HERE / 'cells'}: no such directory, "
              "expected the Table 1 maps of the module's docstring",
              file=sys.stderr)
        return 2
    rows = entries(MODELS_DIR / "dataset", training_maps())
    ranks = {k: round(float(np.mean([r["share"] for r in rows
                                     if r["rank"] == k])), 3)
             for k in sorted({r["rank"] for r in rows})}
    rules = pick_rules(rows)
    table1 = {}
    for path in sorted((HERE / "cells").glob("*.jsonl")):
        cells = read_rows(path)
        plan = json.loads((HERE / "plans" / f"{path.stem}.json").read_text())
        cp = plan["plan"]["catch_point"]
        table1[path.stem] = {
            "cells": len(cells),
            "caught": sum(r["outcome"] == "caught" for r in cells.values()),
            "t_s": cp["t_s"], "v_catch": cp["v_catch"],
            "z": cp["p_WO"][2], "tilt": cp["tilt"]}
    result = {"training": {"entries": len(rows),
                           "objects": len({r["object"] for r in rows}),
                           "share_caught_by_rank": ranks,
                           "share_caught_by_rule": rules,
                           "learned_rule": {"inputs": list(INPUTS),
                                            "ridge": RIDGE}},
              "table1": table1}
    print(f"training objects, share of catching cells by rank: {ranks}")
    for name, share in rules.items():
        print(f"  one point per object, {name}: {share}")
    for entry, t in table1.items():
        print(f"{entry:16s} t {t['t_s']:.3f} s, v_catch {t['v_catch']:.2f} "
              f"m/s, z {t['z']:.3f} m, tilt {t['tilt']:.3f}: "
              f"{t['caught']}/{t['cells']} cells catch")
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
