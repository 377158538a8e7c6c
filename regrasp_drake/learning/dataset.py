"""The training data: each training object's success map and its label.

For every object and each of its first `catch_points` catch points (the
ranked moments of `throw_catch.plan_catches`, at least
CATCH_POINT_SEPARATION_S apart): the watching throw and the offline stage
(the catch point and its v_catch), then one catch episode per cell of the
150-cell parameter space (the success map; cells share the simulated throw
up to their trigger, see episode/branching.py). Then each entry's label,
the catching cell most robust to error (learning/labels.py). An entry none
of whose cells catches has no label and is left out of the training
samples (the data set says so).

The steps of a data set's life, each in its module: the entries computed
here, on processes or Ray, resumed under the data set's lock
(LOCK_FILE); their provenance recorded and checked (learning/provenance.py);
the entries assembled into samples.csv, maps.npz and provenance.json
(`assemble`); the files and their bounds, read back for training
(learning/dataset_files.py, which lists them).
"""

import contextlib
import csv
import hashlib
import json
import logging
import multiprocessing
import os
import time
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io, grid, numerics
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset_files import (
    FEATURE_NAMES,
    SAMPLE_COLUMNS,
    entry_names,
    load_map,
    object_of,
    read_plan,
)
from regrasp_drake.learning.labels import LABEL_RULE, SHAPE, label_cell, robustness
from regrasp_drake.learning.provenance import (
    MODELS_FILE,
    check_same_scenario,
    code_version,
    robot_models_digest,
    runs,
    scenario_text,
)
from regrasp_drake.parameter_space import (
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    cell_parameters,
    cells,
)
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.progress import bar as progress_bar
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.station.throw import free_time_s
from regrasp_drake.throw_catch import (
    CATCH_POINT_SEPARATION_S,
    plan_catches,
    watch,
)
from regrasp_drake.world.objects import CATALOGUE_PATH, resolve_object


# ---- generation --------------------------------------------------------------
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
    if not read_plan(plan).get("usable"):
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
    _check_run(backend, workers, catch_points)
    names = entry_names(names, catch_points)
    out_dir = Path(out_dir)
    scenario = scenario or load_scenario()
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_io.exclusive(out_dir / LOCK_FILE, what=f"data set {out_dir}",
                             wait=False):
        return _generate(names, out_dir, workers=workers, backend=backend,
                         scenario=scenario, progress=progress,
                         only=only, catch_points=catch_points)



def _check_run(backend, workers, catch_points) -> None:
    """Refuses a run's settings out of range (InputError naming the flag)."""
    if backend not in ("process", "ray"):
        raise InputError(f"--backend: got {backend!r}, expected process or ray")
    if workers < 1:
        raise InputError(f"--workers: got {workers}, expected >= 1")
    if not 1 <= catch_points <= 5:
        raise InputError(f"--catch-points: got {catch_points}, expected 1 to 5")


# The lock a run holds on its data set directory (a second run on it is
# refused, naming the first's pid and host).
LOCK_FILE = "dataset.lock"


def _generate(names, out_dir, *, workers, backend, scenario, progress,
              only, catch_points) -> dict:
    """generate's work, under the data set's lock."""
    check_same_scenario(out_dir, scenario)
    tasks = _tasks(names, out_dir, scenario, only)
    wall_s = _run(tasks, workers, backend, progress)
    return _finish(names, out_dir, scenario=scenario, wall_s=wall_s,
                   workers=workers, backend=backend,
                   catch_points=catch_points, computed=len(tasks))


def _tasks(names, out_dir, scenario, only) -> list:
    """The entries of out_dir not yet computed, as tasks of _object_task."""
    (out_dir / "cells").mkdir(parents=True, exist_ok=True)
    return [(scenario, n, str(out_dir), only) for n in names
            if not _object_done(out_dir, n, only)]


def _run(tasks, workers, backend, progress) -> float:
    """Computes the tasks (each writes its entry's files); their wall time."""
    start = time.perf_counter()
    if tasks:
        runner = _run_ray if backend == "ray" else _run_processes
        with progress_bar(len(tasks), "data set", "entries",
                          enabled=progress) as shown:
            for name in runner(tasks, workers):
                shown.set_postfix_str(name)
                shown.update()
    return time.perf_counter() - start


def _finish(names, out_dir, **run) -> dict:
    """Assembles out_dir's files; its provenance."""
    provenance = assemble(names, out_dir, **run)
    # provenance.json holds the scenario and the models' digest now
    # (check_same_scenario).
    (out_dir / "scenario.yaml").unlink(missing_ok=True)
    (out_dir / MODELS_FILE).unlink(missing_ok=True)
    return provenance


# The grasp targets of the data sets the learned planner trains on (issue
# 55): keep and flip, the palm at -30, 0 and +30 mm along the axis.
TARGET_SETS = tuple(Target(kind, offset) for kind in ("keep", "flip")
                    for offset in (-30.0, 0.0, 30.0))


def target_dir_name(target: Target) -> str:
    """A target's data set directory under a root: dataset_flip+0,
    dataset_keep-30, ..."""
    return f"dataset_{target.kind}{target.offset_mm:+.0f}"


def generate_targets(names: list[str], root: Path, *, targets=TARGET_SETS,
                     workers: int = 1, backend: str = "process",
                     scenario=None, progress: bool = True, only=None,
                     catch_points: int = 1) -> dict:
    """`generate` under each target at once: the data set of target t in
    root/target_dir_name(t), its scenario `scenario` aiming for t (its
    throw too: with_target). The entries of every target share one pool
    of workers (or Ray), so that no worker idles between targets; each
    data set is locked, checked (a data set begun under another target
    or scenario is refused before anything runs), resumed and assembled as
    `generate` does it. Returns each data set's provenance by directory
    name. only: as for generate."""
    _check_run(backend, workers, catch_points)
    names = entry_names(names, catch_points)
    base = scenario or load_scenario()
    sets = {target_dir_name(t): (Path(root) / target_dir_name(t),
                                 with_target(base, t)) for t in targets}
    with contextlib.ExitStack() as locks:
        for out_dir, _ in sets.values():
            out_dir.mkdir(parents=True, exist_ok=True)
            locks.enter_context(atomic_io.exclusive(
                out_dir / LOCK_FILE, what=f"data set {out_dir}", wait=False))
        for out_dir, target_scenario in sets.values():
            check_same_scenario(out_dir, target_scenario)
        todo = {key: _tasks(names, out_dir, target_scenario, only)
                for key, (out_dir, target_scenario) in sets.items()}
        wall_s = _run([t for tasks in todo.values() for t in tasks],
                      workers, backend, progress)
        # Each data set records the whole run's wall time, and how many of
        # its entries the run computed.
        return {key: _finish(names, out_dir, scenario=target_scenario,
                             wall_s=wall_s, workers=workers, backend=backend,
                             catch_points=catch_points,
                             computed=len(todo[key]))
                for key, (out_dir, target_scenario) in sets.items()}


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
        plan = read_plan(out_dir / "plans" / f"{name}.json")
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
        writer = csv.DictWriter(f, fieldnames=SAMPLE_COLUMNS)
        writer.writeheader()
        writer.writerows(samples)
    provenance = {
        "objects": len(dict.fromkeys(map(object_of, names))),
        "catch_points_per_object": catch_points,
        "entries": len(names), "maps": len(maps), "samples": len(samples),
        "unusable": unusable, "unlabelled": unlabelled,
        "label_rule": LABEL_RULE,
        "scenario": scenario_text(scenario),
        "catalogue_sha256": hashlib.sha256(
            Path(CATALOGUE_PATH).read_bytes()).hexdigest(),
        "robot_models_sha256": robot_models_digest(),
        "code_version": code_version(),
        "generation_wall_s": None if wall_s is None else round(wall_s, 1),
        "entries_computed": computed,
        "workers": workers, "backend": backend,
    }
    provenance["runs"] = runs(out_dir, provenance)
    _write_json(out_dir / "provenance.json", provenance)
    return provenance
