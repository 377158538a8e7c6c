"""The static test over the regrasp pairs: which targets the closed hand
holds at rest, at the catch's step and a 4× finer one, and the first throw
against them.

    .venv/bin/python benchmarks/static_hold.py [--objects NAME ...]
        [--targets keep:-30 ...] [--steps 0.001 0.00025] [--workers N]
        [--out models/results/landing_step/static_hold_closings]
        [--first-throw ROWS.jsonl ...] [--closings NAME ...]

For every reachable (object, target) pair (default: Table 1's five and the
held-out objects under keep/flip at -30, 0, +30 mm) and plant step, the
static test of episode/static_hold.py (the object laid at rest in the target
grasp on the open hand, the fingers closed at the catch's speed, held 1 s;
each of its closings in turn until one holds; --closings: the named ones
of static_hold.CLOSINGS instead, each alone when given one): held in the target grasp,
by which closing, or why not. Rows go to <out>.jsonl as they finish
(a rerun resumes); the counts, the pairs each step refuses and the two
steps' agreement to <out>.json, and printed. With --first-throw (rows of
benchmarks/regrasp_targets.py --modes first-throw), each file's pairs in the
target grasp: of all reachable pairs, and of those the hand holds at rest
(at the first step), and the pairs the catch lands in the target grasp
that the static test says no closing holds (a refusal they would
contradict).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

from regrasp_drake import atomic_io
from regrasp_drake.episode.static_hold import (
    CLOSINGS,
    closing_named,
    static_hold,
)
from regrasp_drake.errors import InputError
from regrasp_drake.grid import append_rows
from regrasp_drake.learning.table1 import object_names
from regrasp_drake.map_rows import read_rows
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target, check_reachable
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.world.objects import load_catalogue, resolve_object

DEFAULT_TARGETS = [f"{kind}:{offset}" for kind in ("keep", "flip")
                   for offset in (-30, 0, 30)]


def _key(row) -> tuple:
    return (row["object"], row["target"]["kind"], row["target"]["offset_mm"],
            row["step_s"])


def _job(task) -> dict:
    name, target, step, closings = task
    scenario = with_target(load_scenario(), target)
    test = static_hold(scenario, resolve_object(name=name), step_s=step,
                       closings=closings)
    return {"object": name, "target": target.as_dict(), "step_s": step,
            "success": test.success, "held": test.held,
            "reason": test.reason, "rest": test.rest, "closed": test.closed,
            "grasp_error": test.grasp_error, "closing": test.closing,
            "closings": [c.name for c in closings],
            "tried": test.tried, "line": test.line()}


def _pair(key) -> tuple:
    return key[:3]


def summarize(rows: dict, steps, first_throw: dict) -> dict:
    """The counts per step, the refused pairs, the steps' agreement, and
    each first-throw file's share in the target grasp."""
    pairs = sorted({_pair(k) for k in rows})
    by_step = {s: {_pair(k): r for k, r in rows.items() if k[3] == s}
               for s in steps}
    out = {"pairs": len(pairs), "steps": {}}
    for s in steps:
        mine = by_step[s]
        out["steps"][str(s)] = {
            "held": sum(r["success"] for r in mine.values()),
            "refused": [r["line"] for p, r in sorted(mine.items())
                        if not r["success"]]}
    if len(steps) > 1:
        a, b = by_step[steps[0]], by_step[steps[1]]
        common = [p for p in pairs if p in a and p in b]
        out["same_verdict"] = sum(a[p]["success"] == b[p]["success"]
                                  for p in common)
        out["compared"] = len(common)
    holdable = {p for p, r in by_step[steps[0]].items() if r["success"]}
    out["first_throw"] = {}
    for path, done in first_throw.items():
        reach = {(r["object"], r["target"]["kind"], r["target"]["offset_mm"]):
                 r for r in done.values() if r["stopped"] != "refused"}
        held = [p for p in reach if p in holdable]
        out["first_throw"][path] = {
            "reachable": len(reach),
            "in_target": sum(r["success"] for r in reach.values()),
            "holdable": len(held),
            "in_target_of_holdable": sum(reach[p]["success"] for p in held),
            "in_target_not_holdable": sorted(
                ":".join(map(str, p)) for p, r in reach.items()
                if r["success"] and p not in holdable)}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+")
    parser.add_argument("--targets", nargs="+", default=DEFAULT_TARGETS)
    parser.add_argument("--steps", nargs="+", type=float,
                        default=[0.001, 0.00025])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path,
                        default=MODELS_DIR / "results" / "landing_step"
                        / "static_hold_closings")
    parser.add_argument("--first-throw", nargs="*", type=Path, default=[])
    parser.add_argument("--closings", nargs="+", metavar="NAME",
                        help="only these closings, in turn (default: "
                        "static_hold.CLOSINGS)")
    args = parser.parse_args(argv)
    try:
        if args.workers < 1:
            raise InputError(f"--workers: got {args.workers}, expected an "
                             "integer >= 1")
        targets = [Target.parse(t) for t in args.targets]
        closings = (tuple(closing_named(n, "--closings")
                          for n in args.closings)
                    if args.closings else CLOSINGS)
        names = args.objects or object_names() + [
            o.name for o in load_catalogue().values() if o.set == "holdout"]
        first_throw = {str(p): read_rows(p, key=lambda r: (
            r["object"], r["target"]["kind"], r["target"]["offset_mm"],
            r["mode"])) for p in args.first_throw}
        jobs, pairs = [], []
        for name in names:
            obj = resolve_object(name=name)
            for target in targets:
                try:
                    check_reachable(target, obj)
                except InputError:
                    continue
                pairs.append((name, target))
        rows_path = args.out.with_suffix(".jsonl")
        done = read_rows(rows_path, key=_key)
        names_tried = [c.name for c in closings]
        for row in done.values():
            # Rows written before the field existed carry no closings.
            if row.get("closings", names_tried) != names_tried:
                raise InputError(
                    f"--closings: {rows_path} holds rows of the closings "
                    f"{row['closings']}, got {names_tried}; expected the "
                    "same closings to resume it, or another --out")
        jobs = [(name, target, step, closings) for step in args.steps
                for name, target in pairs
                if (name, target.kind, target.offset_mm, step) not in done]
    except InputError as e:
        print(f"static_hold: error: {e}", file=sys.stderr)
        return 2
    append_rows(_job, jobs, rows_path, done, _key, workers=args.workers,
                label="static holds", unit="tests")
    for step in args.steps:
        for key in sorted(k for k in done if k[3] == step):
            print(f"{step * 1e3:g} ms  {done[key]['line']}")
    summary = summarize(done, args.steps, first_throw)
    atomic_io.write_json(args.out.with_suffix(".json"), summary)
    print(json.dumps({k: v for k, v in summary.items()
                      if k != "steps"} | {
        "held": {s: v["held"] for s, v in summary["steps"].items()}},
        indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
