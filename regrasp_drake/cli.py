"""The command line: `regrasp-drake <command> …`.

Every error from bad input is one line on stderr and exit status 2, found
before any simulation (docs/input-checks.md lists what is checked), the
outputs' included: no existing file that is not the command's own is
overwritten. Outputs given no path go to --out-dir (default paths.OUT_DIR:
out/ at the top of the repository, ./out when installed). Ctrl-C ends a
command with one line and exit status 130; what it has written so far (a
map's rows, a data set's entries) is kept and resumed by the next run.

Over 500 lines because it holds the thirteen commands, each a short function
of its own, and their parser; what they write and the checks of it are in
outputs.py, the scenario's options in scenario_args.py.
"""

import argparse
import json
import os
import signal
import sys
import time
from pathlib import Path

from regrasp_drake import atomic_io, outputs, scenario_args
from regrasp_drake.errors import (
    InputError,
    note_interrupt,
)
from regrasp_drake.outputs import InOutDir


def _add_object_args(p: argparse.ArgumentParser) -> None:
    """--object, --object-file or both (the object is then the named one of
    the file); main() refuses neither."""
    p.add_argument("--object", metavar="NAME",
                   help="a catalogue object (see `regrasp-drake objects`); "
                        "with --object-file, the object of that name in F")
    p.add_argument("--object-file", metavar="F", type=Path,
                   help="a YAML object file in the catalogue's format (its "
                        "first object unless --object names another)")


def _add_out_dir_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out-dir", metavar="DIR", type=Path,
                   help="where the outputs given no path go (default: out/ "
                        "at the top of the repository, which git ignores; "
                        "./out when installed)")


def _add_library_arg(p: argparse.ArgumentParser) -> None:
    from regrasp_drake.learning.library import DEFAULT_LIBRARY
    p.add_argument("--library", metavar="F", type=Path,
                   default=InOutDir(DEFAULT_LIBRARY),
                   help=f"the regrasp library YAML (default: {DEFAULT_LIBRARY} "
                        "in --out-dir)")
    _add_out_dir_arg(p)


def _cmd_objects(args) -> int:
    from regrasp_drake.world.objects import load_catalogue, load_object_file
    specs = (load_object_file(args.object_file) if args.object_file
             else list(load_catalogue().values()))
    rows = [{"name": s.name, "set": s.set, "mass_kg": round(s.mass, 5),
             "density": s.density, "h_cm": s.h_cm, "r_cm": s.r_cm,
             "v_conv": s.v_conv} for s in specs]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    print(f"{'name':<24} {'set':<6} {'mass kg':>8} {'density':>8} "
          f"{'h_cm m':>8} {'r_cm m':>8} {'v_conv':>6}")
    for r in rows:
        print(f"{r['name']:<24} {r['set']:<6} {r['mass_kg']:>8.4f} "
              f"{r['density']:>8.0f} {r['h_cm']:>8.3f} {r['r_cm']:>8.3f} "
              f"{r['v_conv']:>6d}")
    counts = {}
    for r in rows:
        counts[r["set"]] = counts.get(r["set"], 0) + 1
    print(", ".join(f"{n} {k}" for k, n in counts.items()))
    return 0


def _cmd_catch(args) -> int:
    from regrasp_drake.station.scenario_checks import check_catch_parameters
    check_catch_parameters(args.h_catch, args.h_down,
                           names=("--h-catch", "--h-down"))
    scenario, obj, _, _ = _scenario_and_object(args)
    from regrasp_drake import api
    run = api.catch(obj, args.h_catch, args.h_down, scenario=scenario,
                    replay=args.html is not None)
    if args.html is not None:
        run.save_replay(args.html)
    if args.plot is not None:
        run.plot(args.plot)
    summary = run.summary()
    print(json.dumps(summary, indent=1))
    print(run.regrasp_line())
    _write_json(args.json, summary)
    return 0


def _cmd_grid(args) -> int:
    _check_workers(args.workers)
    entry = outputs.grid_entry(args)
    from regrasp_drake.grid import format_map, success_map  # torch: after
    rows = success_map(object_name=args.object, object_file=args.object_file,
                       scenario=args.scenario, out=args.out,
                       workers=args.workers, catch_point=args.catch_point)
    print(f"{entry}: outcome of every cell (results in {args.out})")
    print(format_map(rows))
    if args.plot:
        from regrasp_drake.plots import plot_success_map
        plot_success_map(rows, args.plot, title=f"{entry}: success map")
        print(f"map: {args.plot}")
    return 0


def _scenario_and_object(args):
    """The scenario and object of a command, and their provenance labels."""
    from regrasp_drake.planning.grasp import check_reachable
    from regrasp_drake.station.scenario import target_of
    from regrasp_drake.world.objects import resolve_object
    scenario = args.scenario
    obj = resolve_object(name=args.object, file=args.object_file)
    check_reachable(target_of(scenario), obj, field=(
        "--offset-mm" if getattr(args, "offset_mm", None) is not None
        else "the scenario's regrasp.offset_mm"))
    if scenario.regrasp.target != "any":  # the static test simulates
        from regrasp_drake.episode.static_hold import check_holdable
        check_holdable(scenario, obj)
    source = (str(args.object_file.resolve()) if args.object_file
              else "catalogue")
    return scenario, obj, source, args.scenario_label


def _write_json(path, data) -> None:
    if path:
        atomic_io.write_json(path, data)


def _cmd_throw(args) -> int:
    scenario, obj, _, _ = _scenario_and_object(args)  # before heavy imports
    from regrasp_drake.learning.observation import observe
    from regrasp_drake.planning.ik import ArmIk
    observation = observe(scenario, obj, ArmIk(scenario.directives))
    if args.plot:
        from regrasp_drake.learning.plots import plot_flight
        plot_flight(observation, scenario, args.plot)
    summary = observation.as_dict()
    print(json.dumps(summary, indent=1))
    _write_json(args.json, summary)
    return 0


def _cmd_diagram(args) -> int:
    if args.max_depth < 1:
        raise InputError(f"--max-depth: got {args.max_depth}, expected an "
                         "integer >= 1")
    scenario, obj, _, _ = _scenario_and_object(args)
    from regrasp_drake.throw_catch import episode_graphviz
    atomic_io.write_text(args.out, episode_graphviz(
        scenario, obj, max_depth=args.max_depth))
    print(f"diagram: {args.out} (a picture: dot -Tpng {args.out} -o "
          f"{args.out.with_suffix('.png')})")
    return 0


def _load_network(args, scenario):
    """The MLP of --weights (default: the scenario's catch.weights in
    models/), refused with one line naming the file."""
    from regrasp_drake.api import load_network
    return load_network(args.weights, scenario, field="--weights")


def _flight_predictor(args):
    """The flight predictor for --first-throw (default models/
    flight_predictor.json), or None."""
    if not getattr(args, "first_throw", False):
        return None
    from regrasp_drake.api import load_flight_predictor
    return load_flight_predictor(args.flight_model, field="--flight-model")


def _add_first_throw_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--first-throw", action="store_true",
                   help="no watching throw: plan the catch from the flight "
                        "predictor and catch on throw 1")
    p.add_argument("--flight-model", type=Path, metavar="F",
                   help="the flight predictor (default "
                        "models/flight_predictor.json)")
    p.add_argument("--rehearse", action="store_true",
                   help="rehearse the first catch in simulation at a "
                        "lattice of 25 cells in three catch modes (the palm "
                        "waiting, turning with the pitch, moving with the "
                        "object along the palm) before the "
                        "throw, with the palm moved 4-8 mm along the axis "
                        "where no mode lands, and start from the cell that "
                        "lands in the draws of its margin (half the step "
                        "first, then release noise) among the most robust, "
                        "the palm's other places searched too where no "
                        "candidate lands at half the step and in 2 draws, "
                        "then the flight's second catch moment; a target "
                        "that no cell lands and no closing holds at rest "
                        "is refused before the throw (exit 2) "
                        "(learning/rehearsal.py; not with --at-release)")
    p.add_argument("--at-release", action="store_true",
                   help="no watching throw: each throw plans its catch when "
                        "it releases the object, from the object's state "
                        "seen then (not with --first-throw)")


def _add_offset_prior_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--offset-prior", type=Path, metavar="F",
                   help="with a --target other than any: the palm waits "
                        "against the slide this offset prior predicts (e.g. "
                        "models/offset_prior.json; default none: its shifted "
                        "palms land where the grasp is not converged in the "
                        "step, docs/regrasp.md)")


def _offset_prior(args, scenario):
    """The offset prior of --offset-prior for a scenario aiming for a
    target; None without one, or for `any`."""
    from regrasp_drake.api import load_offset_prior
    return load_offset_prior(args.offset_prior, scenario,
                             field="--offset-prior")


def _add_search_arg(p: argparse.ArgumentParser) -> None:
    """--search and --planner: the order of the cells, and who picks the
    first."""
    from regrasp_drake.learning.search import SEARCHES
    p.add_argument("--planner", choices=("shipped", "paper"),
                   default="shipped",
                   help="who picks the search's first cell: shipped (the "
                        "target's planner, models/planner_<target>.json's "
                        "winner on unseen geometries; the paper's network "
                        "under any; default) or paper (the paper's network)")
    p.add_argument("--search", choices=SEARCHES, default="wavefront",
                   help="the order of the cells tried after the network's: "
                        "wavefront (the paper's rings of neighbours; "
                        "default) or map-prior (the cell most likely to "
                        "catch given the training success maps "
                        "models/dataset/maps.npz and the cells failed so "
                        "far)")


def _check_first_throw_args(args) -> None:
    """The first-throw flags and --max-throws of `learn` and `table1`."""
    if args.first_throw and args.at_release:
        raise InputError("--at-release: got it with --first-throw, expected "
                         "one of the two first-throw modes")
    if args.rehearse and args.at_release:
        raise InputError("--rehearse: got it with --at-release, expected it "
                         "without (it rehearses a catch planned before the "
                         "throw)")
    least = 1 if args.first_throw or args.at_release else 2
    if args.max_throws is not None and args.max_throws < least:
        raise InputError(f"--max-throws: got {args.max_throws}, expected an "
                         f"integer >= {least} (the watch, if any, and one "
                         "catch attempt)")


def _cmd_learn(args) -> int:
    _check_first_throw_args(args)
    scenario, obj, source, label = _scenario_and_object(args)
    from regrasp_drake import api
    run = api.learn(obj, scenario=scenario, library=args.library,
                    scenario_label=label, object_source=source,
                    max_throws=args.max_throws,
                    weights=_load_network(args, scenario),
                    watch=not (args.first_throw or args.at_release),
                    flight_model=_flight_predictor(args),
                    at_release=args.at_release, search=args.search,
                    offset_prior=_offset_prior(args, scenario),
                    planner=args.planner, rehearse=args.rehearse,
                    replay=args.html is not None)
    result = run.learning
    if args.html is not None:
        run.save_replay(args.html)
    if args.plot:
        from regrasp_drake.learning.plots import plot_search
        plot_search(result.search_attempts, result.start_cell, args.plot,
                    title=f"{obj.name}: {result.throws} throws, "
                          f"{'caught' if result.success else 'not caught'}")
    summary = result.as_dict() | {
        "stored_in": str(args.library) if result.learned else None}
    print(json.dumps(summary, indent=1))
    print(run.regrasp_line())
    _write_json(args.json, summary)
    return 0


def _cmd_apply(args) -> int:
    start = time.perf_counter()
    scenario, obj, _, _ = _scenario_and_object(args)
    from regrasp_drake import api
    run = api.apply(obj, library=args.library, scenario=scenario,
                    replay=args.html is not None)
    if args.html is not None:
        run.save_replay(args.html)
    summary = run.summary() | {
        "throws": 1, "cell": run.entry.cell, "library": str(args.library),
        "total_wall_s": round(time.perf_counter() - start, 3)}
    print(json.dumps(summary, indent=1))
    print(run.regrasp_line())
    _write_json(args.json, summary)
    return 0


def _cmd_dataset(args) -> int:
    from regrasp_drake.world.objects import load_catalogue
    if args.all_targets and args.target is not None:
        raise InputError(f"--all-targets: got it with --target {args.target}, "
                         "expected one of them (--all-targets makes keep and "
                         "flip at -30, 0, +30 mm)")
    if args.backend == "process":
        _check_workers(args.workers)
    catalogue = load_catalogue()
    names = args.objects or [n for n, o in catalogue.items()
                             if o.set == "train"]
    for name in names:
        if name not in catalogue:
            raise InputError(f"--objects: got {name!r}, expected a catalogue "
                             "object (see `regrasp-drake objects`)")
    if args.all_targets:
        from regrasp_drake.learning.dataset import generate_targets  # torch
        made = generate_targets(names, args.out, workers=args.workers,
                                backend=args.backend, scenario=args.scenario,
                                catch_points=args.catch_points)
        print(json.dumps({key: _dataset_summary(p) for key, p in made.items()},
                         indent=1))
        return 0
    from regrasp_drake.learning.dataset import generate  # torch: after
    provenance = generate(names, args.out, workers=args.workers,
                          backend=args.backend, scenario=args.scenario,
                          catch_points=args.catch_points)
    print(json.dumps(_dataset_summary(provenance), indent=1))
    return 0


def _cmd_train(args) -> int:
    if args.splits < 1:
        raise InputError(f"--splits: got {args.splits}, expected an integer "
                         ">= 1")
    if args.seed < 0:
        raise InputError(f"--seed: got {args.seed}, expected an integer >= 0")
    if args.offset_mm is not None and args.target is None:
        raise InputError(f"--offset-mm: got {args.offset_mm:g} without "
                         "--target, expected --target keep, flip or turn "
                         "beside it")
    from regrasp_drake.paths import MODELS_DIR
    data = args.data
    if data is None and args.target is not None:
        from regrasp_drake.learning.dataset import target_dir_name
        from regrasp_drake.planning.grasp import Target
        data = MODELS_DIR / target_dir_name(Target(args.target,
                                                   args.offset_mm or 0.0))
    data = data or MODELS_DIR / "dataset"
    import torch
    torch.set_num_threads(1)
    if outputs.trains_planner(args):
        return _train_planner(args, data)
    from regrasp_drake.learning.dataset_files import load_training_data
    load_training_data(data)  # refuse a bad data set before any training
    from regrasp_drake.learning.train import train
    out = args.out
    report_json, curve_png = outputs.train_files(out)
    report = train(data, out, seed=args.seed, curve_png=curve_png,
                   report_json=report_json)
    if args.splits > 1:
        from regrasp_drake.learning.train import repeated_splits
        report["repeated_splits"] = repeated_splits(
            data, range(args.seed, args.seed + args.splits))
        _write_json(report_json, report)
    if args.json is not None:
        _write_json(args.json, report)
    print(json.dumps({k: v for k, v in report.items() if k != "split"},
                     indent=1))
    if not report["held_out"]:
        print("regrasp-drake train: warning: fewer than 3 objects in the data "
              "set: trained, validated and tested on the same samples (no "
              "held-out figures)", file=sys.stderr)
    print(f"weights: {out}; report: {report_json}; curve: {curve_png}",
          file=sys.stderr)
    return 0


def _train_planner(args, data) -> int:
    """train --network planner: the learned planner judged on data's maps
    (by geometry and by object, against the paper's network, the best
    constant cell and the ceiling), then trained on all of them."""
    from regrasp_drake.learning.planner import PlannerData, train_planner
    from regrasp_drake.progress import bar as progress_bar
    maps = PlannerData.load(data)  # refuse a bad data set before training
    splits = len(set(maps.geometries)) + len(set(maps.objects))
    with progress_bar(splits, "planner", "splits") as shown:
        report = train_planner(data, args.out, seed=args.seed, maps=maps,
                               progress=shown.update)
    if args.json is not None:
        _write_json(args.json, report)
    print(json.dumps(report, indent=1))
    print(f"planner: {args.out}" + (f"; report: {args.json}" if args.json
                                    else ""), file=sys.stderr)
    return 0


def _cmd_table1(args) -> int:
    _check_first_throw_args(args)  # before torch loads
    import torch

    from regrasp_drake.learning.planner import PAPER_NETWORK
    from regrasp_drake.learning.table1 import (
        format_markdown,
        object_names,
        run_table1,
        write_outputs,
    )
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    scenario = args.scenario
    model = _load_network(args, scenario)
    flight_predictor = _flight_predictor(args)
    for name in object_names(args.objects):  # all of them before any throw
        try:
            resolve_object(name=name)
        except InputError as e:
            raise InputError(f"--objects: {e}") from None
    rows = run_table1(scenario, model, ik=ArmIk(scenario.directives),
                      library_path=args.library,
                      maps_dir=args.maps_dir,
                      flight_predictor=flight_predictor,
                      objects=args.objects, max_throws=args.max_throws,
                      at_release=args.at_release, search=args.search,
                      offset_prior=_offset_prior(args, scenario),
                      planner=PAPER_NETWORK if args.planner == "paper"
                      else None, rehearse=args.rehearse)
    print(format_markdown(rows))
    write_outputs(rows, args.json, args.markdown)
    return 0


def _cmd_train_flight(args) -> int:
    import torch

    from regrasp_drake.learning.flight_predictor import train_from_dataset
    from regrasp_drake.paths import MODELS_DIR
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.world.objects import load_catalogue
    torch.set_num_threads(1)
    scenario = args.scenario
    data = args.data or MODELS_DIR / "dataset"
    held_out = [o for o in load_catalogue().values()
                if o.set in ("test", "holdout")]
    report = train_from_dataset(data, scenario, args.out, ik=ArmIk(scenario.directives),
                                eval_objects=held_out, progress=sys.stderr)
    print(json.dumps(report, indent=1))
    return 0


def _cmd_train_offset(args) -> int:
    from regrasp_drake.learning.offset_prior import OffsetPrior, collect
    from regrasp_drake.planning.grasp import Target
    from regrasp_drake.world.objects import load_catalogue
    _check_workers(args.workers)
    targets = [Target.parse(text) for text in args.targets]
    scenario = args.scenario
    model = _load_network(args, scenario)
    objects = args.objects or [o.name for o in load_catalogue().values()
                               if o.set == "train"]
    rows = collect(scenario, model, targets, objects,
                   args.out.with_suffix(".rows.jsonl"), workers=args.workers,
                   progress=sys.stderr)
    prior = OffsetPrior.fit(rows)
    prior.save(args.out)
    print(json.dumps({k: {"rows": m["rows"], "mean_mm": round(m["mean"], 2),
                          "loo_abs_error_mm": m["loo_abs_error_mm"]}
                      for k, m in prior.models.items()}, indent=1))
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every other refusal
    of the command is (`--help` still shows the usage)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} "
                     "--help)\n")


def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="regrasp-drake",
        description="Regrasp planning through throwing and catching (Drake).")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_episode_commands(sub)
    _add_learning_commands(sub)
    _add_data_commands(sub)
    return parser


def _add_episode_commands(sub) -> None:
    """objects, catch, grid, diagram and throw: one object's episodes."""

    p = sub.add_parser("objects", help="list the object catalogue")
    p.add_argument("--json", action="store_true", help="machine-readable list")
    p.add_argument("--object-file", metavar="F", type=Path,
                   help="list the objects of this file instead")
    p.set_defaults(func=_cmd_objects)

    p = sub.add_parser("catch", help="one throw and one catch attempt")
    _add_object_args(p)
    scenario_args.add(p)
    p.add_argument("--h-catch", type=float, required=True, metavar="X",
                   help="height above the palm at which the fingers start to "
                        "close, m (0 … 0.40)")
    p.add_argument("--h-down", type=float, required=True, metavar="Y",
                   help="how far the hand is lowered, m (-0.14 … 0)")
    p.add_argument("--html", type=Path, metavar="F",
                   help="save the Meshcat replay as one HTML file")
    p.add_argument("--json", type=Path, metavar="F", help="write the result")
    p.add_argument("--plot", type=Path, metavar="F",
                   help="PNG of the sensors and the object's flight")
    p.set_defaults(func=_cmd_catch)

    p = sub.add_parser("grid", help="the outcome of all 150 cells of the "
                                    "parameter space for one object")
    _add_object_args(p)
    scenario_args.add(p)
    p.add_argument("--out", type=Path, metavar="F",
                   default=InOutDir("grid-{entry}.jsonl"),
                   help="JSON lines, written as cells finish; an existing "
                        "map is resumed (default grid-<object>.jsonl, or "
                        "grid-<object>@K.jsonl, in --out-dir)")
    _add_out_dir_arg(p)
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   metavar="N", help="worker processes (default: all cores)")
    p.add_argument("--catch-point", type=int, default=1, metavar="K",
                   help="map the K-th catch point of the watched flight, "
                        "counted as `dataset` counts them (default 1, the "
                        "plan's)")
    p.add_argument("--plot", type=Path, metavar="F",
                   help="PNG of the map, each cell coloured by how it ended, "
                        "the label cell framed")
    p.set_defaults(func=_cmd_grid)

    p = sub.add_parser("diagram", help="the catching episode's Drake Diagram "
                                       "as Graphviz (and a PNG with dot)")
    _add_object_args(p)
    scenario_args.add(p)
    p.add_argument("--out", type=Path, metavar="F",
                   default=InOutDir("diagram.dot"),
                   help="the Graphviz file (default: diagram.dot in "
                        "--out-dir)")
    p.add_argument("--max-depth", type=int, default=2, metavar="N",
                   help="levels of subsystems drawn (default 2: the "
                        "episode's and, inside the station, the station's)")
    _add_out_dir_arg(p)
    p.set_defaults(func=_cmd_diagram)

    p = sub.add_parser("throw", help="the observation throw and its offline "
                                     "stage: catch points and the hand's pose")
    _add_object_args(p)
    scenario_args.add(p)
    p.add_argument("--json", type=Path, metavar="F", help="write the result")
    p.add_argument("--plot", type=Path, metavar="F",
                   help="PNG of the flight, its axis tilt and catch points")
    p.set_defaults(func=_cmd_throw)


def _add_learning_commands(sub) -> None:
    """learn, regrasp and apply: the paper's two phases."""
    for command, help_text in (
            ("learn", "the learning phase: watch, predict, catch, search the "
                      "parameter space (--search)"),
            ("regrasp", "the learning phase aiming for a grasp: --target "
                        "keep/flip/turn/any, --offset-mm; the same options "
                        "as learn")):
        p = sub.add_parser(command, help=help_text)
        _add_object_args(p)
        scenario_args.add(p)
        _add_library_arg(p)
        p.add_argument("--weights", type=Path, metavar="F",
                       help="the MLP's weights file (default: the scenario's "
                            "catch.weights in models/)")
        p.add_argument("--max-throws", type=int, metavar="N",
                       help="stop after N throws, the watch included "
                            "(default: until a catch or all 150 cells are "
                            "tried)")
        p.add_argument("--html", type=Path, metavar="F",
                       help="the Meshcat replay of every throw, one HTML file")
        p.add_argument("--json", type=Path, metavar="F",
                       help="write the result")
        p.add_argument("--plot", type=Path, metavar="F",
                       help="PNG of the search (the paper's Fig. 7)")
        _add_first_throw_args(p)
        _add_search_arg(p)
        _add_offset_prior_arg(p)
        p.set_defaults(func=_cmd_learn, target_required=command == "regrasp")

    p = sub.add_parser("apply", help="the applying phase: one throw, caught "
                                     "with what `learn` stored")
    _add_object_args(p)
    scenario_args.add(p)
    _add_library_arg(p)
    p.add_argument("--html", type=Path, metavar="F",
                   help="the Meshcat replay of the throw, one HTML file")
    p.add_argument("--json", type=Path, metavar="F", help="write the result")
    p.set_defaults(func=_cmd_apply)


def _dataset_summary(provenance: dict) -> dict:
    """A data set's provenance without its scenario's text, to print."""
    return {k: v for k, v in provenance.items() if k != "scenario"}


def _add_data_commands(sub) -> None:
    """dataset, train, table1, train-flight and train-offset: data sets,
    networks and the paper's table."""
    p = sub.add_parser("dataset", help="success maps and labels of the "
                                       "training objects (resumable)")
    scenario_args.add(p)
    p.add_argument("--objects", nargs="+", metavar="NAME",
                   help="catalogue objects (default: every training object)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   metavar="N", help="parallel objects (default: all cores)")
    p.add_argument("--backend", choices=("process", "ray"), default="process",
                   help="local processes, or Ray (RAY_ADDRESS, else local)")
    p.add_argument("--catch-points", type=int, default=1, metavar="K",
                   help="catch points per object, each with its own map and "
                        "label (default 1, as the shipped data set)")
    p.add_argument("--all-targets", action="store_true",
                   help="one data set per grasp target the learned planner "
                        "trains on (keep and flip at -30, 0, +30 mm), in "
                        "--out/dataset_<kind><mm> (dataset_flip+0, ...), "
                        "their entries on one pool of workers")
    p.add_argument("--out", type=Path, metavar="DIR",
                   default=InOutDir("dataset"),
                   help="output directory; an existing data set is resumed "
                        "(default dataset/ in --out-dir; the shipped one is "
                        "models/dataset); with --all-targets, the directory "
                        "of the targets' data sets")
    _add_out_dir_arg(p)
    p.set_defaults(func=_cmd_dataset)

    p = sub.add_parser("train", help="train the catch network, or the "
                                     "learned planner of a grasp target, on "
                                     "a data set")
    p.add_argument("--target", choices=("keep", "flip", "turn"),
                   help="the grasp target whose data set to learn from "
                        "(models/dataset_<kind><mm>, e.g. dataset_flip+0); "
                        "the learned planner by default")
    p.add_argument("--offset-mm", type=float, metavar="MM",
                   help="with --target: the target's offset, mm (default 0)")
    p.add_argument("--network", choices=("planner", "paper"),
                   help="planner: the learned planner (a success model over "
                        "every cell; the default under --target), judged by "
                        "geometry and by object against the paper's network, "
                        "the best constant cell and each map's best; paper: "
                        "the paper's 5-13-2 network (the default otherwise)")
    p.add_argument("--data", type=Path, metavar="DIR",
                   help="data set directory (default models/dataset, or the "
                        "target's)")
    p.add_argument("--out", type=Path, metavar="F",
                   default=InOutDir("{trained}"),
                   help="the network's weights file, with its report F.json "
                        "and training curve F_training.png beside it "
                        "(default catch_mlp.pt in --out-dir; the shipped "
                        "network is models/catch_mlp.pt), or the planner's "
                        "file (default planner_<kind><mm>.json in --out-dir; "
                        "the shipped ones are in models/)")
    p.add_argument("--json", type=Path, metavar="F",
                   help="also write the report here (the planner's: for "
                        "by_geometry and by_object, the success rates of "
                        "learned, paper_network, best_constant, ceiling)")
    _add_out_dir_arg(p)
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the split and the initial weights")
    p.add_argument("--splits", type=int, default=20, metavar="N",
                   help="also judge the network over N random splits (seeds "
                        "seed … seed+N-1; default 20, 1 for none)")
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("table1", help="the paper's Table 1: the learning "
                                      "phase on its five test objects "
                                      "(--search as for learn)")
    scenario_args.add(p)
    _add_library_arg(p)
    p.add_argument("--weights", type=Path, metavar="F",
                   help="the MLP's weights file (default: the scenario's "
                        "catch.weights in models/)")
    p.add_argument("--json", type=Path, metavar="F", help="write the rows")
    p.add_argument("--markdown", type=Path, metavar="F",
                   help="write the table")
    maps = p.add_mutually_exclusive_group()
    maps.add_argument("--maps-dir", type=Path,
                      default=InOutDir("table1-maps"), metavar="DIR",
                      help="each test object's success map, with the search "
                           "marked (JSON lines + PNG; an existing map is "
                           "resumed; default table1-maps/ in --out-dir)")
    maps.add_argument("--no-maps", action="store_true",
                      help="skip the success maps (150 episodes per object)")
    p.add_argument("--max-throws", type=int, metavar="N",
                   help="stop each object's learning phase after N throws")
    p.add_argument("--objects", nargs="+", metavar="NAME",
                   help="other objects instead of Table 1's (e.g. the "
                        "holdout-* objects); no paper figures for them")
    _add_first_throw_args(p)
    _add_search_arg(p)
    _add_offset_prior_arg(p)
    p.set_defaults(func=_cmd_table1)

    p = sub.add_parser("train-flight", help="fit the flight predictor (the "
                       "first-throw mode's) on the data set's flights")
    scenario_args.add(p)
    p.add_argument("--data", type=Path, metavar="DIR",
                   help="data set directory (default models/dataset)")
    p.add_argument("--out", type=Path, metavar="F",
                   default=InOutDir("flight_predictor.json"),
                   help="the predictor, with its report F.report.json beside "
                        "it (default flight_predictor.json in --out-dir; the "
                        "shipped one is models/flight_predictor.json)")
    _add_out_dir_arg(p)
    p.set_defaults(func=_cmd_train_flight)

    p = sub.add_parser("train-offset", help="fit the offset prior: how far "
                       "each target's catch slides along the axis, from one "
                       "catch per training object and target")
    scenario_args.add(p, target=False)
    p.add_argument("--targets", nargs="+", metavar="KIND:MM",
                   default=[f"{k}:{o}" for k in ("keep", "flip")
                            for o in (-30, 0, 30)],
                   help="the targets (default keep and flip at -30, 0, +30)")
    p.add_argument("--objects", nargs="+", metavar="NAME",
                   help="catalogue objects (default: every training object)")
    p.add_argument("--weights", type=Path, metavar="F",
                   help="the MLP's weights file (default: the scenario's "
                        "catch.weights in models/)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   metavar="N", help="worker processes (default: all cores)")
    p.add_argument("--out", type=Path, metavar="F",
                   default=InOutDir("offset_prior.json"),
                   help="the prior, its rows F.rows.jsonl beside it (resumed "
                        "when present); default offset_prior.json in "
                        "--out-dir; the shipped one is models/offset_prior.json")
    _add_out_dir_arg(p)
    p.set_defaults(func=_cmd_train_offset)


# Worker processes beyond this many per core only slow a run down.
_WORKERS_PER_CORE = 4


def _check_workers(workers: int) -> None:
    most = _WORKERS_PER_CORE * (os.cpu_count() or 1)
    if not 1 <= workers <= most:
        raise InputError(f"--workers: got {workers}, expected 1 … {most} "
                         f"({_WORKERS_PER_CORE} per core of this machine)")

def _interrupted_in_a_worker(signum, frame):
    """SIGINT (Ctrl-C reaches the whole process group) in a forked worker:
    it ends quietly; the command's own process reports the interruption."""
    os._exit(130)


def _quiet_lost_interrupt(unraisable) -> None:
    """sys.unraisablehook while the command runs: a KeyboardInterrupt that
    Python could not raise (Ctrl-C in a hook that ignores exceptions, such
    as logging's at-fork lock release) is not printed: note_interrupt
    recorded it, and check_interrupt raises it again at the next safe
    point, so the command still reports it in one line."""
    if not issubclass(unraisable.exc_type, KeyboardInterrupt):
        sys.__unraisablehook__(unraisable)


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    main_pid = os.getpid()

    def on_sigint(signum, frame):
        if os.getpid() != main_pid:
            _interrupted_in_a_worker(signum, frame)
        note_interrupt()
        raise KeyboardInterrupt

    note_interrupt(False)
    previous = signal.getsignal(signal.SIGINT)
    previous_hook = sys.unraisablehook
    if previous is signal.default_int_handler:
        signal.signal(signal.SIGINT, on_sigint)
        sys.unraisablehook = _quiet_lost_interrupt
    try:
        if (args.command != "objects" and "object_file" in vars(args)
                and args.object is None and args.object_file is None):
            raise InputError("--object, --object-file: got neither, expected "
                             "a catalogue object's name, an object file, or "
                             "both (the named object of the file)")
        outputs.fill_defaults(args)
        outputs.check_outputs(args)
        if getattr(args, "out_dir", None) is not None:
            args.out_dir.mkdir(parents=True, exist_ok=True)
        if "scenario" in vars(args):  # loaded once: the command's from here
            args.scenario, args.scenario_label = scenario_args.load(
                args, target_required=getattr(args, "target_required", False))
        return args.func(args)
    except InputError as e:
        # One line whatever the message holds, and never a huge one.
        message = " ".join(str(e).split())
        if len(message) > 1000:
            message = message[:500] + " … " + message[-400:]
        print(f"regrasp-drake {args.command}: error: {message}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"regrasp-drake {args.command}: interrupted; what was written "
              "so far is kept (a map or data set resumes from it)",
              file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`regrasp-drake objects | head`): no
        # traceback. Python's documented recipe: what is left of stdout
        # goes nowhere, and the exit status is 1.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    finally:
        if previous is signal.default_int_handler:
            signal.signal(signal.SIGINT, previous)
            sys.unraisablehook = previous_hook


if __name__ == "__main__":
    sys.exit(main())
