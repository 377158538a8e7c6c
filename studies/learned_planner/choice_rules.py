"""Does restricting the learned planner's choice to the cells that do well
on the training maps beat the best constant cell on unseen geometries?

    .venv/bin/python studies/learned_planner/choice_rules.py [TARGET ...]
        (TARGET: flip+0, keep-30, ...; default every models/dataset_<target>)

For each split by geometry (learning/planner.py `splits`), one model is
trained (as `judge` trains it) and several rules choose a cell for each
held-out map from its predicted success map: the highest of all 150 cells
(the shipped rule), the highest among the k cells that succeed on the most
training maps (k = 3, 5, 10, 20), and the best constant cell itself (k = 1).
Prints each rule's success rate and writes them to choice_rules.json here.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import json
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.learning.labels import SHAPE
from regrasp_drake.learning.planner import (
    PlannerData,
    SuccessModel,
    choose,
    splits,
)
from regrasp_drake.paths import MODELS_DIR

RULES = (1, 3, 5, 10, 20, 150)  # k: the top-k training cells; 150: all


def rates(data: PlannerData) -> dict:
    hits = {k: [] for k in RULES}
    for train, held_out in splits(data.geometries):
        counts = data.caught[train].sum(axis=0).ravel()
        # Ties in the training counts to the lowest index (as best_constant).
        order = np.argsort(-counts, kind="stable")
        model = SuccessModel().fit(data.features[train], data.caught[train])
        predicted = model.success_maps(data.features[held_out])
        for k in RULES:
            allowed = np.zeros(SHAPE[0] * SHAPE[1], bool)
            allowed[order[:k]] = True
            for n, m in enumerate(held_out):
                scores = np.where(allowed.reshape(SHAPE), predicted[n], -1.0)
                hits[k].append(bool(data.caught[m][choose(scores)]))
    return {f"top_{k}" if k < 150 else "all_cells":
            round(float(np.mean(h)), 4) for k, h in hits.items()}


def main(argv=None) -> int:
    torch.set_num_threads(1)
    targets = (argv if argv is not None else sys.argv[1:]) or sorted(
        p.name.removeprefix("dataset_") for p in MODELS_DIR.glob("dataset_*"))
    out_path = Path(__file__).with_name("choice_rules.json")
    out = json.loads(out_path.read_text()) if out_path.exists() else {}
    for target in targets:
        data = PlannerData.load(MODELS_DIR / f"dataset_{target}")
        out[target] = rates(data)
        print(target, out[target], flush=True)
        atomic_io.write_json(out_path, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
