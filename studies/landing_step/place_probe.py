"""Probe of a margin in the palm's place (FINDINGS §18): each of X's picks
(X_eighth.jsonl, every pair with a pick) caught again with the palm moved
±SHIFT_MM along the object's axis from the pick's place, at the rehearsal's
own steps and without noise (`rehearsal.catches` in the pick's mode), so
that the picks whose landing holds at the neighbouring places can be set
against how they fared under release noise (X_noise_eighth.jsonl).
Resumable; rows to models/results/landing_step/place_probe.jsonl.

    .venv/bin/python studies/landing_step/place_probe.py [--workers 2]
        [--candidates]

--candidates: every margin candidate of every pair (not only the pick) at
its place ± SHIFT_MM, in groups that share a throw (mode, place, moment):
rows to models/results/landing_step/place_candidates.jsonl, from which a
margin with the two places as two more draws ("place -2", "place +2")
re-makes the pick (`--picks`: X's rows with the changed picks to
out/P_rehearsals.jsonl, and the changed pairs to out/P_changed.txt).
"""
import regrasp_drake  # noqa: F401, I001 (first: it pins NumPy's kernels)
import argparse
import json

from regrasp_drake.learning import rehearsal as rh
from regrasp_drake.paths import OUT_DIR
from regrasp_drake.throw_catch import shifted_along_axis
from x_rows import RESULTS, pair, run, setup, x_rows

OUT = RESULTS / "place_probe.jsonl"
CANDIDATES = RESULTS / "place_candidates.jsonl"
SHIFT_MM = 2.0


def probe(row: dict) -> dict:
    """`row`'s pick caught at its place ± SHIFT_MM."""
    pick = row["rehearsal"]
    scenario, obj, ik, plan, later = setup(row)
    moment = pick.get("catch_point", 1)
    if moment > 1:
        plan = next(p for p in later if p.moment == moment)
    rehearsed = rh.rehearsal_scenario(rh.mode_scenario(scenario, pick["mode"])
                                      if pick["mode"] in rh.MODES
                                      else scenario)
    places = {}
    for mm in (-SHIFT_MM, SHIFT_MM):
        moved = shifted_along_axis(plan, 1e-3 * (pick["palm_shift_mm"] + mm),
                                   ik)
        if moved is None:
            places[f"{mm:+g}"] = None
            continue
        r = rh.catches(rehearsed, obj, ik, moved, [tuple(pick["cell"])])[0]
        places[f"{mm:+g}"] = {"success": bool(r.success),
                              "grasp": r.achieved_grasp}
    return {"object": row["object"], "target": row["target"],
            "pick": {k: pick.get(k, 1) for k in (
                "cell", "mode", "palm_shift_mm", "catch_point")},
            "judged": row["success"], "places": places}


def probe_candidates(row: dict) -> dict:
    """Every margin candidate of `row` caught at its place ± SHIFT_MM."""
    rehearsal = row["rehearsal"]
    scenario, obj, ik, plan, later = setup(row)
    groups = {}
    for k, c in enumerate(rehearsal["margin"]):
        groups.setdefault((c["mode"], c["palm_shift_mm"],
                           c.get("catch_point", 1)), []).append(k)
    places = [{} for _ in rehearsal["margin"]]
    for (mode, mm, moment), members in groups.items():
        base = (plan if moment == 1
                else next(p for p in later if p.moment == moment))
        rehearsed = rh.rehearsal_scenario(rh.mode_scenario(scenario, mode))
        for shift in (-SHIFT_MM, SHIFT_MM):
            moved = shifted_along_axis(base, 1e-3 * (mm + shift), ik)
            draw = f"place {shift:+g}"
            if moved is None:
                continue
            results = rh.catches(rehearsed, obj, ik, moved, [
                tuple(rehearsal["margin"][k]["cell"]) for k in members])
            for k, r in zip(members, results):
                places[k][draw] = bool(r.success)
    return {"object": row["object"], "target": row["target"],
            "candidates": [c | {"places": p} for c, p in
                           zip(rehearsal["margin"], places)]}


def picks(rows: dict) -> None:
    """The pick re-made with the two places as two more draws, the key
    otherwise X's (landed at half the steps, the count of draws, the order);
    X's rows with the changed picks to out/P_rehearsals.jsonl."""
    def ident(c):
        return (c["mode"], c["palm_shift_mm"], c["cell"],
                c.get("catch_point", 1))

    changed = []
    for line in CANDIDATES.open():
        probed = json.loads(line)
        row = rows[pair(probed)]
        rehearsal = row["rehearsal"]
        cands = probed["candidates"]
        landed = [c["landed_in"] + [d for d, ok in c["places"].items() if ok]
                  for c in cands]
        new = max(range(len(cands)), key=lambda k: (
            "half" in landed[k], len(landed[k]), -k))
        old = next(k for k, c in enumerate(cands) if ident(c) == (
            rehearsal["mode"], rehearsal["palm_shift_mm"], rehearsal["cell"],
            rehearsal.get("catch_point", 1)))
        print(*pair(probed), "X:", cands[old]["cell"], cands[old]["mode"],
              landed[old], "P:", cands[new]["cell"], cands[new]["mode"],
              cands[new]["palm_shift_mm"], landed[new])
        if new != old:
            c = cands[new]
            assert c.get("catch_point", 1) == rehearsal.get("catch_point", 1)
            rehearsal.update(cell=c["cell"], mode=c["mode"],
                             palm_shift_mm=c["palm_shift_mm"])
            changed.append(pair(probed))
    OUT_DIR.mkdir(exist_ok=True)
    with (OUT_DIR / "P_rehearsals.jsonl").open("w") as f:
        for row in rows.values():
            f.write(json.dumps(row) + "\n")
    (OUT_DIR / "P_changed.txt").write_text("".join(
        f"{name} {kind}:{mm:+g}\n" for name, kind, mm in changed))
    print(f"{len(changed)} picks changed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--candidates", action="store_true")
    parser.add_argument("--picks", action="store_true")
    args = parser.parse_args()
    rows = x_rows()
    if args.picks:
        return picks(rows)
    run(probe_candidates if args.candidates else probe,
        [r for r in rows.values()
         if r.get("rehearsal") and r["rehearsal"]["cell"] is not None],
        CANDIDATES if args.candidates else OUT, args.workers)


if __name__ == "__main__":
    main()
