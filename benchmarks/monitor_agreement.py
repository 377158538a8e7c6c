"""The grasp monitor's verdict against the plant's contact results, over a
whole data set.

    .venv/bin/python benchmarks/monitor_agreement.py [models/dataset]
        [--json out/monitor_agreement.json]

Every cell row of a data set (`regrasp-drake dataset`) carries both
verdicts: `outcome` (the grasp monitor's, from the simulated palm sensors,
bumper and finger servos) and `held_by_contact` (the contact results at the
episode's end: the thumb and another finger touching the object at rest
relative to the palm, `grasp_monitor.held`). Prints how many cells agree,
the two kinds of disagreement, and the disagreeing cells per object; writes
the same as JSON. Exit 2 on a missing or malformed data set.
"""

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

from regrasp_drake import atomic_io


def agreement(data_dir: Path) -> dict:
    cells_dir = data_dir / "cells"
    paths = sorted(cells_dir.glob("*.jsonl"))
    if not paths:
        raise ValueError(f"{cells_dir}: no cell rows (*.jsonl), expected a "
                         "data set directory")
    counts = Counter()
    by_object = {}
    for path in paths:
        for n, line in enumerate(path.read_text().splitlines(), 1):
            try:
                row = json.loads(line)
                caught = row["outcome"] == "caught"
                held = row["held_by_contact"]
            except (ValueError, KeyError, TypeError):
                raise ValueError(f"{path}:{n}: not a cell row with outcome "
                                 "and held_by_contact") from None
            if held is None:
                counts["no_contact_verdict"] += 1
                continue
            kind = ("agree" if caught == bool(held) else
                    "held_not_caught" if held else "caught_not_held")
            counts[kind] += 1
            if kind != "agree":
                by_object.setdefault(path.stem, []).append(
                    {"cell": row.get("cell"), "kind": kind,
                     "drop_reason": row.get("drop_reason")})
    return {"data_set": str(data_dir), "cells": sum(counts.values()),
            **{k: counts[k] for k in ("agree", "held_not_caught",
                                      "caught_not_held",
                                      "no_contact_verdict")},
            "disagreeing_by_object": by_object}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("data", nargs="?", type=Path,
                        default=Path("models/dataset"))
    parser.add_argument("--json", type=Path,
                        default=Path("out/monitor_agreement.json"))
    args = parser.parse_args(argv)
    try:
        report = agreement(args.data)
    except (ValueError, OSError) as e:
        print(f"monitor_agreement: error: {e}", file=sys.stderr)
        return 2
    print(f"{report['data_set']}: monitor and contacts agree in "
          f"{report['agree']} of {report['cells']} cells; held by contact "
          f"but not caught {report['held_not_caught']}, caught but not held "
          f"{report['caught_not_held']}"
          + (f"; no contact verdict {report['no_contact_verdict']}"
             if report["no_contact_verdict"] else ""))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(args.json, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
