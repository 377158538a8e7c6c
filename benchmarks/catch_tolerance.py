"""How far off may the palm wait and still catch? Palm offsets at one catch
cell, fast: the throw is simulated once per (object, scenario), then each
offset's catch from a copy of the state at the throw's end (the grasp pose
set there, as run_episode's at_release does).

    .venv/bin/python benchmarks/catch_tolerance.py OBJECT H_CATCH H_DOWN
        [--scenario F] [--scenario-name NAME] [--text YAML]
        [--offsets "dx,dy;dx,dy" | all] [--tag NAME]
        [--out out/catch_tolerance]

e.g. `table1-row2 0.20 -0.13` (studies/palm_toss/FINDINGS.md, "The catch").
The scenario: by default the shipped one. --text: YAML fields over the
scenario's for the catches only (the watched plan stays the scenario's).
The offsets, in mm in the palm's frame (x across the object's axis, y along
it, z along the palm's normal, default 0): "all" is the 25 of a ±20 mm grid
in the palm's plane, 10 mm apart.

Prints one JSON line per offset (the scenario's digest, the cell, the
offset, the monitor's outcome, the drop reason and the contact verdict) and
a summary line; the lines also go to
<out>/<OBJECT>_<H_CATCH>_<H_DOWN>[_<tag>].jsonl. The watched plan is cached
in <out>/, per object and scenario.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

from regrasp_drake import atomic_io, progress, scenario_args

GRID_MM = range(-20, 21, 10)


def parse_offsets(text: str) -> list[tuple[int, ...]]:
    """"all" (the ±20 mm grid in the palm's plane) or "dx,dy;dx,dy" in
    whole mm, each with an optional third entry dz along the palm's normal
    ("dx,dy,dz")."""
    from regrasp_drake.errors import InputError
    if text == "all":
        return [(dx, dy) for dx in GRID_MM for dy in GRID_MM]
    try:
        offsets = [tuple(int(v) for v in s.split(",")) for s in text.split(";")]
    except ValueError:
        offsets = []
    if not offsets or any(len(o) not in (2, 3) for o in offsets):
        raise InputError(f"--offsets: got {text!r}, expected \"all\" or "
                         "\"dx,dy;dx,dy\" (or \"dx,dy,dz;...\") in whole mm")
    return offsets


def watched_plan(scenario, obj, ik, out: Path):
    """The palm's grasp pose X_WG planned from the watched throw, cached in
    `out` by object and scenario."""
    from pydrake.math import RigidTransform

    from regrasp_drake.station.scenario import scenario_yaml
    from regrasp_drake.throw_catch import plan_catch, watch
    digest = hashlib.sha256(scenario_yaml(scenario).encode()).hexdigest()[:12]
    cache = out / f"plan_{obj.name}_{digest}.json"
    if cache.is_file():
        return RigidTransform(json.loads(cache.read_text())["X_WG"])
    X_WG = plan_catch(scenario, obj, ik, watch(scenario, obj, ik)).X_WG
    atomic_io.write_json(cache, {"X_WG": X_WG.GetAsMatrix4().tolist()},
                         indent=None)
    return X_WG


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("object")
    parser.add_argument("h_catch", type=float)
    parser.add_argument("h_down", type=float)
    scenario_args.add(parser, text=False, target=False)
    parser.add_argument("--text", default=None,
                        help="YAML fields over the scenario's, for the "
                             "catches only")
    parser.add_argument("--offsets", default="all")
    parser.add_argument("--tag", default="")
    parser.add_argument("--out", type=Path, default=Path("out/catch_tolerance"))
    return _run(parser.parse_args(argv))


def _run(args) -> int:
    from regrasp_drake.errors import InputError
    from regrasp_drake.world.objects import resolve_object
    try:
        base, _ = scenario_args.load(args)
        scenario, _ = scenario_args.load(args, over=args.text)
        obj = resolve_object(name=args.object)
        offsets = parse_offsets(args.offsets)
    except InputError as e:
        print(f"catch_tolerance: error: {e}", file=sys.stderr)
        return 2
    from pydrake.math import RigidTransform
    from pydrake.systems.analysis import InitializeParams

    from regrasp_drake.episode.episode import (
        Episode,
        ThrowCache,
        advance_to_outcome,
    )
    from regrasp_drake.episode.result import read_ending, read_outcome
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import scenario_digest
    args.out.mkdir(parents=True, exist_ok=True)
    ik = ArmIk()
    X_WG = watched_plan(base, obj, ik, args.out)
    t0 = time.time()
    # To the release time, at the catch's step from there (a throw of its
    # own: no kept one).
    episode = Episode(scenario, obj, ik=ik, X_WG=X_WG,
                      catch_parameters=(args.h_catch, args.h_down),
                      throws=ThrowCache(size=0))
    episode.start()
    episode.advance_to_release()
    sim, station, scenario = (episode.simulator, episode.diagram,
                              episode.scenario)
    saved = sim.get_context().Clone()
    rows = []
    name = f"{args.object}_{args.h_catch:g}_{args.h_down:g}"
    lines = args.out / (f"{name}_{args.tag}.jsonl" if args.tag
                        else f"{name}.jsonl")
    with atomic_io.replace(lines, "w") as f:
        for offset in progress.iterate(offsets, len(offsets), name,
                                       "offsets"):
            dx, dy, dz = (*offset, 0)[:3]
            context = saved.Clone()
            station.controller.set_task(
                context, X_WG=X_WG @ RigidTransform([dx / 1e3, dy / 1e3,
                                                     dz / 1e3]))
            sim.reset_context(context)
            sim.Initialize(InitializeParams(
                suppress_initialization_events=True))
            message = advance_to_outcome(sim, station, scenario)
            end_context = sim.get_context()
            outcome, _ = read_outcome(station, end_context, message)
            ending = read_ending(station, end_context, outcome)
            row = dict(object=args.object, tag=args.tag,
                       scenario=scenario_digest(base),
                       h_catch=args.h_catch, h_down=args.h_down,
                       dx_mm=dx, dy_mm=dy, dz_mm=dz,
                       outcome=outcome, held=ending["held_by_contact"],
                       reason=ending["drop_reason"],
                       touching=ending["touching"], msg=message)
            rows.append(row)
            progress.say(json.dumps(row), sys.stdout)
            f.write(json.dumps(row) + "\n")
    caught = sum(r["outcome"] == "caught" for r in rows)
    held = sum(bool(r["held"]) for r in rows)
    print(f"SUMMARY {args.tag} {args.object} ({args.h_catch},{args.h_down}) "
          f"caught {caught}/{len(rows)} held_by_contact {held} "
          f"wall {time.time() - t0:.0f}s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
