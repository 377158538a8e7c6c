"""One model across the six targets, or one per target? The shipped
planner is one per target; this trains one success model on the maps of
all six targets at once (the target's kind and offset as two more inputs)
and scores it by geometry on each target, as `judge` scores the shipped
one.

    .venv/bin/python studies/learned_planner/pooled.py

For each of the 9 geometries: one model trained on every other geometry's
maps under all six targets; each held-out map scores the cell of highest
predicted success. Prints the rate per target beside the per-target
model's (models/results/planner_<target>.json) and writes pooled.json here.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import json
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.learning.planner import (
    PLANNER_FEATURES,
    PlannerData,
    SuccessModel,
    choose,
)
from regrasp_drake.paths import MODELS_DIR

TARGETS = ["keep-30", "keep+0", "keep+30", "flip-30", "flip+0", "flip+30"]


def main() -> int:
    torch.set_num_threads(1)
    features, caught, geometries, target_of = [], [], [], []
    for t in TARGETS:
        data = PlannerData.load(MODELS_DIR / f"dataset_{t}")
        kind = 1.0 if t.startswith("flip") else -1.0
        offset = float(t.removeprefix("flip").removeprefix("keep")) / 30.0
        features.append(np.hstack([data.features,
                                   np.tile([kind, offset], (len(data.features), 1))]))
        caught.append(data.caught)
        geometries += data.geometries
        target_of += [t] * len(data.geometries)
    features, caught = np.vstack(features), np.concatenate(caught)
    geometries, target_of = np.array(geometries), np.array(target_of)
    hits = {t: [] for t in TARGETS}
    for g in sorted(set(geometries)):
        train, held = geometries != g, np.flatnonzero(geometries == g)
        model = SuccessModel(n_features=len(PLANNER_FEATURES) + 2).fit(
            features[train], caught[train])
        predicted = model.success_maps(features[held])
        for n, m in enumerate(held):
            hits[target_of[m]].append(bool(caught[m][choose(predicted[n])]))
        print(g, flush=True)
    out = {}
    for t in TARGETS:
        alone = json.loads((MODELS_DIR / "results" / f"planner_{t}.json")
                           .read_text())["by_geometry"]
        out[t] = {"pooled": round(float(np.mean(hits[t])), 4),
                  "per_target": alone["learned"],
                  "best_constant": alone["best_constant"],
                  "paper_network": alone["paper_network"]}
        print(t, out[t], flush=True)
    atomic_io.write_json(Path(__file__).with_name("pooled.json"), out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
