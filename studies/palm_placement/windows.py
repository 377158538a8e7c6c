"""Where should the palm wait? For each Table 1 object, at its learned cell,
how many of the 25 offsets of the ±20 mm tolerance grid would catch if the
palm waited at another place in its own plane.

    .venv/bin/python studies/palm_placement/windows.py [scan.jsonl]

Reads the dense scan (`scan.jsonl`: every palm offset dx = -40 … 40 mm
across the object's axis, 10 mm apart, and dy = -40 … 40 mm along it, 5 mm
apart, from the shipped plan, one catch each, written by
`benchmarks/catch_tolerance.py OBJECT H_CATCH H_DOWN --offsets=… --tag
scan`; FINDINGS.md has the commands) and prints each object's map of
outcomes and, for each palm placement (sx, sy) on that lattice, the caught
count of the 25-offset grid around it: the figure issue 26 asks at (0, 0).
A placement moves the palm rigidly in its plane; the throw and the cell are
the same, so the grid around (sx, sy) is the scan's offsets (sx + dx,
sy + dy).
"""

import json
import sys
from collections import defaultdict
from pathlib import Path

GRID_MM = range(-20, 21, 10)


def load(path):
    maps = defaultdict(dict)
    for line in Path(path).read_text().splitlines():
        row = json.loads(line)
        maps[row["object"]][(row["dx_mm"], row["dy_mm"])] = (
            row["outcome"] == "caught")
    return maps


def window(caught, sx, sy):
    """Offsets caught of the 25 around (sx, sy), or None where the scan
    does not cover them."""
    cells = [(sx + dx, sy + dy) for dx in GRID_MM for dy in GRID_MM]
    if not all(c in caught for c in cells):
        return None
    return sum(caught[c] for c in cells)


def main(path=Path(__file__).with_name("scan.jsonl")):
    for name, caught in sorted(load(path).items()):
        dxs = sorted({dx for dx, _ in caught})
        dys = sorted({dy for _, dy in caught})
        print(f"{name}: {sum(caught.values())} of {len(caught)} offsets "
              "caught (rows dy from +40 down, columns dx from -40; c caught)")
        for dy in reversed(dys):
            print(f"  dy {dy:+3d} " + "".join(
                "c" if caught[(dx, dy)] else "." for dx in dxs))
        print("  caught of 25 around the palm placed at (sx, sy) mm:")
        for sx in range(-20, 21, 10):
            counts = [(sy, window(caught, sx, sy)) for sy in range(-20, 21, 5)]
            print(f"  sx {sx:+3d}: " + "  ".join(
                f"sy {sy:+d}: {n}" for sy, n in counts if n is not None))


if __name__ == "__main__":
    main(*sys.argv[1:])
