"""Where does the gap between the best constant cell and the ceiling lie?
The six target data sets' maps, lopsided objects (an off-axis centre of
mass: their grasp has a side, planning/grasp.py) apart from round ones.

    .venv/bin/python studies/learned_planner/misses.py

Per target and group: the maps, the best constant cell of all the maps
(in sample) and how many maps it holds in the target grasp, the ceiling
(maps with any cell in it), the share of cells in it, and every missing
cell's cause from its row in cells/<entry>.jsonl, as the learning phase
names it (planning/grasp.py `miss_reason`): dropped, wrong way round (the
axis reversed, or for a lopsided object the side not where the target
turns it), tilted (the axis more than 20 degrees off), off offset (more
than 10 mm off). Prints a table and writes misses.json here.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import collections
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake import atomic_io
from regrasp_drake.learning.planner import PlannerData, best_constant
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning import grasp
from regrasp_drake.planning.grasp import has_side
from regrasp_drake.world.objects import resolve_object

HERE = Path(__file__).resolve().parent
TARGETS = ["keep-30", "keep+0", "keep+30", "flip-30", "flip+0", "flip+30"]
CAUSES = ("dropped", "wrong_way_round", "tilted", "off_offset")


def cause(row: dict) -> str:
    """Why a cell's catch missed the target grasp (grasp.miss_reason)."""
    held = row["outcome"] in ("caught", "wrong_grasp")
    return grasp.miss_reason(held, row.get("grasp_error")) or "dropped"


def main() -> int:
    report = {}
    for target in TARGETS:
        data_dir = MODELS_DIR / f"dataset_{target}"
        data = PlannerData.load(data_dir)
        constant = best_constant(data.caught)
        lopsided = np.array([has_side(resolve_object(name=n.partition("@")[0]))
                             for n in data.objects])
        report[target] = {"best_constant_cell": list(constant)}
        for group, mask in (("lopsided", lopsided), ("round", ~lopsided)):
            misses = collections.Counter()
            for name in np.array(data.objects)[mask]:
                for line in (data_dir / "cells" / f"{name}.jsonl").open():
                    row = json.loads(line)
                    if row["outcome"] != "caught":
                        misses[cause(row)] += 1
            caught = data.caught[mask]
            report[target][group] = {
                "maps": int(mask.sum()),
                "best_constant_holds": int(caught[:, constant[0], constant[1]].sum()),
                "ceiling": int(caught.reshape(len(caught), -1).any(1).sum()),
                "cells_in_target": round(float(caught.mean()), 4),
                "misses": {c: misses[c] for c in CAUSES}}
    print("| Target | Group | Maps | Best constant holds | Ceiling | Cells in "
          "target | Missed cells: dropped / wrong way round / tilted / off offset |")
    print("|---|---|---|---|---|---|---|")
    for target, groups in report.items():
        for group in ("round", "lopsided"):
            g = groups[group]
            print(f"| {target} | {group} | {g['maps']} | {g['best_constant_holds']}"
                  f" | {g['ceiling']} | {g['cells_in_target']:.2f} | "
                  + " / ".join(str(g["misses"][c]) for c in CAUSES) + " |")
    atomic_io.write_json(HERE / "misses.json", report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
