"""How far success maps agree: each map's catches, and for every pair the
cells with the same outcome (caught or not), over the cells both hold, with
the number two independent maps of those catch rates would share by chance.

    .venv/bin/python studies/cenic/map_agreement.py
        "discrete 0.25 ms=out/ptmaps/row2_0.00025.jsonl"
        "CENIC 1e-4=out/cenic_maps/row2_1e-4.jsonl" ...

Each map is LABEL=FILE, FILE the JSON lines of `regrasp-drake grid --out`.
"""

import itertools
import json
import sys
from pathlib import Path


def read_map(path: Path) -> dict:
    """{cell: caught} of a grid's JSON lines."""
    cells = {}
    for line in path.read_text().splitlines():
        if line.strip():
            row = json.loads(line)
            cells[tuple(row["cell"])] = row["outcome"] == "caught"
    return cells


def agreement(a: dict, b: dict) -> dict:
    shared = sorted(set(a) & set(b))
    if not shared:
        return {"cells": 0, "same": 0, "chance": 0.0}
    p = sum(a[c] for c in shared) / len(shared)
    q = sum(b[c] for c in shared) / len(shared)
    return {"cells": len(shared),
            "same": sum(a[c] == b[c] for c in shared),
            "chance": round(len(shared) * (p * q + (1 - p) * (1 - q)), 1)}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    maps = {}
    for arg in argv:
        label, sep, path = arg.partition("=")
        if not sep or not Path(path).is_file():
            print(f"error: got {arg!r}, expected LABEL=FILE of a grid's "
                  "JSON lines", file=sys.stderr)
            return 2
        maps[label] = read_map(Path(path))
    print("| map | cells | caught |\n|---|---:|---:|")
    for label, cells in maps.items():
        print(f"| {label} | {len(cells)} | {sum(cells.values())} |")
    print("\n| maps | cells in both | same outcome | by chance |\n"
          "|---|---:|---:|---:|")
    for a, b in itertools.combinations(maps, 2):
        r = agreement(maps[a], maps[b])
        print(f"| {a} / {b} | {r['cells']} | {r['same']} | {r['chance']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
