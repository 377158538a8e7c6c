"""The scenario's options, for the command line and the benchmark scripts
alike: --scenario F, --scenario-name NAME, --scenario-text YAML and, where
a command aims for a grasp, --target and --offset-mm.

`load` merges them as data and loads the scenario once
(station.scenario.load_scenario: the file, the named scenario and the
text's fields, then one `yaml_load_typed`); the target's throw is then
picked (`with_target`). What a command hands its workers is that Scenario
itself: it pickles as its YAML (Scenario.__reduce__), never through a
temporary file.
"""

import argparse
from pathlib import Path

from regrasp_drake.errors import InputError

TARGETS = ("keep", "flip", "turn", "any")


def add(p: argparse.ArgumentParser, *, text: bool = True,
        target: bool = True) -> None:
    """Adds --scenario and --scenario-name, --scenario-text when `text`,
    --target and --offset-mm when `target`."""
    p.add_argument("--scenario", metavar="F", type=Path,
                   help="a scenario YAML file; with --scenario-name, a file "
                        "of named scenarios (default: "
                        "regrasp_drake/scenarios.yaml)")
    p.add_argument("--scenario-name", metavar="NAME",
                   help="a scenario of the named scenarios' file, e.g. Fast "
                        "(default: Default)")
    if text:
        p.add_argument("--scenario-text", metavar="YAML",
                       help="fields that replace the scenario's, e.g. "
                            "'{catch: {return_s: 0.4}}'")
    if not target:
        return
    p.add_argument("--target", choices=TARGETS,
                   help="the grasp the catch must end in, relative to how "
                        "the object lies before the throw (keep, flip: end "
                        "over end, turn: the wrist's half turn, any: held at "
                        "all); picks the target's throw (default: the "
                        "scenario's regrasp.target, 'any')")
    p.add_argument("--offset-mm", type=float, metavar="MM",
                   help="with --target: the palm centre's position along the "
                        "object's axis from its centre of mass, mm (default 0)")


def load(args: argparse.Namespace, *, target_required: bool = False,
         over: str | None = None):
    """(scenario, label): the scenario the options of `args` (as `add`
    made them) give, loaded once and validated, and how it was given (for
    provenance: the flags and their values, the file's absolute path, or
    "defaults"). over: YAML fields over those of the options (a script's
    own, for some of its runs; the label leaves them out). Refuses
    --offset-mm without --target, and no --target when `target_required`."""
    from regrasp_drake.station.scenario import (
        load_scenario,
        merged_text,
        with_target,
    )
    path = args.scenario
    name = getattr(args, "scenario_name", None)
    text = getattr(args, "scenario_text", None)
    kind = getattr(args, "target", None)
    offset = getattr(args, "offset_mm", None)
    if kind is None and target_required:
        raise InputError("--target: missing, expected keep, flip, turn or any")
    if offset is not None and kind is None:
        raise InputError(f"--offset-mm: got {offset:g} without --target, "
                         "expected --target keep, flip, turn or any beside it")
    fields = text
    if over is not None:
        fields = over if text is None else merged_text(text, over)
    scenario = load_scenario(path, name=name, text=fields)
    if kind is not None:
        from regrasp_drake.planning.grasp import OFFSET_LIMIT_MM, Target
        if offset is not None and not abs(offset) <= OFFSET_LIMIT_MM:
            raise InputError(f"--offset-mm: got {offset:g}, expected a number "
                             f"in [-{OFFSET_LIMIT_MM:g}, +{OFFSET_LIMIT_MM:g}]")
        scenario = with_target(scenario, Target(kind, offset or 0.0))
    if name is None and text is None and kind is None:
        return scenario, str(path.resolve()) if path else "defaults"
    given = [("--scenario", path and path.resolve()),
             ("--scenario-name", name), ("--scenario-text", text),
             ("--target", kind), ("--offset-mm", offset)]
    return scenario, " ".join(f"{flag} {value}" for flag, value in given
                              if value is not None)
