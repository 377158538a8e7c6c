"""The map-prior search against the paper's wavefront search, on stored
success maps only (no simulation).

    .venv/bin/python studies/search_prior/search_prior.py
        [--out studies/search_prior/search_prior.json]

A search's cost on a success map is the number of cells it tries up to and
including the first that catches (`search.attempts_to_catch`); in the
learning phase that is the catching throws, the watching throw not counted.
Three searches: the paper's wavefront, the map prior as the learning phase
runs it (its maps weighted by the feature kernel, search.FEATURE_SIGMA), and
the map prior with every map weighing alike ("map-prior-uniform").

0. The feature kernel's width: the leave-one-object-out search of section 1
   from the cell (7, 2), for each width of search.py's FEATURE_SIGMA comment;
   the width it picks by that comment's rule, and whether that is the
   shipped FEATURE_SIGMA. Then the same with a whole geometry held out
   (every object of the held-out entry's catalogue geometry removed from
   the prior), as the Table 1 objects are of geometries no training object
   has: the width that rule would pick there, and each width's cells on the
   Table 1 maps (as section 2). Reported, not used to choose.

1. Leave-one-object-out on the training maps (models/dataset/maps.npz): each
   entry whose map catches somewhere is held out with every entry of its
   object (every catch point) removed from the map prior, and searched from
   - the cell (7, 2) (a fixed start, kept from the first evaluations),
   - its own label cell (learning/labels.py's most robust catching cell: a
     catching cell by definition, so both searches need 1 cell; listed as
     the brief asked, a check rather than a comparison),
   - the label cell of the object's other catch point (the cell a network
     that knew the object but not the catch point would start at), where
     that map has a label.
   Reported per search: the mean cells tried, the share of entries caught
   within 1, 2 and 3 cells, and the worst case.
2. The Table 1 objects' maps (models/results/maps/table1-row*.jsonl, one
   line per cell with "cell" [i_catch, i_down] and "outcome"), searched from
   each row's start cell in models/results/table1.json (the network's cell
   at the watched plan), with the whole training prior (weighted by the
   row's features in table1.json). The predicted throws
   of `regrasp-drake table1 --search …` are these cells + 1 (the watch),
   and the cells tried are listed. If models/results/table1_prior.json
   (`regrasp-drake table1 --search map-prior`) exists, its throws and cells
   are set beside the prediction.
3. The network and the search together on objects neither has seen: for
   each of the seeds 0-4 the network is trained as `regrasp-drake train
   --seed k` does (its split by object, 44 / 10 / 10 in proportion), and
   each map of a test-split object is searched from the network's cell for
   it, with the map prior of every entry not of a test-split object. The
   figures pool the five splits (an entry may be tested in several).
   `--no-network-splits` skips it (it trains five networks, about 15 s).

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

from regrasp_drake.learning.dataset_files import object_of
from regrasp_drake.learning.labels import label_cell
from regrasp_drake.learning.search import (
    FEATURE_SIGMA,
    attempts_to_catch,
    feature_weighted_order,
    load_prior_maps,
    wavefront_order,
)
from regrasp_drake.paths import MODELS_DIR, REPO_DIR
from regrasp_drake.world.objects import load_catalogue

RESULTS_DIR = MODELS_DIR / "results"
FIXED_START = (7, 2)  # the network's cell for table1 rows 1-3 (table1.json)


SEARCHES = ("wavefront", "map-prior", "map-prior-uniform")
SIGMAS = (None, 4.0, 3.0, 2.0, 1.5, 1.0, 0.75, 0.5)  # FEATURE_SIGMA's choices


def search_order(search: str, start, prior, prior_features=None,
                 features=None, sigma=FEATURE_SIGMA):
    """The cells of `search` from start, with prior maps (and, for the
    weighted map prior, their entries' features and the object's)."""
    if search == "wavefront":
        return wavefront_order(start)
    return feature_weighted_order(
        start, prior, prior_features if search == "map-prior" else None,
        features, sigma)


def statistics(counts: dict) -> dict:
    """Over {entry: cells tried}: the mean and median cells tried, the share
    caught within 1, 2 and 3 cells, and the worst entry."""
    n = np.array(list(counts.values()))
    worst = max(counts, key=counts.get)
    return {"entries": len(n), "mean_cells": round(float(n.mean()), 3),
            "median_cells": float(np.median(n)),
            **{f"within_{k}": round(float(np.mean(n <= k)), 3)
               for k in (1, 2, 3)},
            "max_cells": int(n.max()), "worst_entry": worst}


def _width_rows(names, maps, features, group_of) -> list[dict]:
    """Per width of SIGMAS, the statistics of the map-prior search from
    FIXED_START on every entry that catches somewhere, with every entry of
    its group (group_of(entry name)) left out of the prior."""
    rows = []
    for sigma in SIGMAS:
        counts = {}
        for k, (name, caught) in enumerate(zip(names, maps)):
            if not caught.any():
                continue
            keep = [group_of(n) != group_of(name) for n in names]
            counts[name] = attempts_to_catch(search_order(
                "map-prior", FIXED_START, maps[keep], features[keep],
                features[k], sigma), caught)
        rows.append({"sigma": sigma} | statistics(counts))
    return rows


def _pick(rows):
    """The width FEATURE_SIGMA's comment's rule picks from _width_rows."""
    return max(rows, key=lambda r: (r["within_2"], r["within_3"]))["sigma"]


def feature_sigma(names, maps, features) -> dict:
    """Section 0 of the module's docstring."""
    rows = _width_rows(names, maps, features, object_of)
    chosen = _pick(rows)
    catalogue = load_catalogue()
    by_geometry = _width_rows(names, maps, features,
                              lambda n: catalogue[object_of(n)].geometry)
    t1 = json.loads((RESULTS_DIR / "table1.json").read_text())
    t1_maps = table1_maps()
    for row in by_geometry:
        row["table1_cells"] = {r["object"]: attempts_to_catch(search_order(
            "map-prior", tuple(r["start_cell"]), maps, features,
            r["features"], row["sigma"]), t1_maps[r["object"]]) for r in t1}
    return {"start_cell": list(FIXED_START), "widths": rows,
            "chosen": chosen, "shipped": FEATURE_SIGMA,
            "agrees": chosen == FEATURE_SIGMA,
            "leave_one_geometry_out": {"widths": by_geometry,
                                       "would_choose": _pick(by_geometry)}}


def leave_one_object_out(names, maps, features) -> dict:
    """Section 1 of the module's docstring."""
    by_name = dict(zip(names, maps))
    starts = {"fixed_cell_7_2": lambda name: FIXED_START,
              "own_label": lambda name: label_cell(by_name[name]),
              "other_catch_point_label": lambda name: _sibling_label(
                  name, names, by_name)}
    out = {"skipped_no_catching_cell": [n for n, m in zip(names, maps)
                                        if not m.any()]}
    for label, start_for in starts.items():
        counts = {s: {} for s in SEARCHES}
        for k, (name, caught) in enumerate(zip(names, maps)):
            start = start_for(name) if caught.any() else None
            if start is None:
                continue
            keep = [object_of(n) != object_of(name) for n in names]
            for s in SEARCHES:
                counts[s][name] = attempts_to_catch(search_order(
                    s, start, maps[keep], features[keep], features[k]),
                    caught)
        out[label] = {s: statistics(c) for s, c in counts.items()}
    return out


def _sibling_label(name, names, by_name):
    """The label cell of the other catch point of name's object, or None."""
    others = [n for n in names if object_of(n) == object_of(name) and n != name]
    labels = [label_cell(by_name[n]) for n in others]
    return next((c for c in labels if c is not None), None)


def table1_maps() -> dict:
    """{object: boolean map} of the Table 1 objects' stored success maps."""
    out = {}
    for path in sorted((RESULTS_DIR / "maps").glob("table1-row*.jsonl")):
        caught = np.zeros((10, 15), bool)
        seen = set()
        for line in path.read_text().splitlines():
            row = json.loads(line)
            cell = tuple(row["cell"])
            seen.add(cell)
            caught[cell] = row["outcome"] == "caught"
        if len(seen) != 150:
            sys.exit(f"{path}: {len(seen)} cells, expected all 150")
        out[path.stem] = caught
    return out


def table1(maps, prior_features) -> list[dict]:
    """Section 2 of the module's docstring."""
    rows = json.loads((RESULTS_DIR / "table1.json").read_text())
    start_cells = {r["object"]: tuple(r["start_cell"]) for r in rows}
    features = {r["object"]: r["features"] for r in rows}
    simulated = RESULTS_DIR / "table1_prior.json"
    simulated = ({r["object"]: r for r in json.loads(simulated.read_text())}
                 if simulated.exists() else {})
    rows = []
    for name, caught in table1_maps().items():
        start = start_cells[name]
        row = {"object": name, "start_cell": list(start),
               "cells_caught": int(caught.sum())}
        for s in SEARCHES:
            args = (s, start, maps, prior_features, features[name])
            n = attempts_to_catch(search_order(*args), caught)
            tried = list(search_order(*args))[:n or 150]
            row[s] = {"cells": n, "predicted_throws": None if n is None
                      else n + 1, "cells_tried": [list(c) for c in tried]}
        if name in simulated:
            r = simulated[name]
            cells = [a["cell"] for a in r["attempts"]]
            row["map-prior"] |= {
                "simulated_throws": r["throws"],
                "simulated_cells": cells,
                "simulated_outcomes": [a["outcome"] for a in r["attempts"]],
                "agrees": (r["throws"] == row["map-prior"]["predicted_throws"]
                           and cells == row["map-prior"]["cells_tried"])}
        rows.append(row)
    return rows


def network_splits(names, maps, features, seeds=range(5)) -> dict:
    """Section 3 of the module's docstring."""
    import tempfile

    import torch

    from regrasp_drake.grid import nearest_cell
    from regrasp_drake.learning.learning_phase import predict
    from regrasp_drake.learning.train import train
    from regrasp_drake.station.mlp_system import load_weights
    torch.set_num_threads(1)
    counts = {s: {} for s in SEARCHES}
    per_seed = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in seeds:
            report = train(MODELS_DIR / "dataset", Path(tmp) / "w.pt",
                           seed=seed)
            model, _ = load_weights(Path(tmp) / "w.pt")
            tested = {object_of(n) for n in report["split"]["test"]}
            keep = np.array([object_of(n) not in tested for n in names])
            seen = {}
            for k, (name, caught) in enumerate(zip(names, maps)):
                if object_of(name) not in tested or not caught.any():
                    continue
                start = nearest_cell(*predict(model, features[k])[1])
                for s in SEARCHES:
                    n = attempts_to_catch(search_order(
                        s, start, maps[keep], features[keep], features[k]),
                        caught)
                    counts[s][f"{name} (seed {seed})"] = n
                    seen.setdefault(s, []).append(n)
            per_seed.append({"seed": seed, "test_objects": sorted(tested),
                             "entries": len(seen.get("wavefront", [])),
                             **{s: round(float(np.mean(v)), 3)
                                for s, v in seen.items()}})
    return {"seeds": list(seeds), "per_seed_mean_cells": per_seed,
            **{s: statistics(c) for s, c in counts.items()}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path,
                        default=(REPO_DIR / "studies" / "search_prior"
                                 / "search_prior.json"))
    parser.add_argument("--no-network-splits", action="store_true",
                        help="skip section 3 (five network trainings)")
    args = parser.parse_args(argv)
    names, maps, features = load_prior_maps(with_features=True)
    if features is None:
        sys.exit("models/dataset/maps.npz: no 'features' (written before the "
                 "feature kernel): run `regrasp-drake dataset` to rewrite it")
    result = {"prior": {"file": "models/dataset/maps.npz",
                        "entries": len(names)},
              "feature_sigma": feature_sigma(names, maps, features),
              "leave_one_object_out": leave_one_object_out(names, maps,
                                                           features),
              "table1": table1(maps, features)}
    if not args.no_network_splits:
        result["network_splits"] = network_splits(names, maps, features)
    fs = result["feature_sigma"]
    print(f"feature kernel width, leave-one-object-out from {FIXED_START}:")
    for r in fs["widths"]:
        print(f"  sigma {str(r['sigma']):<5} mean {r['mean_cells']:5.2f} "
              f"cells, within 1/2/3: {r['within_1']:.3f} {r['within_2']:.3f}"
              f" {r['within_3']:.3f}, worst {r['max_cells']}")
    print(f"  chosen {fs['chosen']}, shipped {fs['shipped']} "
          f"(agrees: {fs['agrees']})")
    print("the same, leave-one-geometry-out (Table 1 cells beside):")
    for r in fs["leave_one_geometry_out"]["widths"]:
        print(f"  sigma {str(r['sigma']):<5} mean {r['mean_cells']:5.2f} "
              f"cells, within 1/2/3: {r['within_1']:.3f} {r['within_2']:.3f}"
              f" {r['within_3']:.3f}; Table 1 "
              f"{list(r['table1_cells'].values())}")
    print(f"  would choose {fs['leave_one_geometry_out']['would_choose']}")
    loo = result["leave_one_object_out"]
    print(f"leave-one-object-out, {len(names)} training maps "
          f"({len(loo['skipped_no_catching_cell'])} with no catching cell "
          "skipped):")
    for label in ("fixed_cell_7_2", "own_label", "other_catch_point_label"):
        for s in SEARCHES:
            st = loo[label][s]
            print(f"  start {label:<24} {s:<17} {st['entries']:>3} entries: "
                  f"mean {st['mean_cells']:5.2f} (median "
                  f"{st['median_cells']:g}) cells, within 1/2/3: "
                  f"{st['within_1']:.3f} {st['within_2']:.3f} "
                  f"{st['within_3']:.3f}, worst {st['max_cells']} "
                  f"({st['worst_entry']})")
    print("Table 1 maps (cells tried to the first catch; throws = cells + 1):")
    for row in result["table1"]:
        line = (f"  {row['object']} from {tuple(row['start_cell'])}: "
                + ", ".join(f"{s} {row[s]['cells']}" for s in SEARCHES))
        if "simulated_throws" in row["map-prior"]:
            line += (f"; simulated map-prior throws "
                     f"{row['map-prior']['simulated_throws']} (agrees: "
                     f"{row['map-prior']['agrees']})")
        print(line)
    if "network_splits" in result:
        ns = result["network_splits"]
        print("network + search on test-split objects, seeds "
              f"{ns['seeds'][0]}-{ns['seeds'][-1]} pooled:")
        for s in SEARCHES:
            st = ns[s]
            print(f"  {s:<17} {st['entries']:>3} entries: mean "
                  f"{st['mean_cells']:5.2f} (median {st['median_cells']:g}) "
                  f"cells, within 1/2/3: {st['within_1']:.3f} "
                  f"{st['within_2']:.3f} {st['within_3']:.3f}, worst "
                  f"{st['max_cells']} ({st['worst_entry']})")
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"written: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
