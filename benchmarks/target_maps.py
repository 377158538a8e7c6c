"""Do the catch parameters matter under a regrasp target? Success maps of
data sets made under targets (`regrasp-drake dataset --target KIND
[--offset-mm MM]`), side by side with the shipped `any` data set.

    .venv/bin/python benchmarks/target_maps.py NAME=DIR [NAME=DIR ...]
        [--out models/results/target_maps.json]

Per data set (its maps.npz; a cell succeeds when the catch ends held in
the target grasp): the share of each map's cells that succeed (mean, min,
max), how many maps lie in 10-90 % and how many are empty, the best
constant cell's success rate over the maps, and the shipped network's
(models/catch_mlp.pt, trained on `any`) cell's rate: the cell it picks from
each object's features, scored on that object's map. Beside each, the same
figures of the shipped `any` data set on the same objects.
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
from regrasp_drake.learning.learning_phase import predict
from regrasp_drake.parameter_space import nearest_cell
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.mlp_system import load_weights


def load(directory: Path) -> dict:
    data = np.load(Path(directory) / "maps.npz")
    return {"objects": [str(o) for o in data["objects"]],
            "caught": np.asarray(data["caught"], bool),
            "features": np.asarray(data["features"], float)}


def figures(maps: dict, model) -> dict:
    caught = maps["caught"]
    share = caught.reshape(len(caught), -1).mean(axis=1)
    cells = [nearest_cell(*predict(model, f)[1]) for f in maps["features"]]
    network = float(np.mean([caught[k][c] for k, c in enumerate(cells)]))
    per_cell = caught.mean(axis=0)
    best = np.unravel_index(int(np.argmax(per_cell)), per_cell.shape)
    return {"maps": len(caught),
            "share_mean": round(float(share.mean()), 3),
            "share_min": round(float(share.min()), 3),
            "share_max": round(float(share.max()), 3),
            "maps_in_10_90": int(np.sum((share >= 0.1) & (share <= 0.9))),
            "maps_empty": int(np.sum(share == 0.0)),
            "best_constant_cell": [int(best[0]), int(best[1])],
            "best_constant_rate": round(float(per_cell[best]), 3),
            "network_rate": round(network, 3)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sets", nargs="+", metavar="NAME=DIR")
    parser.add_argument("--any", type=Path, default=MODELS_DIR / "dataset",
                        help="the `any` data set (default the shipped one)")
    parser.add_argument("--out", type=Path,
                        default=MODELS_DIR / "results" / "target_maps.json")
    args = parser.parse_args(argv)
    model, _ = load_weights(MODELS_DIR / "catch_mlp.pt")
    shipped = load(args.any)
    out = {}
    for name, directory in (s.split("=", 1) for s in args.sets):
        maps = load(Path(directory))
        rows = [shipped["objects"].index(o) for o in maps["objects"]]
        same = {"objects": maps["objects"], "caught": shipped["caught"][rows],
                "features": shipped["features"][rows]}
        out[name] = {"objects": maps["objects"],
                     "target": figures(maps, model),
                     "any_same_objects": figures(same, model)}
    atomic_io.write_json(args.out, out)
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
