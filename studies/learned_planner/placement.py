"""Where the palm waits, as the planner's choice: does a chooser of the
placement and the cell beat the best constant placement and cell on
geometries it has never seen?

    .venv/bin/regrasp-drake dataset --target flip --offset-mm 0 --workers 2 \\
        --out out/placement/flip+0_fingers20 \\
        --scenario-text '{catch: {palm_toward_fingers_m: 0.02}}'   # ~20 min
    .venv/bin/python studies/learned_planner/placement.py \\
        [--variant out/placement/flip+0_fingers20] [--base models/dataset_flip+0]

Two data sets of one target that differ only in where the palm waits (the
base: the shipped catch, the palm 10 mm toward its heel; the variant: 20
mm, so that the object lands nearer the fingertips). On the objects both
hold a map of, split by geometry as `judge` splits them:
  - learned: one success model (learning/planner.py `SuccessModel`) trained
    on both placements' maps of the training objects (the palm's place is
    among its inputs), choosing for a held-out object the placement and
    cell of highest predicted success;
  - learned, base only: the same model on the base maps alone (the shipped
    planner's design);
  - best constant: the placement and cell that succeed on the most
    training objects; and the best constant cell of each placement alone;
  - ceiling: any cell of either placement.
Also apart for the lopsided objects (off-axis centre of mass) and the round
ones. Prints the figures and writes placement.json here.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError
from regrasp_drake.learning.planner import (
    PlannerData,
    SuccessModel,
    best_constant,
    choose,
)
from regrasp_drake.paths import MODELS_DIR, REPO_DIR
from regrasp_drake.planning.grasp import has_side
from regrasp_drake.world.objects import resolve_object

HERE = Path(__file__).resolve().parent


def shown(path: Path) -> str:
    """A path from the checkout's top when inside it."""
    path = path.resolve()
    if REPO_DIR is not None and path.is_relative_to(REPO_DIR):
        return str(path.relative_to(REPO_DIR))
    return str(path)


def both(base: PlannerData, variant: PlannerData):
    """The objects both data sets map, and per placement their features
    and maps in that order."""
    names = [n for n in base.objects if n in variant.objects]
    rows = [[d.objects.index(n) for n in names] for d in (base, variant)]
    return (names, [base.geometries[k] for k in rows[0]],
            [d.features[r] for d, r in zip((base, variant), rows)],
            [d.caught[r] for d, r in zip((base, variant), rows)])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", type=Path, default=MODELS_DIR / "dataset_flip+0")
    parser.add_argument("--variant", type=Path, default=(
        REPO_DIR or Path.cwd()) / "out" / "placement" / "flip+0_fingers20")
    parser.add_argument("--out", type=Path, default=HERE / "placement.json")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    names, geometries, features, caught = both(PlannerData.load(args.base),
                                               PlannerData.load(args.variant))
    geometries = np.array(geometries)
    lopsided = np.array([has_side(resolve_object(name=n)) for n in names])
    choosers = ("learned", "learned_base_only", "best_constant",
                "best_constant_base", "best_constant_variant", "ceiling")
    hits = {c: np.zeros(len(names), bool) for c in choosers}
    picked_variant = np.zeros(len(names), bool)
    for g in sorted(set(geometries)):
        train, held = np.flatnonzero(geometries != g), np.flatnonzero(geometries == g)
        model = SuccessModel().fit(
            np.vstack([f[train] for f in features]),
            np.concatenate([c[train] for c in caught]))
        base_model = SuccessModel().fit(features[0][train], caught[0][train])
        stacked = np.stack([c[train] for c in caught], 1)  # objects × 2 × 10 × 15
        counts = stacked.reshape(len(train), -1).sum(0)
        p, i, j = np.unravel_index(int(np.argmax(counts)), (2, 10, 15))
        constants = [best_constant(c[train]) for c in caught]
        predicted = [model.success_maps(f[held]) for f in features]
        predicted_base = base_model.success_maps(features[0][held])
        for n, m in enumerate(held):
            scores = [predicted[v][n].max() for v in (0, 1)]
            v = int(np.argmax(scores))
            picked_variant[m] = v == 1
            hits["learned"][m] = caught[v][m][choose(predicted[v][n])]
            hits["learned_base_only"][m] = caught[0][m][choose(predicted_base[n])]
            hits["best_constant"][m] = caught[p][m][i, j]
            hits["best_constant_base"][m] = caught[0][m][constants[0]]
            hits["best_constant_variant"][m] = caught[1][m][constants[1]]
            hits["ceiling"][m] = caught[0][m].any() or caught[1][m].any()
        print(g, flush=True)
    groups = {"all": np.ones(len(names), bool), "lopsided": lopsided,
              "round": ~lopsided}
    report = {"base": shown(args.base), "variant": shown(args.variant),
              "maps": len(names), "split": "by geometry",
              "cells_in_target": {"base": round(float(caught[0].mean()), 4),
                                  "variant": round(float(caught[1].mean()), 4)},
              "learned_picked_variant": int(picked_variant.sum())}
    for group, mask in groups.items():
        report[group] = {"maps": int(mask.sum())} | {
            c: round(float(h[mask].mean()), 4) for c, h in hits.items()}
        print(f"{group:9s} {mask.sum():2d} maps: " + ", ".join(
            f"{c} {report[group][c]:.3f}" for c in choosers))
    atomic_io.write_json(args.out, report)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except InputError as e:  # a data set missing or malformed: one line
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
