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
import statistics

from regrasp_drake.learning import rehearsal as rh
from regrasp_drake.paths import OUT_DIR
from regrasp_drake.throw_catch import shifted_along_axis
from x_rows import RESULTS, pair, run, setup, x_rows

OUT = RESULTS / "T_tilt_probe.jsonl"


def key(candidate: dict) -> tuple:
    """What X's pick ranks a margin candidate by, before its order."""
    return ("half" in candidate["landed_in"], len(candidate["landed_in"]))


def probe(row: dict) -> dict:
    """The tied candidates of `row`'s rehearsal, each with its catches in
    MARGIN_DRAWS."""
    scenario, obj, ik, plan, later = setup(row)
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
    return {"object": row["object"], "target": row["target"],
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
    rows = x_rows()
    if args.picks:
        return picks(rows)
    run(probe, [r for r in rows.values() if r.get("rehearsal")
                and r["rehearsal"]["cell"] is not None
                and sum(key(c) == max(map(key, r["rehearsal"]["margin"]))
                        for c in r["rehearsal"]["margin"]) >= 2],
        OUT, args.workers)


if __name__ == "__main__":
    main()
