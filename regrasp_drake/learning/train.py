"""Training the catch network on the data set, and judging it (issue 5).

The paper's network: 5 inputs (v_catch, h_cm, r_cm, d_obj, v_conv), 13 tanh
neurons, 2 outputs (h_catch, h_down); its 64 samples split 44 / 10 / 10 at
random into training, validation and test. Here the split keeps those
proportions for any number of samples, drawn with a fixed seed. Inputs and
outputs are normalized by the training split's means and standard deviations
(kept in the weights file). Full-batch Adam on the mean squared error of the
normalized outputs; the weights kept are those of the epoch with the lowest
validation loss.

Judged on the test split: the error of (h_catch, h_down), and how often the
predicted parameters' cell catches (read from the object's success map),
against two baselines: the single cell that catches the most training
objects, used for every object; and the mean of the training labels.
"""

from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset_files import (
    FEATURE_NAMES,
    load_training_data,
    object_of,
)
from regrasp_drake.parameter_space import cell_parameters, nearest_cell
from regrasp_drake.station.mlp_system import CatchMlp, ParameterSpace, save_weights

SPLIT = (44, 10, 10)  # the paper's training / validation / test counts


def split_indices(n: int, seed: int = 0,
                  groups: list | None = None) -> tuple[list, list, list]:
    """A random split of n samples in the paper's 44 / 10 / 10 proportions.
    `groups` (one key per sample, e.g. its object): samples of one group go
    to the same split, so that no object's other catch point is tested on
    after training on one. Fewer than 3 groups (a smoke-test data set)
    cannot be split: all three splits are then all the samples."""
    if n < 1:
        raise InputError("data set: no samples (no object caught in any cell)")
    groups = list(range(n)) if groups is None else list(groups)
    keys = list(dict.fromkeys(groups))
    if len(keys) < 3:
        return list(range(n)), list(range(n)), list(range(n))
    order = [keys[i] for i in np.random.default_rng(seed).permutation(len(keys))]
    n_val = max(1, round(n * SPLIT[1] / sum(SPLIT)))
    n_test = max(1, round(n * SPLIT[2] / sum(SPLIT)))
    members = {k: [i for i, g in enumerate(groups) if g == k] for k in keys}
    test, val, train = [], [], []
    for k in order:  # test first, then validation, the rest training
        if len(test) < n_test:
            test += members[k]
        elif len(val) < n_val:
            val += members[k]
        else:
            train += members[k]
    return sorted(train), sorted(val), sorted(test)


def _arrays(samples):
    x = np.array([[s[f] for f in FEATURE_NAMES] for s in samples], float)
    y = np.array([[s["h_catch"], s["h_down"]] for s in samples], float)
    return x, y


def train(data_dir: Path, out: Path, *, seed: int = 0, epochs: int = 3000,
          learning_rate: float = 0.01, curve_png: Path | None = None,
          report_json: Path | None = None) -> dict:
    """Trains on data_dir's samples, writes the weights to `out`, and
    returns the report; writes the training curve to curve_png and the
    report to report_json too, when given (the command line's names:
    cli._train_files)."""
    data_dir, out = Path(data_dir), Path(out)
    samples, maps, provenance = load_training_data(data_dir)
    train_i, val_i, test_i = split_indices(
        len(samples), seed, groups=[object_of(s["object"]) for s in samples])
    x, y = _arrays(samples)
    torch.manual_seed(seed)
    model = CatchMlp()
    model.set_normalization(torch.as_tensor(x[train_i]),
                            torch.as_tensor(y[train_i]))
    xt = {k: torch.as_tensor(x[i]) for k, i in
          (("train", train_i), ("val", val_i))}
    yt = {k: (torch.as_tensor(y[i]) - model.output_mean) / model.output_std
          for k, i in (("train", train_i), ("val", val_i))}

    def loss(split):
        pred = (model(xt[split]) - model.output_mean) / model.output_std
        return torch.mean((pred - yt[split]) ** 2)

    best_epoch, best_score, curve = fit(
        model, lambda: loss("train"), lambda: -float(loss("val")),
        epochs=epochs, learning_rate=learning_rate)

    report = evaluate(model, samples, maps, train_i, test_i)
    report |= {
        "samples": len(samples),
        "split": {"train": [samples[i]["object"] for i in train_i],
                  "validation": [samples[i]["object"] for i in val_i],
                  "test": [samples[i]["object"] for i in test_i]},
        # False when the data set has too few objects to split
        # (split_indices): every figure is then on the training samples.
        "held_out": not set(test_i) & set(train_i),
        "seed": seed, "epochs": epochs, "best_epoch": best_epoch,
        "best_validation_loss": -best_score,
        "final_training_loss": curve["train"][-1],
    }
    metadata = {
        "features": list(FEATURE_NAMES), "outputs": ["h_catch", "h_down"],
        "hidden": 13, "seed": seed, "epochs": epochs, "best_epoch": best_epoch,
        "data": {"samples": len(samples),
                 "code_version": provenance.get("code_version"),
                 "catalogue_sha256": provenance.get("catalogue_sha256")},
        "split": report["split"],
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    save_weights(out, model, metadata)
    if report_json is not None:
        atomic_io.write_json(report_json, report)
    if curve_png is not None:
        _plot_curve(curve, best_epoch, curve_png)
    return report


def fit(model, training_loss, validation_score, *, epochs: int,
        learning_rate: float):
    """Full-batch Adam on training_loss() for `epochs` epochs; the model
    keeps the weights of the epoch with the highest validation_score().
    Returns that epoch, its score and the curves of both (the score's
    negative, so that a loss reads as a loss)."""
    optimizer = torch.optim.Adam(model.parameters(), lr=learning_rate)
    curve = {"train": [], "val": []}
    best = (-float("inf"), 0, None)
    for epoch in range(epochs):
        optimizer.zero_grad()
        loss = training_loss()
        loss.backward()
        optimizer.step()
        with torch.no_grad():
            score = validation_score()
        curve["train"].append(float(loss.detach()))
        curve["val"].append(-score)
        if score > best[0]:
            best = (score, epoch,
                    {k: v.clone() for k, v in model.state_dict().items()})
    model.load_state_dict(best[2])
    model.eval()
    return best[1], best[0], curve


def repeated_splits(data_dir: Path, seeds, *, epochs: int = 3000,
                    learning_rate: float = 0.01) -> dict:
    """The test-split catch rates of the network and both baselines over
    several random splits (one training per seed): a test split of a few
    objects is a noisy judge, their mean over splits less so."""
    import tempfile
    rates = {"network": [], "best_constant_cell": [], "mean_label": []}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            report = train(data_dir, Path(tmp) / f"split{seed}.pt", seed=seed,
                           epochs=epochs, learning_rate=learning_rate)
            for name in rates:
                rates[name].append(report["test"][name]["catch_rate"])
    network = np.array(rates["network"])
    return {"seeds": list(seeds),
            "mean_catch_rate": {k: round(float(np.mean(v)), 4)
                                for k, v in rates.items()},
            # Splits on which the network catches more / as many / fewer of
            # the test objects than each baseline.
            "network_vs": {k: {"better": int(np.sum(network > np.array(v))),
                               "equal": int(np.sum(network == np.array(v))),
                               "worse": int(np.sum(network < np.array(v)))}
                           for k, v in rates.items() if k != "network"},
            "catch_rates": {k: [round(x, 4) for x in v]
                            for k, v in rates.items()}}


def evaluate(model, samples, maps, train_i, test_i) -> dict:
    """Test-split errors and catch rates, with the two baselines; maps: each
    sample's success map by entry name (load_training_data)."""
    x, y = _arrays(samples)
    space = ParameterSpace()
    with torch.no_grad():
        pred = model(torch.as_tensor(x[test_i])).numpy()
    pred = np.array([space.clamp(*p) for p in pred])
    # Baselines from the training split only.
    train_maps = np.array([maps[samples[i]["object"]] for i in train_i])
    best_cell = tuple(int(c) for c in np.unravel_index(
        np.argmax(train_maps.sum(axis=0)), train_maps.shape[1:]))
    mean_label = y[train_i].mean(axis=0)

    def rate(cell_for):
        hits = [bool(maps[samples[i]["object"]][cell_for(k)])
                for k, i in enumerate(test_i)]
        return sum(hits) / len(hits)

    def error(p):
        e = np.abs(np.asarray(p) - y[test_i])
        return {"h_catch_mae_m": round(float(e[:, 0].mean()), 4),
                "h_down_mae_m": round(float(e[:, 1].mean()), 4)}

    return {
        "test": {
            "network": error(pred) | {"catch_rate": rate(
                lambda k: nearest_cell(*pred[k]))},
            "best_constant_cell": error(
                [cell_parameters(best_cell)] * len(test_i)) | {
                "cell": list(cell_parameters(best_cell)),
                "catch_rate": rate(lambda k: best_cell)},
            "mean_label": error([mean_label] * len(test_i)) | {
                "parameters": [round(float(v), 4) for v in mean_label],
                "catch_rate": rate(lambda k: nearest_cell(*mean_label))},
            "objects": [samples[i]["object"] for i in test_i],
        },
    }


def _plot_curve(curve, best_epoch, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(curve["train"], label="training")
    ax.semilogy(curve["val"], label="validation")
    ax.axvline(best_epoch, color="k", ls=":", label=f"kept (epoch {best_epoch})")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE of normalized (h_catch, h_down)")
    ax.legend()
    ax.set_title("Catch network training")
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)
