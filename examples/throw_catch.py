"""Throw a Table 1 object, watch its flight, and catch it; save the replay.

    .venv/bin/python examples/throw_catch.py [--object table1-row2]

Writes throw_catch.html (the Meshcat replay, self-contained) and
throw_catch.png (the sensors over time), and prints the outcome.
"""

import argparse
import json
import sys
from pathlib import Path

from regrasp_drake.errors import InputError
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import catch_once


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--out", type=Path, default=Path("throw_catch.html"))
    args = parser.parse_args()
    defaults = load_scenario().catch
    try:
        result, plan = catch_once(
            object_name=args.object, h_catch=defaults.h_catch_m,
            h_down=defaults.h_down_m, html=args.out,
            plot=args.out.with_suffix(".png"))
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(result.summary() | {"plan": plan.as_dict()}, indent=1))
    print(f"replay: {args.out}  sensors: {args.out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
