"""Maps as probabilities: a target's maps at several catch steps taken as
draws of each cell's outcome. Does a chooser of the cell beat the best
constant cell on unseen geometries when each cell counts by how often it
holds?

    .venv/bin/python benchmarks/planner_convergence.py --target flip+0 \\
        --steps-ms 0.5 0.25 --objects <every object of models/dataset_flip+0>
    .venv/bin/python studies/learned_planner/step_draws.py \\
        [--fine out/planner_convergence/flip+0_0.5ms ..._0.25ms]  # ~35 min

On the objects mapped at every step (models/dataset_flip+0 at 1 ms and
each --fine directory's), each cell's success is the mean of its
outcomes. Split by geometry as `judge` splits them: the success model
(learning/planner.py) trained on those means (its cross entropy takes them
as soft targets), choosing the cell of highest predicted success; the best
constant cell, of the highest summed mean over the training maps; the
ceiling, each held-out map's best cell. A held-out map scores the mean of
the chosen cell. Prints the figures and writes step_draws.json here (with
--json F, there).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io, grid
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset_files import load_map
from regrasp_drake.learning.labels import SHAPE
from regrasp_drake.learning.planner import PlannerData, SuccessModel, choose
from regrasp_drake.paths import MODELS_DIR, REPO_DIR

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--coarse", type=Path, default=MODELS_DIR / "dataset_flip+0")
    runs = (REPO_DIR or Path.cwd()) / "out" / "planner_convergence"
    parser.add_argument("--fine", type=Path, nargs="+", default=[
        runs / "flip+0_0.5ms", runs / "flip+0_0.25ms"])
    parser.add_argument("--json", type=Path, default=HERE / "step_draws.json")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    data = PlannerData.load(args.coarse)
    keep = [k for k, n in enumerate(data.objects)
            if all((d / "cells" / f"{n}.jsonl").exists() for d in args.fine)]
    for d in args.fine:  # a map still being computed would count as misses
        for k in keep:
            rows = grid.read_rows(d / "cells" / f"{data.objects[k]}.jsonl")
            if len(rows) != SHAPE[0] * SHAPE[1]:
                raise InputError(f"--fine: {d}: {data.objects[k]}'s map has "
                                 f"{len(rows)} cells, expected all "
                                 f"{SHAPE[0] * SHAPE[1]} (is it still running?)")
    if not keep:
        raise InputError(f"--fine: {' '.join(map(str, args.fine))}: no map of "
                         f"{args.coarse}'s objects in each, expected the maps "
                         "benchmarks/planner_convergence.py writes")
    draws = [data.caught[keep].astype(float)] + [
        np.stack([load_map(d, data.objects[k]) for k in keep]) for d in args.fine]
    p = np.mean(draws, axis=0)
    features = data.features[keep]
    geometries = np.array(data.geometries)[keep]
    scores = {"learned": [], "best_constant": [], "ceiling": []}
    for g in sorted(set(geometries)):
        train, held = np.flatnonzero(geometries != g), np.flatnonzero(geometries == g)
        model = SuccessModel().fit(features[train], p[train])
        predicted = model.success_maps(features[held])
        constant = np.unravel_index(int(np.argmax(p[train].sum(0))), SHAPE)
        for n, m in enumerate(held):
            scores["learned"].append(p[m][choose(predicted[n])])
            scores["best_constant"].append(p[m][constant])
            scores["ceiling"].append(p[m].max())
        print(g, flush=True)
    report = {"maps": len(keep), "draws": 1 + len(args.fine),
              "split": "by geometry",
              "cells_in_target": round(float(p.mean()), 4),
              "cells_held_at_every_step": round(float((p == 1.0).mean()), 4)} | {
        k: round(float(np.mean(v)), 4) for k, v in scores.items()}
    print(report)
    atomic_io.write_json(args.json, report)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except InputError as e:  # a data set missing or malformed: one line
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
