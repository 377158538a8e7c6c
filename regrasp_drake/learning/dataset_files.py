"""A data set's files (learning/dataset.py writes them) and their readers.

Files, under the data set's directory:
    cells/<entry>.jsonl    one line per finished cell, appended and flushed
                           as it finishes (a killed run resumes from these);
    plans/<entry>.json     the features, catch point and v_catch;
    samples.csv            one row per labelled entry: features and label
                           (learning/labels.py);
    maps.npz               entries × 10 × 15 outcomes (1 caught, 0 not),
                           and each entry's features (entries × 5, in
                           FEATURE_NAMES order; the map-prior search's
                           feature kernel, learning/search.py);
    provenance.json        scenario, catalogue hash, code version, timing,
                           and every run that computed entries here
                           (learning/provenance.py);
    scenario.yaml          until the first run has finished: the scenario
                           the entries are computed with.
An entry is named after its object, `<object>` for the first catch point
and `<object>@k` for the k-th.

Bounds (anything else is refused, naming the file, the line or field and
the value): entry names an object name (as in an object file) with an
optional @k; v_catch within ±50 m/s; h_cm, r_cm within ±0.3 m; d_obj
20 … 20 000 kg/m³; v_conv an integer 0 … 128; h_catch, h_down in the
parameter space; the label cell in the grid; robustness an integer
0 … 15; cells_caught an integer 1 … 150. The files are read within the
limits of regrasp_drake/input_files.py (size, nesting, duplicate keys,
finite numbers); maps.npz as learning/search.py's load_prior_maps reads it.
"""

import csv
import math
from pathlib import Path

import numpy as np

from regrasp_drake import grid
from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import load_json, read_text
from regrasp_drake.learning.labels import SHAPE
from regrasp_drake.learning.search import load_prior_maps
from regrasp_drake.parameter_space import H_CATCH_VALUES, H_DOWN_VALUES
from regrasp_drake.world.objects import (
    DENSITY_RANGE,
    MAX_CENTER_M,
    NAME_PATTERN,
)

FEATURE_NAMES = ("v_catch", "h_cm", "r_cm", "d_obj", "v_conv")

SAMPLE_COLUMNS = ["object", *FEATURE_NAMES, "h_catch", "h_down",
                   "label_i_catch", "label_i_down", "robustness",
                   "cells_caught"]

# The bounds of every number of a sample (and of a plan's features): low,
# high, unit; the columns of _INTEGERS hold integers.
_BOUNDS = {
    "v_catch": (-50.0, 50.0, " m/s"),
    "h_cm": (-MAX_CENTER_M, MAX_CENTER_M, " m"),
    "r_cm": (-MAX_CENTER_M, MAX_CENTER_M, " m"),
    "d_obj": (*DENSITY_RANGE, " kg/m³"),
    "v_conv": (0, 128, ""),
    "h_catch": (float(H_CATCH_VALUES[0]), float(H_CATCH_VALUES[-1]), " m"),
    "h_down": (float(H_DOWN_VALUES[0]), float(H_DOWN_VALUES[-1]), " m"),
    "label_i_catch": (0, SHAPE[0] - 1, ""),
    "label_i_down": (0, SHAPE[1] - 1, ""),
    "robustness": (0, max(SHAPE), ""),
    "cells_caught": (1, SHAPE[0] * SHAPE[1], ""),
}

_INTEGERS = ("v_conv", "label_i_catch", "label_i_down", "robustness",
             "cells_caught")


def entry_names(names, catch_points: int) -> list[str]:
    """The data set's entries: each object's catch points 1..catch_points."""
    return [n if k == 1 else f"{n}@{k}" for n in names
            for k in range(1, catch_points + 1)]


def object_of(entry: str) -> str:
    """The object an entry belongs to."""
    return entry.split("@")[0]


def load_map(out_dir: Path, name: str) -> np.ndarray:
    """The object's map as a boolean array of SHAPE (True: caught; a cell
    not run counts as not caught)."""
    rows = grid.read_rows(Path(out_dir) / "cells" / f"{name}.jsonl")
    caught = np.zeros(SHAPE, bool)
    for (i, j), row in rows.items():
        caught[i, j] = row["outcome"] == "caught"
    return caught


def load_samples(data_dir: Path) -> list[dict]:
    """The samples of a data set, with numbers as floats, each within its
    bounds (the module's docstring)."""
    path = Path(data_dir) / "samples.csv"
    if not path.exists():
        raise InputError(f"{path}: no such data set (run `regrasp-drake "
                         "dataset` first)")
    try:
        rows = list(csv.DictReader(read_text(path, "CSV file").splitlines()))
    except csv.Error as e:
        raise InputError(f"{path}: not a CSV table ({e})") from None
    for n, row in enumerate(rows, 2):
        if set(row) != set(SAMPLE_COLUMNS) or None in row.values():
            raise InputError(f"{path}: line {n}: columns {quote(list(row))}, "
                             f"expected {', '.join(SAMPLE_COLUMNS)}")
        _check_entry(f"{path}: line {n}: object", row["object"])
        for k in SAMPLE_COLUMNS[1:]:
            row[k] = _bounded(f"{path}: line {n}: {k}", row[k], k)
    return rows


def _bounded(field: str, value, column: str) -> float:
    """value (a number, or a number's text) as a float within the bounds of
    `column` (_BOUNDS); InputError naming `field` otherwise."""
    lo, hi, unit = _BOUNDS[column]
    integer = column in _INTEGERS
    x = math.nan
    if isinstance(value, (str, int, float)) and not isinstance(value, bool):
        try:
            x = float(value)
        except (ValueError, OverflowError):
            pass
    if not (math.isfinite(x) and lo <= x <= hi
            and (x.is_integer() or not integer)):
        raise field_error(field, value, f"{'an integer' if integer else 'a number'}"
                          f" in [{lo}, {hi}]{unit}")
    return x


def _check_entry(field: str, entry) -> None:
    """An entry's name: an object's name, with @k for its k-th catch point."""
    name, at, point = entry.partition("@") if isinstance(entry, str) else ("",) * 3
    if not (NAME_PATTERN.fullmatch(name)
            and (not at or point.isascii() and point.isdigit()
                 and len(point) <= 3)):
        raise field_error(field, entry, "an object's name, with @k for its "
                          "k-th catch point")


def read_plan(path: Path) -> dict:
    """An entry's plans/<entry>.json: usable, with its features (within the
    bounds of the module's docstring), or not, with the reason; InputError
    for one that is not."""
    plan = load_json(path)
    if not isinstance(plan, dict) or not isinstance(plan.get("usable"), bool):
        raise InputError(f"{path}: not an entry's plan (no usable: true or "
                         "false), expected one `regrasp-drake dataset` wrote")
    if not plan["usable"]:
        if not isinstance(plan.get("reason"), str):
            raise field_error(f"{path}: reason", plan.get("reason"),
                              "why the entry is not usable, a string")
        return plan
    features = plan.get("features")
    if not isinstance(features, dict) or set(features) != set(FEATURE_NAMES):
        raise field_error(f"{path}: features", features,
                          f"a mapping of exactly {', '.join(FEATURE_NAMES)}")
    for k in FEATURE_NAMES:
        _bounded(f"{path}: features.{k}", features[k], k)
    return plan


def load_provenance(path: Path) -> dict:
    """A data set's provenance.json: a mapping whose scenario (when there)
    is the scenario's text and whose runs (when there) are a list of
    mappings; InputError otherwise."""
    data = load_json(path)
    if not isinstance(data, dict):
        raise InputError(f"{path}: not a JSON mapping, expected the data "
                         "set's provenance")
    if not isinstance(data.get("scenario", ""), str):
        raise field_error(f"{path}: scenario", data["scenario"],
                          "the scenario's YAML text")
    runs = data.get("runs", [])
    if not (isinstance(runs, list) and all(isinstance(r, dict) for r in runs)):
        raise field_error(f"{path}: runs", runs, "a list of mappings")
    return data


def load_training_data(data_dir: Path) -> tuple[list[dict], dict, dict]:
    """What `train` reads of a data set, all checked before any training:
    its samples (load_samples), each sample's success map by entry name
    (maps.npz, as learning/search.py's load_prior_maps reads it) and its
    provenance ({} without a provenance.json)."""
    data_dir = Path(data_dir)
    samples = load_samples(data_dir)
    path = data_dir / "provenance.json"
    provenance = load_provenance(path) if path.exists() else {}
    names, caught = load_prior_maps(data_dir / "maps.npz")
    maps = dict(zip(names, caught))
    for n, sample in enumerate(samples, 2):
        if sample["object"] not in maps:
            raise InputError(f"{data_dir / 'samples.csv'}: line {n}: object "
                             f"{quote(sample['object'])} has no success map in "
                             f"{data_dir / 'maps.npz'}, expected a sample of "
                             "an entry there")
    return samples, maps, provenance
