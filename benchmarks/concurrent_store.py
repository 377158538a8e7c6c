"""Several processes adding entries to one regrasp library at once, as
`learn --library L` runs started together in a shell loop do at their end
(issue 44): how many entries survive, how many processes fail.

    .venv/bin/python benchmarks/concurrent_store.py [--processes 6]
        [--entries 25] [--library out/concurrent_library.yaml]

Prints one JSON line: processes, entries each, entries kept (of
processes × entries), processes failed and the first failure's last line.
Before the library's update was locked (main at edbdaa0): 6 × 25 kept 26 of
150, 1 to 3 processes failed with FileNotFoundError 'L.tmp' -> 'L'.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import math
import multiprocessing
import sys
import time
import traceback
from pathlib import Path

from regrasp_drake.learning.library import LearnedEntry, load_library, store
from regrasp_drake.paths import OUT_DIR


def example_entry() -> LearnedEntry:
    """A valid entry (the values of a real one of table1-row2)."""
    c, s = math.cos(1.234), math.sin(1.234)
    return LearnedEntry(
        object_source="catalogue",
        object_features={"h_cm": -0.01, "r_cm": 0.0, "d_obj": 200.0,
                         "v_conv": 0},
        scenario="defaults", scenario_digest="0" * 64, code_version="0.1.0",
        catch_point={"t_s": 1.312, "p_WO": [0.88, -0.115, 0.775],
                     "axis_W": [0.939, 0.329, -0.105], "v_catch": -3.516,
                     "tilt": 0.105},
        p_WG=[0.88, -0.115, 0.743],
        R_WG=[[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]],
        q_grasp=[0.227, -0.26, -0.853, -1.522, -1.472, 4.252], side="paper",
        h_catch=0.2, h_down=-0.05, cell=[4, 9], throws=2, mode="watch",
        search="wavefront")


def _store_many(library, process, entries, start_at, failures):
    """One process's stores, begun at start_at (time.time()) so that all
    processes start together; a failure's last line goes to `failures`."""
    entry = example_entry()
    time.sleep(max(0.0, start_at - time.time()))
    try:
        for k in range(entries):
            store(library, f"p{process}-e{k}", entry)
    except BaseException as e:  # noqa: BLE001 (counted, reported)
        failures.put(f"{type(e).__name__}: {e}")
        traceback.print_exc()
        sys.exit(1)


def run(library: Path, processes: int, entries: int) -> dict:
    """processes × entries concurrent store() calls on a new library."""
    library = Path(library)
    library.unlink(missing_ok=True)
    ctx = multiprocessing.get_context("fork")
    failures = ctx.Queue()
    start_at = time.time() + 0.5
    workers = [ctx.Process(target=_store_many,
                           args=(library, p, entries, start_at, failures))
               for p in range(processes)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    failed = [w for w in workers if w.exitcode != 0]
    first = failures.get(timeout=5) if failed else None
    return {"processes": processes, "entries_each": entries,
            "kept": len(load_library(library)),
            "of": processes * entries, "processes_failed": len(failed),
            "first_failure": first}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--processes", type=int, default=6)
    p.add_argument("--entries", type=int, default=25)
    p.add_argument("--library", type=Path,
                   default=OUT_DIR / "concurrent_library.yaml")
    args = p.parse_args(argv)
    if args.processes < 1 or args.entries < 1:
        print("concurrent_store.py: error: --processes, --entries: expected "
              "integers >= 1", file=sys.stderr)
        return 2
    args.library.parent.mkdir(parents=True, exist_ok=True)
    print(json.dumps(run(args.library, args.processes, args.entries)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
