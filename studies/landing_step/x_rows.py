"""What the probes of FINDINGS §18 share: X's rows (X_eighth.jsonl, one per
pair), each pair's scenario, plans and rehearsal set up again as the
rehearsal made them, and a resumable run of a probe over pairs."""
import regrasp_drake  # noqa: F401, I001 (first: it pins NumPy's kernels)
import json
import multiprocessing

import torch

from regrasp_drake.learning import rehearsal as rh
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import (
    load_scenario,
    scenario_digest,
    with_target,
)
from regrasp_drake.world.objects import resolve_object

RESULTS = MODELS_DIR / "results" / "landing_step"
X_ROWS = RESULTS / "X_eighth.jsonl"


def pair(row: dict) -> tuple:
    """A row's (object, target kind, offset)."""
    return (row["object"], row["target"]["kind"], row["target"]["offset_mm"])


def x_rows() -> dict:
    """X's rows by pair (a later row of a pair replaces the earlier)."""
    return {pair(row): row for row in map(json.loads, X_ROWS.open())}


def setup(row: dict):
    """(scenario, obj, ik, plan, later) of `row`'s rehearsal: the target's
    scenario (its rehearsal's digest checked), the predicted flight's plan
    and the plans at its later catch moments (rehearsal.later_moments)."""
    torch.set_num_threads(1)
    t = row["target"]
    scenario = with_target(load_scenario(), Target(t["kind"], t["offset_mm"]))
    assert (scenario_digest(rh.rehearsal_scenario(scenario))
            == row["rehearsal_digest"])
    obj = resolve_object(name=row["object"])
    ik = ArmIk(scenario.directives)
    predictor = FlightPredictor.load(MODELS_DIR / "flight_predictor.json")
    plan = predictor.plan(obj, scenario, ik)
    later = rh.later_moments(scenario, obj, ik,
                             predictor.as_watched(obj, scenario))
    return scenario, obj, ik, plan, later


def run(probe, rows, out, workers: int) -> None:
    """`probe` on each of `rows` not yet in `out` (JSON lines, appended as
    each finishes), `workers` processes at once."""
    done = ({pair(json.loads(line)) for line in out.open()}
            if out.exists() else set())
    todo = [r for r in rows if pair(r) not in done]
    print(f"{len(todo)} pairs", flush=True)
    with (out.open("a") as f,
          multiprocessing.get_context("fork").Pool(workers) as pool):
        for probed in pool.imap_unordered(probe, todo):
            f.write(json.dumps(probed) + "\n")
            f.flush()
            print(*pair(probed), flush=True)
