"""The parameter space of the paper's §V.A, and success maps over it.

150 cells: 15 values of h_down (-0.14 … 0.00 m in steps of 0.01, the paper's
tolerance) times 10 values of h_catch (0.04 … 0.40 m in steps of 0.04). The
paper gives h_catch in [0, 0.40] with a tolerance of 0.04 and 10 states: the
10 states are 0.04 … 0.40 (h_catch = 0 would close the fingers only once the
object touches the palm). h_down: the paper's [-0.14, -0.01] with 0.01 gives 14
states for its 15; we add 0.00 (no lowering), as its Fig. 9 allows.

A success map runs one catch episode per cell, in parallel over worker
processes (each builds its own diagram; torch is held to one thread), writes
each result as a JSON line as soon as it is known, and resumes from that file.
"""

import json
import multiprocessing
import os
import sys
import time
from pathlib import Path

import numpy as np

H_DOWN_VALUES = np.round(np.arange(-0.14, 0.001, 0.01), 2)    # 15, [m]
H_CATCH_VALUES = np.round(np.arange(0.04, 0.401, 0.04), 2)    # 10, [m]


def cells() -> list[tuple[int, int]]:
    """All (i_catch, i_down) cells, row-major in h_catch."""
    return [(i, j) for i in range(len(H_CATCH_VALUES))
            for j in range(len(H_DOWN_VALUES))]


def cell_parameters(cell) -> tuple[float, float]:
    i, j = cell
    return float(H_CATCH_VALUES[i]), float(H_DOWN_VALUES[j])


def nearest_cell(h_catch: float, h_down: float) -> tuple[int, int]:
    return (int(np.argmin(np.abs(H_CATCH_VALUES - h_catch))),
            int(np.argmin(np.abs(H_DOWN_VALUES - h_down))))


# ---- success maps, in worker processes ------------------------------------
_worker = {}


def _plan(scenario_path, object_name, object_file):
    """The watching throw and the offline stage (deterministic)."""
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import load_scenario
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    scenario = load_scenario(scenario_path)
    obj = resolve_object(name=object_name, file=object_file)
    ik = ArmIk()
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    return scenario, obj, ik, plan


def _init_worker(scenario_path, object_name, object_file):
    import torch
    torch.set_num_threads(1)
    scenario, obj, ik, plan = _plan(scenario_path, object_name, object_file)
    _worker.update(scenario=scenario, obj=obj, ik=ik, plan=plan)


def _run_cell(cell):
    from regrasp_drake.station.episode import run_episode
    h_catch, h_down = cell_parameters(cell)
    w = _worker
    result = run_episode(w["scenario"], w["obj"], ik=w["ik"],
                         X_WG=w["plan"].X_WG,
                         catch_parameters=(h_catch, h_down))
    return {"cell": list(cell), "h_catch": h_catch, "h_down": h_down,
            "outcome": result.outcome, "sim_time_s": round(result.sim_time_s, 4),
            "wall_s": round(result.wall_s, 3)}


def success_map(*, object_name=None, object_file=None, scenario_path=None,
                out: Path, workers: int = 2, progress=True) -> dict:
    """Runs every cell not yet in `out` (JSON lines); returns {cell: row}."""
    out = Path(out)
    done = {}
    if out.exists():
        for line in out.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a kill: the cell runs again
            done[tuple(row["cell"])] = row
    todo = [c for c in cells() if c not in done]
    start = time.perf_counter()
    if todo:
        # Plan once here first: an object with no reachable catch point is
        # refused before any worker starts (a failing worker initializer
        # would be restarted by the pool forever).
        _plan(scenario_path, object_name, object_file)
        ctx = multiprocessing.get_context("fork")
        with ctx.Pool(workers, _init_worker,
                      (scenario_path, object_name, object_file)) as pool, \
                out.open("a") as f:
            for n, row in enumerate(pool.imap_unordered(_run_cell, todo), 1):
                f.write(json.dumps(row) + "\n")
                f.flush()
                os.fsync(f.fileno())
                done[tuple(row["cell"])] = row
                if progress:
                    _progress(n, len(todo), start)
        if progress:
            print(file=sys.stderr)
    return done


def _progress(n, total, start):
    elapsed = time.perf_counter() - start
    rate = n / elapsed
    left = (total - n) / rate if rate > 0 else float("inf")
    bar = "#" * int(30 * n / total)
    print(f"\r[{bar:<30}] {n}/{total} cells, {rate:.2f} cells/s, "
          f"{left:.0f} s left", end="", file=sys.stderr, flush=True)


def format_map(rows: dict) -> str:
    """A ✓/✗ grid: rows h_catch (m), columns h_down (cm); ? not yet run."""
    lines = ["h_catch m \\ h_down cm " + " ".join(f"{d * 100:>3.0f}"
                                                for d in H_DOWN_VALUES)]
    for i, h_catch in enumerate(H_CATCH_VALUES):
        marks = []
        for j in range(len(H_DOWN_VALUES)):
            row = rows.get((i, j))
            marks.append("?" if row is None else
                         "✓" if row["outcome"] == "caught" else "✗")
        lines.append(f"{h_catch:>20.2f}  " + " ".join(f"{m:>3}" for m in marks))
    caught = sum(r["outcome"] == "caught" for r in rows.values())
    lines.append(f"{caught}/{len(rows)} cells catch")
    return "\n".join(lines)
