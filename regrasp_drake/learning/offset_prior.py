"""Where the palm should wait along the object's axis: the offset prior.

The palm waits under the object at the target's offset (planning/grasp.py),
but the object does not stay where it lands: it slides along the palm as it
settles and the fingers close, by an amount that depends on the object and
the throw (table1-row4 under the flip: +13 mm; under keep: -9 mm). The
prior learns that slide from earlier throws, as the catch network learns its
parameters: one catch of each training object per target at the network's
cell, the palm at the target's offset, and the offset it ended at
(`collect`); then, per target, a ridge regression of the slide on the
network's five features (`OffsetPrior.fit`). The learning phase waits that
much the other way from its first throw on (learning_phase, `offset_prior`)
and corrects it further from what its own throws show.
"""

import dataclasses as dc
import json
import multiprocessing
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake import progress as progress_lines
from regrasp_drake.errors import InputError
from regrasp_drake.learning.learning_phase import NoCatchPoint, learn
from regrasp_drake.learning.planner import PAPER_NETWORK
from regrasp_drake.map_rows import open_rows, read_rows
from regrasp_drake.planning import grasp
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import (
    Scenario,
    scenario_digest,
    with_target,
)
from regrasp_drake.world.objects import resolve_object

# The ridge penalty on the standardized features (the 48 training objects
# give 48 rows a target at most).
RIDGE = 1.0


def target_key(target: Target) -> str:
    return f"{target.kind}:{target.offset_mm:+.0f}"


@dc.dataclass
class OffsetPrior:
    """Per target (`target_key`): the slide [mm] as mean + w · z, z the
    features standardized by their training mean and scale."""
    models: dict  # key -> {"mean", "weights", "feature_mean", "feature_std"}

    @staticmethod
    def fit(rows: list[dict]) -> "OffsetPrior":
        """From `collect`'s rows (those held with the axis right)."""
        models = {}
        for key in sorted({r["target"] for r in rows}):
            mine = [r for r in rows if r["target"] == key
                    and r.get("slide_mm") is not None]
            if len(mine) < 3:
                continue
            X = np.array([r["features"] for r in mine], float)
            y = np.array([r["slide_mm"] for r in mine], float)
            models[key] = _ridge(X, y) | {
                "rows": len(mine),
                "loo_abs_error_mm": _loo_error(X, y)}
        return OffsetPrior(models)

    def predict(self, target: Target, features) -> float:
        """The expected slide [mm] of a catch under `target` (0 for a target
        the prior has no model of)."""
        m = self.models.get(target_key(target))
        if m is None:
            return 0.0
        z = ((np.asarray(features, float) - m["feature_mean"])
             / m["feature_std"])
        return float(m["mean"] + np.asarray(m["weights"]) @ z)

    def save(self, path) -> None:
        atomic_io.write_json(path, {"models": self.models})

    @staticmethod
    def load(path) -> "OffsetPrior":
        path = Path(path)
        try:
            data = json.loads(path.read_text())
            models = data["models"]
            for key, m in models.items():
                if len(m["weights"]) != len(m["feature_mean"]):
                    raise ValueError(f"{key}: weights and features differ")
        except FileNotFoundError:
            raise InputError(f"{path}: no such offset prior") from None
        except (ValueError, KeyError, TypeError) as e:
            raise InputError(f"{path}: not an offset prior ({e}), expected "
                             "the JSON that `regrasp-drake train-offset` "
                             "writes") from None
        return OffsetPrior(models)


def _ridge(X, y) -> dict:
    mean, std = X.mean(axis=0), X.std(axis=0)
    std[std == 0] = 1.0
    Z = (X - mean) / std
    w = np.linalg.solve(Z.T @ Z + RIDGE * np.eye(Z.shape[1]),
                        Z.T @ (y - y.mean()))
    return {"mean": float(y.mean()), "weights": w.tolist(),
            "feature_mean": mean.tolist(), "feature_std": std.tolist()}


def _loo_error(X, y) -> float:
    """The mean |error| [mm] of each row predicted by the others' fit."""
    errors = []
    for k in range(len(y)):
        keep = np.arange(len(y)) != k
        m = _ridge(X[keep], y[keep])
        z = (X[k] - m["feature_mean"]) / np.asarray(m["feature_std"])
        errors.append(abs(m["mean"] + np.asarray(m["weights"]) @ z - y[k]))
    return round(float(np.mean(errors)), 2)


_JOBS: list = []


def _one(k: int) -> dict:
    """Job k of _JOBS (set before the workers fork: the scenario does not
    pickle): one catch of an object under a target at the network's cell (the
    learning phase's first catching throw, the palm at the target's
    offset): its slide, or None when it was not held with the axis and side
    right."""
    scenario, model, name, target = _JOBS[k]
    torch.set_num_threads(1)
    obj = resolve_object(name=name)
    row = {"object": name, "target": target_key(target),
           "scenario_digest": scenario_digest(scenario), "slide_mm": None}
    try:
        grasp.check_reachable(target, obj)
        result = learn(scenario, obj, model, ik=ArmIk(scenario.directives),
                       max_throws=2, progress=None, planner=PAPER_NETWORK)
    except (NoCatchPoint, InputError) as e:
        return row | {"outcome": "no_plan", "error": str(e)}
    attempt = result.attempts[0]
    error = attempt.grasp_error or {}
    row |= {"features": [round(x, 6) for x in result.features],
            "outcome": attempt.outcome, "cell": list(attempt.cell)}
    if (attempt.caught and error.get("axis_error_deg") is not None
            and error["axis_error_deg"] <= grasp.AXIS_TOLERANCE_DEG
            and error.get("side_ok") is not False):
        row["slide_mm"] = error["offset_error_mm"]
    return row


def collect(base: Scenario, model, targets, objects, rows_path, *,
            workers: int = 1, progress=None) -> list[dict]:
    """`_one` for every (target, object) not yet in rows_path (JSON lines,
    appended as each finishes: a rerun resumes; rows of another scenario
    are refused), on `workers` forked processes. Returns every row."""
    rows_path = Path(rows_path)
    rows = list(read_rows(rows_path, key=lambda r: (
        r["object"], r["target"])).values())
    jobs = []
    for target in targets:
        scenario = with_target(base, target)
        digest = scenario_digest(scenario)
        for name in objects:
            old = [r for r in rows if (r["object"], r["target"]) == (
                name, target_key(target))]
            if old and old[0]["scenario_digest"] != digest:
                raise InputError(
                    f"{rows_path}: the row of {name} under "
                    f"{target_key(target)} was made under another scenario, "
                    "expected the same scenario to resume it, or another "
                    "--out")
            if not old:
                jobs.append((scenario, model, name, target))
    _JOBS[:] = jobs
    with (multiprocessing.get_context("fork").Pool(workers) as pool,
          open_rows(rows_path) as f):
        for row in progress_lines.iterate(
                pool.imap(_one, range(len(jobs))), len(jobs), "offset prior",
                "episodes", enabled=progress is not None):
            rows.append(row)
            f.append(json.dumps(row))
            if progress is not None:
                progress_lines.say(
                    f"{row['target']} {row['object']}: {row['outcome']}, "
                    f"slide {row['slide_mm']} mm", progress)
    return rows
