"""Could any function of the network's five features pick better catch
cells than one cell for every object? Stored success maps only (no
simulation).

    .venv/bin/python studies/network_alternatives/network_alternatives.py [--seeds N]
        [--epochs N] [--out studies/network_alternatives/network_alternatives]

For each of the seeds 0 … N-1, the data set (models/dataset) is split as
`regrasp-drake train --seed k` splits it (by object, 44 / 10 / 10 in
proportion), and each predictor below, fitted on the training split (and,
where it trains, kept at its best validation epoch), picks a cell for each
test-split entry; its score is the share of those cells that catch on the
entry's success map. Predictors:

- network, labels: the shipped training (`learning/train.py`: the MLP on
  the labels, the most robust catching cells);
- network, smoothed maps (σ cells): the same MLP (5-13-2, tanh) trained to
  maximize its output's catch chance on the training maps smoothed by a
  Gaussian of σ cells: the labels' alternative that sees every catching
  cell, not one per map. Kept at the epoch of the best smoothed catch
  chance on the validation maps;
- nearest maps (k): a cell that catches on the most of the k training
  maps nearest in the five features (each scaled by its spread over the
  training split, as the map-prior search's kernel weighs them,
  `search.feature_weights`), the one of those the data set's label rule
  picks (farthest from the others, `dataset.label_cell`); for k = 1 the
  nearest map's label, for k = every training map a best constant cell;
- best constant cell and mean label: the two baselines of `train.py`;
- a random cell: the expected rate of a cell drawn at random for each
  test entry (its map's share of catching cells), the floor.

Writes <out>.jsonl (each split's rates as soon as they are known; a rerun
skips the splits there that were made on the same data set), <out>.json
(per predictor: the mean catch rate over the splits, the per-split rates,
and the splits where it catches more / as many / fewer test entries than
the best constant cell) and <out>.png.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import hashlib
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import grid
from regrasp_drake.grid import open_rows, read_rows
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset import label_cell, load_samples, object_of
from regrasp_drake.learning.search import feature_weights
from regrasp_drake.learning.train import _arrays, fit, split_indices, train
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.mlp_system import CatchMlp, ParameterSpace

DATA_DIR = MODELS_DIR / "dataset"
SIGMAS_CELLS = (0.5, 1.0, 1.5, 2.0)
NEIGHBOURS = (1, 3, 5, 10)
LEARNING_RATE = 0.01  # train.py's


def soft_catch(parameters, maps, sigma_cells):
    """The catch chance of (h_catch, h_down) on each map (N×10×15, 1 =
    caught) smoothed by a Gaussian of sigma_cells cells, differentiable in
    the parameters (N×2, m)."""
    i_catch, i_down = (torch.as_tensor(v, dtype=torch.float64).ravel()
                       for v in np.meshgrid(range(len(grid.H_CATCH_VALUES)),
                                            range(len(grid.H_DOWN_VALUES)),
                                            indexing="ij"))
    step_catch = grid.H_CATCH_VALUES[1] - grid.H_CATCH_VALUES[0]
    step_down = grid.H_DOWN_VALUES[1] - grid.H_DOWN_VALUES[0]
    u = (parameters[:, 0] - grid.H_CATCH_VALUES[0]) / step_catch
    v = (parameters[:, 1] - grid.H_DOWN_VALUES[0]) / step_down
    d2 = (u[:, None] - i_catch[None]) ** 2 + (v[:, None] - i_down[None]) ** 2
    weights = torch.softmax(-d2 / (2 * sigma_cells ** 2), dim=1)
    return (weights * maps.reshape(len(maps), -1)).sum(dim=1)


def map_trained_cells(x, maps, split, sigma_cells, seed, epochs):
    """Test-split cells of the MLP trained on the smoothed maps."""
    train_i, val_i, test_i = split
    torch.manual_seed(seed)
    model = CatchMlp()
    # Outputs normalized by the training split's catching cells' spread.
    caught = [grid.cell_parameters(c) for m in maps[train_i]
              for c in zip(*np.nonzero(m))]
    model.set_normalization(torch.as_tensor(x[train_i]), torch.as_tensor(caught))
    xt, mt = ({k: torch.as_tensor(a[i]) for k, i in
               (("train", train_i), ("val", val_i))} for a in (x, maps))
    fit(model,
        lambda: -soft_catch(model(xt["train"]), mt["train"], sigma_cells).mean(),
        lambda: float(soft_catch(model(xt["val"]), mt["val"], sigma_cells).mean()),
        epochs=epochs, learning_rate=LEARNING_RATE)
    with torch.no_grad():
        pred = model(torch.as_tensor(x[test_i])).numpy()
    space = ParameterSpace()
    return [grid.nearest_cell(*space.clamp(*p)) for p in pred]


def nearest_maps_cells(x, maps, split, k):
    """Test-split cells catching on the most of the k nearest training maps
    (of those, the one the label rule picks)."""
    train_i, _, test_i = split
    cells = []
    for t in test_i:
        # Nearness as the map-prior search weighs it (features scaled by
        # their spread over the training maps); a wide kernel, so that no
        # weight underflows and the order is the distances'.
        weights = feature_weights(x[t], x[train_i], sigma=100.0)
        near = np.asarray(train_i)[np.argsort(-weights, kind="stable")[:k]]
        votes = maps[near].sum(axis=0)
        cells.append(label_cell(votes == votes.max()))
    return cells


def run(seeds, epochs, data_dir=DATA_DIR, progress=None,
        rows_path: Path | None = None) -> dict:
    """Section above; returns the JSON's contents. With `rows_path`, each
    split's rates are a JSON line there as soon as they are known, and the
    splits already there (same seed and epochs) are not redone."""
    samples = load_samples(data_dir)
    with np.load(Path(data_dir) / "maps.npz") as data:
        by_name = dict(zip(data["objects"].tolist(), data["caught"]))
    maps = np.array([by_name[s["object"]] for s in samples], float)
    x, _ = _arrays(samples)
    groups = [object_of(s["object"]) for s in samples]

    def rate(cells, test_i):
        return float(np.mean([maps[t][c] for t, c in zip(test_i, cells)]))

    def split_rates(seed, tmp):
        split = split_indices(len(samples), seed, groups=groups)
        report = train(data_dir, Path(tmp) / "net.pt", seed=seed,
                       epochs=epochs)["test"]
        rates = {name: report[key]["catch_rate"] for name, key in (
            ("network, labels", "network"),
            ("best constant cell", "best_constant_cell"),
            ("mean label", "mean_label"))}
        for sigma in SIGMAS_CELLS:
            rates[f"network, smoothed maps (σ {sigma} cells)"] = rate(
                map_trained_cells(x, maps, split, sigma, seed, epochs),
                split[2])
        for k in NEIGHBOURS:
            rates[f"nearest maps (k {k})"] = rate(
                nearest_maps_cells(x, maps, split, k), split[2])
        rates["a random cell"] = float(maps[split[2]].mean())
        return rates

    # A split's rates hold for this data set only: a row of another one (the
    # data set regenerated) is not reused.
    data_digest = hashlib.sha256(
        (Path(data_dir) / "samples.csv").read_bytes()
        + (Path(data_dir) / "maps.npz").read_bytes()).hexdigest()[:16]

    def key(row):
        return row["seed"], row["epochs"], row.get("data")

    done = read_rows(rows_path, key) if rows_path else {}
    with tempfile.TemporaryDirectory() as tmp:
        for n, seed in enumerate(seeds):
            if (seed, epochs, data_digest) not in done:
                row = {"seed": seed, "epochs": epochs, "data": data_digest,
                       "rates": split_rates(seed, tmp)}
                done[key(row)] = row
                if rows_path:
                    with open_rows(rows_path) as f:
                        f.write(json.dumps(row) + "\n")
            if progress:
                progress(n + 1, len(seeds))
    rates: dict[str, list] = {}
    for seed in seeds:
        for name, value in done[(seed, epochs, data_digest)]["rates"].items():
            rates.setdefault(name, []).append(value)
    constant = np.array(rates["best constant cell"])
    return {
        "data": str(data_dir), "samples": len(samples), "seeds": list(seeds),
        "epochs": epochs,
        "predictors": {
            name: {"mean_catch_rate": round(float(np.mean(r)), 4),
                   "vs_best_constant_cell": {
                       "more": int(np.sum(np.array(r) > constant)),
                       "as_many": int(np.sum(np.array(r) == constant)),
                       "fewer": int(np.sum(np.array(r) < constant))},
                   "catch_rates": [round(v, 4) for v in r]}
            for name, r in rates.items()}}


def plot(result, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(result["predictors"])
    fig, ax = plt.subplots(figsize=(8, 0.45 * len(names) + 1.5))
    for row, name in enumerate(names):
        r = result["predictors"][name]
        ax.plot(r["catch_rates"], [row] * len(r["catch_rates"]), "|",
                color="0.6", ms=10)
        ax.plot(r["mean_catch_rate"], row, "o", color="C0")
    constant = result["predictors"]["best constant cell"]["mean_catch_rate"]
    ax.axvline(constant, color="C3", ls=":", label="best constant cell (mean)")
    ax.set_yticks(range(len(names)), names)
    ax.invert_yaxis()
    ax.set_xlabel(f"test-split catch rate (| one split of {len(result['seeds'])},"
                  " ● their mean)")
    ax.set_title("Picking the catch cell from the five features, on stored maps")
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=20, metavar="N",
                   help="splits with the seeds 0 … N-1 (default 20)")
    p.add_argument("--epochs", type=int, default=3000, metavar="N",
                   help="training epochs of each network (default 3000, "
                        "train.py's)")
    p.add_argument("--data", type=Path, default=DATA_DIR, metavar="DIR")
    p.add_argument("--out", type=Path,
                   default=Path(__file__).with_name("network_alternatives"),
                   metavar="PATH", help="writes PATH.json and PATH.png")
    args = p.parse_args(argv)
    torch.set_num_threads(1)  # as `regrasp-drake train`: the same bits anywhere
    try:
        for flag, value in (("--seeds", args.seeds), ("--epochs", args.epochs)):
            if value < 1:
                raise InputError(f"{flag}: got {value}, expected an integer ≥ 1")
        args.out.parent.mkdir(parents=True, exist_ok=True)
        result = run(range(args.seeds), args.epochs, args.data,
                     rows_path=args.out.with_suffix(".jsonl"), progress=lambda
                     n, total: print(f"\rsplit {n}/{total}", end="",
                                     file=sys.stderr, flush=True))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(file=sys.stderr)
    for name, r in result["predictors"].items():
        v = r["vs_best_constant_cell"]
        print(f"{name:42s} {r['mean_catch_rate']:.3f}   vs best constant cell: "
              f"{v['more']} more / {v['as_many']} as many / {v['fewer']} fewer")
    args.out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    plot(result, args.out.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
