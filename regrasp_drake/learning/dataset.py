"""The training data: each training object's success map and its label.

For every object and each of its first `catch_points` catch points (the
ranked moments of `throw_catch.plan_catches`, at least
CATCH_POINT_SEPARATION_S apart): the watching throw and the offline stage
(the catch point and its v_catch), then one catch episode per cell of the
150-cell parameter space (the success map; cells share the simulated throw
up to their trigger, see episode/branching.py). An entry is named after its
object, `<object>` for the first catch point and `<object>@k` for the k-th.
The label of an entry is the catching cell most robust to error:

    robustness(c) = the Chebyshev distance (in cells) from c to the nearest
                    cell that does not catch (cells beyond the grid's edge
                    are not failures; a map with no failure gives every
                    catching cell the largest distance, 15).
    label = argmax robustness over the catching cells; ties go to the cell
            nearest (Euclidean, in cells) to the mean of the tied cells, then
            to the lowest (h_catch index, h_down index).

An entry none of whose cells catches has no label and is left out of the
training samples (the data set says so).

Files, under the output directory:
    cells/<entry>.jsonl    one line per finished cell, appended and flushed
                           as it finishes (a killed run resumes from these);
    plans/<entry>.json     the features, catch point and v_catch;
    samples.csv            one row per labelled entry: features and label;
    maps.npz               entries × 10 × 15 outcomes (1 caught, 0 not),
                           and each entry's features (entries × 5, in
                           FEATURE_NAMES order; the map-prior search's
                           feature kernel, learning/search.py);
    provenance.json        scenario, catalogue hash, code version, timing,
                           and every run that computed entries here;
    scenario.yaml          until the first run has finished: the scenario
                           the entries are computed with.
A data set is resumed only under the scenario it was begun with
(`check_same_scenario`).

Bounds (anything else is refused, naming the file, the line or field and
the value): entry names an object name (as in an object file) with an
optional @k; v_catch within ±50 m/s; h_cm, r_cm within ±0.3 m; d_obj
20 … 20 000 kg/m³; v_conv an integer 0 … 128; h_catch, h_down in the
parameter space; the label cell in the grid; robustness an integer
0 … 15; cells_caught an integer 1 … 150. The files are read within the
limits of regrasp_drake/input_files.py (size, nesting, duplicate keys,
finite numbers); maps.npz as learning/search.py's load_prior_maps reads it.

Over 500 lines: a data set's whole life (its entries computed on processes
or Ray, resumed under its lock, its provenance checked, then assembled
into labels and loaded for training) shares its file layout; splitting it
along those steps is the next clean-up.
"""

import csv
import hashlib
import json
import logging
import math
import multiprocessing
import os
import subprocess
import time
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io, grid, numerics
from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import load_json, parse_yaml, read_text
from regrasp_drake.learning.search import load_prior_maps
from regrasp_drake.parameter_space import (
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    cell_parameters,
    cells,
)
from regrasp_drake.paths import REPO_DIR, SDF_DIR
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.progress import bar as progress_bar
from regrasp_drake.station.scenario import load_scenario, scenario_yaml
from regrasp_drake.station.throw import free_time_s
from regrasp_drake.throw_catch import plan_catches, watch
from regrasp_drake.world.objects import (
    CATALOGUE_PATH,
    DENSITY_RANGE,
    MAX_CENTER_M,
    NAME_PATTERN,
    resolve_object,
)

FEATURE_NAMES = ("v_catch", "h_cm", "r_cm", "d_obj", "v_conv")
CATCH_POINT_SEPARATION_S = grid.CATCH_POINT_SEPARATION_S
SHAPE = (len(H_CATCH_VALUES), len(H_DOWN_VALUES))
_SAMPLE_COLUMNS = ["object", *FEATURE_NAMES, "h_catch", "h_down",
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


# ---- labels ------------------------------------------------------------------
def robustness(caught: np.ndarray) -> np.ndarray:
    """Per cell, the Chebyshev distance (cells) to the nearest failed cell;
    0 for failed cells. `caught`: a boolean array of SHAPE."""
    failed = np.argwhere(~caught)
    out = np.zeros(caught.shape, int)
    for i, j in np.argwhere(caught):
        if len(failed) == 0:
            out[i, j] = max(caught.shape)
        else:
            out[i, j] = int(np.min(np.maximum(np.abs(failed[:, 0] - i),
                                              np.abs(failed[:, 1] - j))))
    return out


def label_cell(caught: np.ndarray) -> tuple[int, int] | None:
    """The label of a success map (see the module's docstring), or None."""
    r = robustness(caught)
    if r.max() == 0:
        return None
    best = np.argwhere(r == r.max())
    mean = best.mean(axis=0)
    key = [(float(np.sum((c - mean) ** 2)), int(c[0]), int(c[1])) for c in best]
    _, i, j = min(key)
    return (i, j)


# ---- generation --------------------------------------------------------------
def entry_names(names, catch_points: int) -> list[str]:
    """The data set's entries: each object's catch points 1..catch_points."""
    return [n if k == 1 else f"{n}@{k}" for n in names
            for k in range(1, catch_points + 1)]


def object_of(entry: str) -> str:
    """The object an entry belongs to."""
    return entry.split("@")[0]


def _object_task(args):
    """One entry's plan and map (in a worker process); returns its name."""
    scenario, entry, out_dir, only = args
    name, _, point = entry.partition("@")
    point = int(point or 1)
    torch.set_num_threads(1)
    obj = resolve_object(name=name)
    ik = ArmIk(scenario.directives)
    out_dir = Path(out_dir)
    watched = watch(scenario, obj, ik)
    # The free-flight state at the end of the throw: the flight predictor's
    # training data.
    k = int(np.argmin(np.abs(watched.logs.t - free_time_s(scenario))))
    free = {"t_s": float(watched.logs.t[k]),
            "state": watched.logs.object_state[:, k].tolist()}
    try:
        plans = plan_catches(scenario, obj, ik, watched, count=point,
                             min_separation_s=CATCH_POINT_SEPARATION_S)
        if len(plans) < point:
            raise InputError(f"object {name}: {len(plans)} reachable catch "
                             f"point(s) at least {CATCH_POINT_SEPARATION_S} s "
                             f"apart, no catch point {point}")
    except InputError as e:  # no reachable catch point: recorded, no map
        _write_json(out_dir / "plans" / f"{entry}.json",
                    {"object": name, "usable": False, "reason": str(e),
                     "free_flight": free})
        return entry
    plan = plans[point - 1]
    features = {"v_catch": float(plan.catch_point.v_catch)} | obj.features()
    _write_json(out_dir / "plans" / f"{entry}.json",
                {"object": name, "catch_point": point, "usable": True,
                 "features": features, "plan": plan.as_dict(),
                 "free_flight": free})
    grid.run_map(scenario, obj, ik, plan, out_dir / "cells" / f"{entry}.jsonl",
                 workers=1, progress=False, only=only)
    return entry


def _write_json(path: Path, data) -> None:
    """Writes atomically (a kill leaves the old file or the new one)."""
    _write_text(path, json.dumps(data, indent=1) + "\n")


def _object_done(out_dir: Path, name: str, only) -> bool:
    plan = out_dir / "plans" / f"{name}.json"
    if not plan.exists():
        return False
    if not _read_plan(plan).get("usable"):
        return True
    rows = grid.read_rows(out_dir / "cells" / f"{name}.jsonl")
    wanted = cells() if only is None else [tuple(c) for c in only]
    return all(c in rows for c in wanted)


def generate(names: list[str], out_dir: Path, *, workers: int = 1,
             backend: str = "process", scenario=None,
             progress: bool = True, only=None, catch_points: int = 1) -> dict:
    """Computes every entry's plan and map not yet in out_dir (the objects'
    first `catch_points` catch points), then writes samples.csv, maps.npz
    and provenance.json. Returns the provenance. `only`: a subset of the
    cells (a coarse data set; the cells left out count as not catching).
    scenario: a Scenario (default: the shipped one); the workers get it as
    data (it pickles as its YAML). One run at a time works on a data set
    (LOCK_FILE in it)."""
    if backend not in ("process", "ray"):
        raise InputError(f"--backend: got {backend!r}, expected process or ray")
    if workers < 1:
        raise InputError(f"--workers: got {workers}, expected >= 1")
    if not 1 <= catch_points <= 5:
        raise InputError(f"--catch-points: got {catch_points}, expected 1 to 5")
    names = entry_names(names, catch_points)
    out_dir = Path(out_dir)
    scenario = scenario or load_scenario()
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_io.exclusive(out_dir / LOCK_FILE, what=f"data set {out_dir}",
                             wait=False):
        return _generate(names, out_dir, workers=workers, backend=backend,
                         scenario=scenario, progress=progress,
                         only=only, catch_points=catch_points)


# The lock a run holds on its data set directory (a second run on it is
# refused, naming the first's pid and host).
LOCK_FILE = "dataset.lock"


def _generate(names, out_dir, *, workers, backend, scenario, progress,
              only, catch_points) -> dict:
    """generate's work, under the data set's lock."""
    check_same_scenario(out_dir, scenario)
    (out_dir / "cells").mkdir(parents=True, exist_ok=True)
    todo = [n for n in names if not _object_done(out_dir, n, only)]
    start = time.perf_counter()
    tasks = [(scenario, n, str(out_dir), only) for n in todo]
    if tasks:
        runner = _run_ray if backend == "ray" else _run_processes
        with progress_bar(len(tasks), "data set", "entries",
                          enabled=progress) as shown:
            for name in runner(tasks, workers):
                shown.set_postfix_str(name)
                shown.update()
    wall_s = time.perf_counter() - start
    provenance = assemble(names, out_dir, scenario=scenario,
                          wall_s=wall_s, workers=workers, backend=backend,
                          catch_points=catch_points, computed=len(tasks))
    # provenance.json holds the scenario and the models' digest now
    # (check_same_scenario).
    (out_dir / "scenario.yaml").unlink(missing_ok=True)
    (out_dir / _MODELS_FILE).unlink(missing_ok=True)
    return provenance


# The robot's model files (the arm, the hand and their directives), which
# the scenario names by path only: a data set records their digest.
_MODELS_FILE = "robot_models.sha256"


def robot_models_digest() -> str:
    """A sha256 of sdf/'s robot model files (*.sdf, *.dmd.yaml; the
    objects have the catalogue's hash)."""
    digest = hashlib.sha256()
    sdf = SDF_DIR
    for path in sorted(list(sdf.glob("*.sdf")) + list(sdf.glob("*.dmd.yaml"))):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def scenario_text(scenario=None) -> str:
    """The scenario as the data set records it (its every value, YAML);
    None: the shipped one."""
    return scenario_yaml(scenario or load_scenario())


def check_same_scenario(out_dir: Path, scenario=None) -> None:
    """Entries are resumed and assembled only under the scenario they were
    computed with: the one in out_dir's provenance.json, or, before a run
    has finished, in its scenario.yaml (written here for a new data set).
    Another one is refused (InputError naming --scenario and the first
    field that differs): resuming would mix two scenarios' maps under one
    provenance. So are other robot model files (sdf/, which the scenario
    names by path only), when the data set recorded their digest."""
    _check_same_models(out_dir)
    current = scenario_text(scenario)
    provenance, started = out_dir / "provenance.json", out_dir / "scenario.yaml"
    stored = None
    if provenance.exists():
        try:
            stored = load_provenance(provenance).get("scenario")
        except InputError as e:
            raise InputError(f"--out: {e}") from None
        if stored is None:
            raise InputError(f"--out: {provenance}: no scenario text, "
                             "expected the data set's provenance")
    elif started.exists():
        stored = read_text(started, "scenario YAML file")
    if stored is None:
        out_dir.mkdir(parents=True, exist_ok=True)
        atomic_io.write_text(started, current)
        return
    if stored != current:
        try:
            a = parse_yaml(stored, tags=True)
        except InputError as e:
            raise InputError(f"--out: {out_dir}: the data set's scenario is "
                             f"{e}") from None
        a = a if isinstance(a, dict) else {}
        field, old, new = _first_difference(
            a, parse_yaml(current, tags=True) or {})
        raise InputError(
            f"--scenario: {field} is {new!r} here but {old!r} in the data set "
            f"in {out_dir} (computed with another scenario), expected the "
            "same scenario to resume it, or another --out")


def _check_same_models(out_dir: Path) -> None:
    """InputError when out_dir's entries were computed with other robot
    model files than sdf/'s now (the digest in its provenance.json, or in
    robot_models.sha256 before its first run finished; a new data set gets
    that file). A data set that recorded none is not checked."""
    current = robot_models_digest()
    provenance, started = out_dir / "provenance.json", out_dir / _MODELS_FILE
    if provenance.exists():
        try:
            stored = load_provenance(provenance).get("robot_models_sha256")
        except InputError as e:
            raise InputError(f"--out: {e}") from None
    elif started.exists():
        stored = read_text(started, "digest file").strip()
    else:
        if not (out_dir / "scenario.yaml").exists():  # a new data set
            out_dir.mkdir(parents=True, exist_ok=True)
            atomic_io.write_text(started, current + "\n")
        return
    if stored is not None and stored != current:
        raise InputError(
            f"sdf/: the robot models (*.sdf, *.dmd.yaml) have digest "
            f"{current} here but {stored} in the data set in {out_dir} "
            "(computed with other models), expected the same models to "
            "resume it, or another --out")


def _first_difference(a, b, prefix=""):
    """(dotted field, a's value, b's value) of the first field where two
    parsed YAML mappings differ."""
    for key in sorted(set(a) | set(b), key=str):
        x, y = a.get(key), b.get(key)
        if x == y:
            continue
        if isinstance(x, dict) and isinstance(y, dict):
            return _first_difference(x, y, f"{prefix}{key}.")
        return f"{prefix}{key}", x, y
    return prefix.rstrip(".") or "scenario", a, b


def _run_processes(tasks, workers):
    if workers == 1:
        for task in tasks:
            yield _object_task(task)
        return
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(workers, maxtasksperchild=1) as pool:
        yield from pool.imap_unordered(_object_task, tasks)


def _remote_entry(scenario, entry, only):
    """One entry's _object_task on a Ray worker, in a scratch directory of
    its own machine (a cluster's nodes share no filesystem with the driver):
    returns the entry, its plan file's text and its cells file's text (None
    for an entry with no usable catch point), for the driver to write."""
    import tempfile
    with tempfile.TemporaryDirectory() as scratch:
        scratch = Path(scratch)
        (scratch / "cells").mkdir()
        _object_task((scenario, entry, str(scratch), only))
        cells = scratch / "cells" / f"{entry}.jsonl"
        return (entry, (scratch / "plans" / f"{entry}.json").read_text(),
                cells.read_text() if cells.exists() else None)


def _write_text(path: Path, text: str) -> None:
    """Writes atomically (a kill leaves the old file or the new one), making
    its directory."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_text(path, text)


def _run_ray(tasks, workers):
    """The entries on Ray: the cluster at RAY_ADDRESS (its own CPUs set the
    parallelism), or, unset, a local Ray of `workers` CPUs started (and shut
    down) here. Each entry is computed
    whole on a worker and written here when it returns, its cells file
    before its plan file (an entry counts as done only once both are), so
    a killed run resumes as with processes: finished entries kept, the
    others computed again."""
    try:
        import ray
    except ImportError:
        raise InputError("--backend ray: Ray is not installed (pip install "
                         "'regrasp-drake[ray]')") from None
    address = os.environ.get("RAY_ADDRESS") or None
    # The workers of a cluster do not inherit this process's environment:
    # pass them the pinned kernels (numerics.py) explicitly.
    pinned = {k: os.environ[k] for k in numerics.VARIABLES if k in os.environ}
    started = not ray.is_initialized()
    if started:
        local = {} if address else {"num_cpus": workers,
                                    "include_dashboard": False}
        # "local": a Ray of our own even when another runs on this machine
        # (ray.init without an address would join that one).
        ray.init(address=address or "local", log_to_driver=False,
                 logging_level=logging.ERROR,  # not Ray's start-up notes
                 runtime_env={"env_vars": pinned}, **local)
    try:
        # A task lost with its node is retried (Ray's default, max_retries
        # 3; tests/test_dataset.py RayClusterTest kills a node mid-entry): an entry's
        # result does not depend on where or how often it is computed, and
        # only the returned result is written, so no cell is written twice.
        remote = ray.remote(num_cpus=1)(_remote_entry)
        waiting = {}  # task -> the output directory of its entry
        for scenario, entry, out_dir, only in tasks:
            waiting[remote.remote(scenario, entry, only)] = Path(out_dir)
        while waiting:
            ready, _ = ray.wait(list(waiting), num_returns=1)
            out_dir = waiting.pop(ready[0])
            entry, plan_text, cells_text = ray.get(ready[0])
            if cells_text is not None:
                _write_text(out_dir / "cells" / f"{entry}.jsonl", cells_text)
            _write_text(out_dir / "plans" / f"{entry}.json", plan_text)
            yield entry
    finally:
        if started:
            ray.shutdown()


# ---- assembly ----------------------------------------------------------------
def load_map(out_dir: Path, name: str) -> np.ndarray:
    """The object's map as a boolean array of SHAPE (True: caught; a cell
    not run counts as not caught)."""
    rows = grid.read_rows(Path(out_dir) / "cells" / f"{name}.jsonl")
    caught = np.zeros(SHAPE, bool)
    for (i, j), row in rows.items():
        caught[i, j] = row["outcome"] == "caught"
    return caught


def assemble(names, out_dir: Path, *, scenario=None, wall_s=None,
             workers=None, backend=None, catch_points=1,
             computed=None) -> dict:
    """Writes samples.csv, maps.npz and provenance.json from the per-entry
    files (entries in `names` order). wall_s, workers, backend and computed
    describe the run that called it: its wall time, and how many entries it
    computed (the others were already in out_dir)."""
    out_dir = Path(out_dir)
    maps, features, samples, unusable, unlabelled = [], [], [], [], []
    for name in names:
        plan = _read_plan(out_dir / "plans" / f"{name}.json")
        if not plan["usable"]:
            unusable.append({"object": name, "reason": plan["reason"]})
            continue
        caught = load_map(out_dir, name)
        maps.append(caught)
        features.append([plan["features"][k] for k in FEATURE_NAMES])
        cell = label_cell(caught)
        if cell is None:
            unlabelled.append(name)
            continue
        h_catch, h_down = cell_parameters(cell)
        samples.append({"object": name} | plan["features"] | {
            "h_catch": h_catch, "h_down": h_down,
            "label_i_catch": cell[0], "label_i_down": cell[1],
            "robustness": int(robustness(caught)[cell]),
            "cells_caught": int(caught.sum())})
    usable = [n for n in names if n not in {u["object"] for u in unusable}]
    with atomic_io.replace(out_dir / "maps.npz", "wb") as f:
        np.savez_compressed(f, objects=np.array(usable),
                            caught=np.array(maps, bool).reshape(-1, *SHAPE),
                            features=np.array(features, float).reshape(
                                -1, len(FEATURE_NAMES)),
                            feature_names=np.array(FEATURE_NAMES),
                            h_catch=H_CATCH_VALUES, h_down=H_DOWN_VALUES)
    with atomic_io.replace(out_dir / "samples.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=_SAMPLE_COLUMNS)
        writer.writeheader()
        writer.writerows(samples)
    provenance = {
        "objects": len(dict.fromkeys(map(object_of, names))),
        "catch_points_per_object": catch_points,
        "entries": len(names), "maps": len(maps), "samples": len(samples),
        "unusable": unusable, "unlabelled": unlabelled,
        "label_rule": "most robust catching cell (Chebyshev distance to the "
                      "nearest failed cell); ties: nearest the tied cells' "
                      "mean, then lowest indices",
        "scenario": scenario_text(scenario),
        "catalogue_sha256": hashlib.sha256(
            Path(CATALOGUE_PATH).read_bytes()).hexdigest(),
        "robot_models_sha256": robot_models_digest(),
        "code_version": _code_version(),
        "generation_wall_s": None if wall_s is None else round(wall_s, 1),
        "entries_computed": computed,
        "workers": workers, "backend": backend,
    }
    provenance["runs"] = _runs(out_dir, provenance)
    _write_json(out_dir / "provenance.json", provenance)
    return provenance


def _runs(out_dir: Path, provenance: dict) -> list[dict]:
    """The generation runs that computed the entries of out_dir, oldest
    first: those of the provenance.json already there (a file written
    before runs were kept counts as one run of all its entries), and this
    run, when it computed an entry."""
    runs = []
    path = out_dir / "provenance.json"
    if path.exists():
        old = load_provenance(path)
        runs = old.get("runs")
        if runs is None:
            runs = [] if old.get("generation_wall_s") is None else [{
                "wall_s": old["generation_wall_s"],
                "entries_computed": old.get("entries"),
                "workers": old.get("workers"), "backend": old.get("backend"),
                "code_version": old.get("code_version")}]
    if provenance["entries_computed"]:
        runs = runs + [{k: provenance[k] for k in (
            "code_version", "workers", "backend")} | {
            "wall_s": provenance["generation_wall_s"],
            "entries_computed": provenance["entries_computed"],
            "numerics": numerics.status()}]
    return runs


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
        if set(row) != set(_SAMPLE_COLUMNS) or None in row.values():
            raise InputError(f"{path}: line {n}: columns {quote(list(row))}, "
                             f"expected {', '.join(_SAMPLE_COLUMNS)}")
        _check_entry(f"{path}: line {n}: object", row["object"])
        for k in _SAMPLE_COLUMNS[1:]:
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


def _read_plan(path: Path) -> dict:
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


def _code_version() -> str:
    """The git commit (when known) and a hash of the package's and models'
    source files, which identifies uncommitted code too."""
    digest = hashlib.sha256()
    root = REPO_DIR
    for path in sorted(list((root / "regrasp_drake").rglob("*.py"))
                       + list((root / "sdf").rglob("*.*"))):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return git_version() + " sources-sha256:" + digest.hexdigest()[:16]


def git_version() -> str:
    """The repository's commit, with "+dirty" when its code or models have
    uncommitted changes; "unknown" outside a git checkout."""
    try:
        commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO_DIR,
                                capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--",
                                "regrasp_drake", "sdf"], cwd=REPO_DIR,
                               capture_output=True, text=True, check=True)
        return commit.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
