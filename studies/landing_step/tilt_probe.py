"""Probe of a tilt tie-break in the rehearsal's pick (FINDINGS §18): for each
pair of X's picks whose margin has two candidates or more tied on the pick's
key (landed at half the steps, then the count of MARGIN_DRAWS landed in),
every tied candidate is rehearsed again in each of MARGIN_DRAWS at the
rehearsal's own steps (`rehearsal._draw_scenario`, `rehearsal.catches`), its
resting grasp recorded per draw. Resumable; rows to
models/results/landing_step/T_tilt_probe.jsonl.

    .venv/bin/python studies/landing_step/tilt_probe.py [--workers 2]
    .venv/bin/python studies/landing_step/tilt_probe.py --picks

--picks: T's pick for each probed pair (among the tied candidates, the least
mean tilt over the draws landed in, to 0.1°; a tie, X's order), X's rows
with the changed picks written to out/T_rehearsals.jsonl, to be judged by
benchmarks/regrasp_targets.py --rehearse --rehearsal-from that file at the
finer step, one pair at a time.
"""
import regrasp_drake  # noqa: F401, I001 (first: it pins NumPy's kernels)
import argparse
import json
import multiprocessing
import statistics

import torch

from regrasp_drake.learning import rehearsal as rh
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.paths import MODELS_DIR, OUT_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import (
    load_scenario,
    scenario_digest,
    with_target,
)
from regrasp_drake.throw_catch import shifted_along_axis
from regrasp_drake.world.objects import resolve_object

RESULTS = MODELS_DIR / "results" / "landing_step"
X_ROWS = RESULTS / "X_eighth.jsonl"
OUT = RESULTS / "T_tilt_probe.jsonl"


def key(candidate: dict) -> tuple:
    """What X's pick ranks a margin candidate by, before its order."""
    return ("half" in candidate["landed_in"], len(candidate["landed_in"]))


def pair(row: dict) -> tuple:
    return (row["object"], row["target"]["kind"], row["target"]["offset_mm"])


def probe(row: dict) -> dict:
    """The tied candidates of `row`'s rehearsal, each with its catches in
    MARGIN_DRAWS."""
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
    margin = row["rehearsal"]["margin"]
    best = max(key(c) for c in margin)
    groups = {}
    for c in margin:
        if key(c) == best:
            groups.setdefault((c["mode"], c["palm_shift_mm"],
                               c.get("catch_point", 1)), []).append(c)
    tied = []
    for (mode, mm, moment), members in groups.items():
        base = (plan if moment == 1
                else next(p for p in later if p.moment == moment))
        moved = shifted_along_axis(base, 1e-3 * mm, ik) if mm else base
        judged = [dict(c, draws={}) for c in members]
        for draw in rh.MARGIN_DRAWS:
            results = rh.catches(rh._draw_scenario(scenario, mode, draw), obj,
                                 ik, moved, [tuple(c["cell"]) for c in members])
            for c, r in zip(judged, results):
                c["draws"][draw] = {"success": bool(r.success),
                                    "grasp": r.achieved_grasp}
        tied += judged
    return {"object": row["object"], "target": t,
            "pick": {k: row["rehearsal"].get(k, 1) for k in (
                "cell", "mode", "palm_shift_mm", "catch_point")},
            "judged": {"success": row["success"],
                       "grasp": row["achieved_grasp"]},
            "tied": tied}


def mean_tilt(candidate: dict) -> float:
    """A probed candidate's mean resting tilt over the draws it landed in,
    [°] to 0.1 (inf: none)."""
    tilts = [d["grasp"]["tilt_deg"] for d in candidate["draws"].values()
             if d["success"]]
    return round(statistics.mean(tilts), 1) if tilts else float("inf")


def picks(rows: dict) -> None:
    """T's picks (module docstring) into out/T_rehearsals.jsonl."""
    def ident(c):
        return (c["mode"], c["palm_shift_mm"], c["cell"],
                c.get("catch_point", 1))

    changed = 0
    for line in OUT.open():
        probed = json.loads(line)
        tied, p = probed["tied"], probed["pick"]
        x = next(k for k, c in enumerate(tied) if ident(c) == (
            p["mode"], p["palm_shift_mm"], p["cell"], p["catch_point"]))
        t = min(range(len(tied)), key=lambda k: (mean_tilt(tied[k]), k))
        if mean_tilt(tied[t]) < mean_tilt(tied[x]):
            c = tied[t]
            rows[pair(probed)]["rehearsal"].update(
                cell=c["cell"], mode=c["mode"],
                palm_shift_mm=c["palm_shift_mm"])
            changed += 1
            print(*pair(probed), p["cell"], p["mode"], mean_tilt(tied[x]),
                  "->", c["cell"], c["mode"], c["palm_shift_mm"],
                  mean_tilt(c))
    OUT_DIR.mkdir(exist_ok=True)
    with (OUT_DIR / "T_rehearsals.jsonl").open("w") as f:
        for row in rows.values():
            f.write(json.dumps(row) + "\n")
    print(f"{changed} picks changed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--picks", action="store_true")
    args = parser.parse_args()
    rows = {}
    for line in X_ROWS.open():
        row = json.loads(line)
        rows[pair(row)] = row  # a later row of a pair replaces the earlier
    if args.picks:
        return picks(rows)
    done = ({pair(json.loads(line)) for line in OUT.open()}
            if OUT.exists() else set())
    todo = [r for k, r in rows.items()
            if k not in done and r.get("rehearsal")
            and r["rehearsal"]["cell"] is not None
            and sum(key(c) == max(map(key, r["rehearsal"]["margin"]))
                    for c in r["rehearsal"]["margin"]) >= 2]
    print(f"{len(todo)} pairs", flush=True)
    with (OUT.open("a") as f,
          multiprocessing.get_context("fork").Pool(args.workers) as pool):
        for out in pool.imap_unordered(probe, todo):
            f.write(json.dumps(out) + "\n")
            f.flush()
            print(out["object"], out["target"], flush=True)


if __name__ == "__main__":
    main()
