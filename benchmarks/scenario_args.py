"""--scenario and --scenario-name for the benchmark scripts, as the
command line has them: a scenario file, or a named scenario of
regrasp_drake/scenarios.yaml (Default, the shipped one; Fast, the same at
1 ms; FingerThrow, the retired throw) or of --scenario's file. The scripts
hand their workers a scenario path, so a named scenario is written to a
temporary file for the run."""

import argparse
import contextlib
import tempfile
from pathlib import Path


def resolved(args, stack: contextlib.ExitStack):
    """--scenario-name: the named scenario (of --scenario's file, or of the
    shipped regrasp_drake/scenarios.yaml) written to a temporary file, kept
    until `stack` closes, that args.scenario then names for the run and its
    workers. Returns how the scenario was given (None: the shipped one)."""
    if args.scenario_name is None:
        return str(args.scenario) if args.scenario else None
    from regrasp_drake import atomic_io
    from regrasp_drake.station.scenario import load_scenario, scenario_yaml
    scenario = load_scenario(args.scenario, name=args.scenario_name)
    label = " ".join(f"{flag} {value}" for flag, value in (
        ("--scenario", args.scenario), ("--scenario-name", args.scenario_name))
        if value is not None)
    directory = Path(stack.enter_context(
        tempfile.TemporaryDirectory(prefix="regrasp-scenario-")))
    args.scenario = directory / f"{args.scenario_name}.yaml"
    atomic_io.write_text(args.scenario, scenario_yaml(scenario))
    return label


def add(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", type=Path,
                        help="a scenario YAML file; with --scenario-name, a "
                             "file of named scenarios (default: the shipped "
                             "scenario)")
    parser.add_argument("--scenario-name", metavar="NAME",
                        help="a named scenario of --scenario's file or of "
                             "regrasp_drake/scenarios.yaml, e.g. Fast")
