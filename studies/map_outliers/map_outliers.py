"""How typical each success map is of the training maps, and whether how a
cell failed tells a search where to go next; on stored maps only (no
simulation).

    .venv/bin/python studies/map_outliers/map_outliers.py
        [--out studies/map_outliers/map_outliers.json]

1. Typicality. The training catch frequency F is, per cell, the share of the
   training maps (models/dataset/maps.npz) that catch there: what every
   predictor learned from those maps (the network, the best constant cell,
   the map prior) leans on. A map's typicality is the Pearson correlation
   between the map (1 caught, 0 not) and F over the 150 cells: near 1 where
   the map catches where most training maps do, negative where it catches
   where they do not. Each training entry is measured against F of the
   other objects' maps (every catch point of its own object left out); each
   Table 1 map (models/results/maps/table1-row*.jsonl) against F of all
   training maps. Reported per Table 1 row: its typicality, the share of
   training entries (of those that catch in some cells and fail in others)
   that are less typical, and F's mean over its catching and its failing
   cells.

2. Searching on the ending. `regrasp-drake grid` sorts every failed cell by
   how it ended (grid.ending: below the palm, in the fingers, against the
   arm, ...), and the data set stores that ending for every training cell
   (models/dataset/cells/*.jsonl). The map prior (learning/search.py) reads
   a failure only as "not caught"; the ending prior reads it as "ended so":
   map m's weight is multiplied, after a failure at cell c with ending k, by

       EPS_k + (1 - 2 EPS_k) · E_m[k, c],

   E_m[k] being m's one-hot map of ending k smoothed as search.smooth does
   the catch maps. The next cell is, as for the map prior, the untried cell
   with the largest posterior catch probability. Evaluated
   leave-one-object-out on the training maps from the cell (7, 2), as
   studies/search_prior/search_prior.py does, and on the Table 1 maps from the
   network's cells (models/results/table1.json); the endings of those maps
   are those of studies/failure_modes/failure_modes/table1-row*.jsonl, a rerun equal
   to the stored maps cell for cell (checked here). Cells tried to the
   first catch: in the learning phase, the catching throws (the watch not
   counted).

Writes the JSON and a PNG beside it (the typicality histogram with the Table
1 rows marked, F, and the least typical Table 1 map).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, check_output_path, field_error
from regrasp_drake import grid
from regrasp_drake.grid import H_CATCH_VALUES, H_DOWN_VALUES, ending
from regrasp_drake.learning.dataset import object_of
from regrasp_drake.learning.search import (
    EPS,
    SHAPE,
    SIGMA_CELLS,
    MapPrior,
    Search,
    attempts_to_catch,
    load_prior_maps,
    map_prior_order,
    smooth,
)
from regrasp_drake.paths import MODELS_DIR

ROOT = Path(__file__).resolve().parents[2]
DATASET_DIR = MODELS_DIR / "dataset"
RESULTS_DIR = MODELS_DIR / "results"
FAILURE_MODES_DIR = ROOT / "studies" / "failure_modes" / "failure_modes"
FIXED_START = (7, 2)  # as studies/search_prior/search_prior.py
# grid.ending's keys (the index of E_m's first axis).
ENDING_KEYS = tuple(grid.ENDINGS)
ENDING_EPS = (EPS, 0.1, 0.05)  # the ending prior's EPS_k tried (all k alike)


def typicality(caught, frequency) -> float:
    """The Pearson correlation between a map (10 x 15 booleans) and a
    catch-frequency map; nan for a map that catches everywhere or nowhere."""
    x = np.asarray(caught, float).ravel()
    f = np.asarray(frequency, float).ravel()
    if x.std() == 0 or f.std() == 0:
        return float("nan")
    return float(np.corrcoef(x, f)[0, 1])


def training_typicality(names, maps) -> dict:
    """{entry: typicality against the other objects' maps} for every entry
    whose map neither catches everywhere nor nowhere."""
    out = {}
    objects = np.array([object_of(n) for n in names])
    for k, name in enumerate(names):
        t = typicality(maps[k], maps[objects != objects[k]].mean(axis=0))
        if not np.isnan(t):
            out[name] = t
    return out


def read_rows(path: Path) -> dict:
    """{cell: row} of a whole map's JSON lines (grid.read_rows); a missing
    file or one without all 150 cells is refused in one line."""
    rows = grid.read_rows(path) if path.is_file() else {}
    if len(rows) != SHAPE[0] * SHAPE[1]:
        raise field_error("map", str(path), f"a JSON-lines map of all "
                          f"{SHAPE[0] * SHAPE[1]} cells (got {len(rows)})")
    return rows


def caught_map(rows: dict) -> np.ndarray:
    """The boolean success map of {cell: row}."""
    out = np.zeros(SHAPE, bool)
    for cell, row in rows.items():
        out[cell] = row["outcome"] == "caught"
    return out


def ending_map(rows: dict) -> np.ndarray:
    """Each cell's index into ENDING_KEYS (10 x 15 ints)."""
    out = np.zeros(SHAPE, int)
    for cell, row in rows.items():
        out[cell] = ENDING_KEYS.index(ending(row))
    return out


def ending_prior_order(start_cell, prior_maps, prior_endings, observed,
                       eps: float = EPS, sigma_cells: float = SIGMA_CELLS):
    """The ending prior's search from start_cell (the module's docstring,
    section 2): a generator of cells, start_cell first; each cell yielded is
    taken to have failed with the ending observed[cell] (an index into
    ENDING_KEYS) when the next is asked for.

    prior_maps: (entries, 10, 15) booleans; prior_endings: (entries, 10, 15)
    indices into ENDING_KEYS; observed: (10, 15) indices."""
    maps = np.asarray(prior_maps, float)
    endings = np.asarray(prior_endings)
    if endings.shape != maps.shape:
        raise field_error("prior_endings", f"shape {endings.shape}",
                          f"the prior maps' shape {maps.shape}")
    onehot = np.stack([endings == k for k in range(len(ENDING_KEYS))], axis=1)
    E = smooth(onehot.reshape(-1, *SHAPE), sigma_cells).reshape(onehot.shape)
    # The map prior's search, reading the failure's ending at each cell.
    return iter(Search(start_cell, MapPrior(
        maps, eps=eps, sigma_cells=sigma_cells,
        observed=lambda c: E[:, observed[c], c[0], c[1]])))


def training_endings(names, maps, cells_dir: Path) -> np.ndarray:
    """The stored endings of every training entry (entries, 10, 15), checked
    against its map in maps.npz."""
    out = []
    for name, caught in zip(names, maps):
        rows = read_rows(cells_dir / f"{name}.jsonl")
        if not np.array_equal(caught_map(rows), caught):
            raise field_error("cells", str(cells_dir / f"{name}.jsonl"),
                              f"the outcomes of {name}'s map in maps.npz")
        out.append(ending_map(rows))
    return np.stack(out)


def _statistics(counts: list) -> dict:
    n = np.array(counts)
    return {"entries": len(n), "mean_cells": round(float(n.mean()), 3),
            **{f"within_{k}": round(float(np.mean(n <= k)), 3)
               for k in (1, 2, 3)}}


def ending_search(names, maps, endings, table1_maps, table1_endings,
                  starts) -> dict:
    """Section 2 of the module's docstring: {search: {"training": statistics,
    "table1": {row: cells tried}}}."""
    objects = np.array([object_of(n) for n in names])
    searches = {"map-prior": lambda start, keep, observed: map_prior_order(
        start, maps[keep])}
    for eps in ENDING_EPS:
        searches[f"ending-prior eps {eps}"] = (
            lambda start, keep, observed, eps=eps: ending_prior_order(
                start, maps[keep], endings[keep], observed, eps))
    out = {}
    for label, order in searches.items():
        counts = [attempts_to_catch(order(FIXED_START, objects != objects[k],
                                          endings[k]), maps[k])
                  for k in range(len(names)) if maps[k].any()]
        everything = np.ones(len(names), bool)
        out[label] = {"training": _statistics(counts), "table1": {
            row: attempts_to_catch(order(starts[row], everything,
                                         table1_endings[row]), caught)
            for row, caught in table1_maps.items()}}
    return out


def summarize(names, maps, table1_maps) -> dict:
    """Section 1 of the module's docstring."""
    train = training_typicality(names, maps)
    values = np.array(list(train.values()))
    frequency = maps.mean(axis=0)
    rows = {}
    for row, caught in table1_maps.items():
        t = typicality(caught, frequency)
        rows[row] = {
            "cells_caught": int(caught.sum()),
            "typicality": round(t, 3),
            "training_less_typical": round(float(np.mean(values < t)), 3),
            "frequency_where_caught": round(float(frequency[caught].mean()), 3),
            "frequency_where_failed": round(float(frequency[~caught].mean()), 3)}
    return {"training": {
        "entries": len(values), "mean": round(float(values.mean()), 3),
        "median": round(float(np.median(values)), 3),
        "share_negative": round(float(np.mean(values < 0)), 3),
        "least_typical": sorted(train, key=train.get)[:5]},
        "table1": rows, "_training_values": values,
        "_frequency": frequency}


def plot(summary, table1_maps, path: Path):
    """The PNG of the module's docstring."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6), layout="constrained",
                             gridspec_kw={"width_ratios": [1.1, 1, 1]})
    ax = axes[0]
    ax.hist(summary["_training_values"], bins=24, color="0.7",
            label="training entries (vs the other objects' maps)")
    for row, r in summary["table1"].items():
        ax.axvline(r["typicality"], color=f"C{row - 1}", lw=2,
                   label=f"Table 1 row {row}: {r['typicality']:+.2f}")
    ax.set_xlabel("typicality: corr(map, training catch frequency)")
    ax.set_ylabel("training entries")
    ax.legend(fontsize=8)
    worst = min(summary["table1"], key=lambda r: summary["table1"][r]["typicality"])
    extent = [H_DOWN_VALUES[0] - 0.005, H_DOWN_VALUES[-1] + 0.005,
              H_CATCH_VALUES[0] - 0.02, H_CATCH_VALUES[-1] + 0.02]
    for ax, image, title, cmap in (
            (axes[1], summary["_frequency"],
             "training catch frequency (share of maps)", "viridis"),
            (axes[2], table1_maps[worst].astype(float),
             f"table1-row{worst}'s map (caught: yellow)", "viridis")):
        im = ax.imshow(image, origin="lower", aspect="auto", extent=extent,
                       cmap=cmap, vmin=0, vmax=1)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("h_down [m]")
        ax.set_ylabel("h_catch [m]")
    fig.colorbar(im, ax=axes[2], shrink=0.8, label="share / caught")
    fig.suptitle("How typical each map is of the training maps")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(Path(__file__).with_suffix(".json")))
    args = parser.parse_args(argv)
    try:
        out = Path(args.out)
        check_output_path("--out", out)
        names, maps = load_prior_maps(DATASET_DIR / "maps.npz")
        path = RESULTS_DIR / "table1.json"
        try:
            starts = {r["row"]: tuple(r["start_cell"])
                      for r in json.loads(path.read_text())}
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise field_error("table1 results", str(path),
                              "`regrasp-drake table1 --json` output, each row "
                              f"with 'row' and 'start_cell' ({type(e).__name__})"
                              ) from None
        table1_maps, table1_endings = {}, {}
        for row in sorted(starts):
            stored = caught_map(
                read_rows(RESULTS_DIR / "maps" / f"table1-row{row}.jsonl"))
            rerun = read_rows(FAILURE_MODES_DIR / f"table1-row{row}.jsonl")
            if not np.array_equal(caught_map(rerun), stored):
                raise field_error("failure_modes map", f"table1-row{row}",
                                  "the stored Table 1 map, cell for cell")
            table1_maps[row], table1_endings[row] = stored, ending_map(rerun)
        endings = training_endings(names, maps, DATASET_DIR / "cells")
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    summary = summarize(names, maps, table1_maps)
    result = {
        "training_maps": len(names),
        "typicality": {k: v for k, v in summary.items() if not k.startswith("_")},
        "ending_search": {"start_cell_training": list(FIXED_START),
                          "table1_start_cells": {r: list(c) for r, c in starts.items()},
                          "searches": ending_search(names, maps, endings, table1_maps,
                                                    table1_endings, starts)}}
    out.write_text(json.dumps(result, indent=1) + "\n")
    plot(summary, table1_maps, out.with_suffix(".png"))
    t = result["typicality"]
    print(f"training entries: typicality mean {t['training']['mean']}, "
          f"{t['training']['share_negative']:.1%} negative")
    for row, r in t["table1"].items():
        print(f"table1-row{row}: {r['cells_caught']} cells, typicality "
              f"{r['typicality']:+.3f} (training less typical: "
              f"{r['training_less_typical']:.1%}), training frequency where "
              f"caught {r['frequency_where_caught']}, where failed "
              f"{r['frequency_where_failed']}")
    for label, s in result["ending_search"]["searches"].items():
        tr = s["training"]
        print(f"{label}: training mean {tr['mean_cells']} cells, within 2 "
              f"{tr['within_2']}, within 3 {tr['within_3']}; Table 1 cells "
              f"{[s['table1'][r] for r in sorted(s['table1'])]}")
    print(f"wrote {out} and {out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
