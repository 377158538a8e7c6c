"""The test suite on every core: `python -m tests [--jobs N] [module ...]`.

unittest runs one test at a time, and most of this suite is serial
simulation, so one of a 2-core machine's cores idles. This runner splits
the test modules into N shards of about equal cost (the costs below,
measured: wall seconds of each module run alone; others count
DEFAULT_COST_S), runs each shard as `python -m tests.shard MODULES` (each
module in turn, as `python -m unittest -v` would, with its wall seconds)
in its own process, prints each shard's output as it finished, and exits
non-zero when any shard fails. Each module runs whole in one shard, so its
setUpClass fixtures are shared as before.
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# Wall seconds of the slower modules in one run of the whole suite (the
# "module wall seconds" tests/shard.py prints; measured 2026-12-07 with the
# machine shared, so only their ratios matter); others count DEFAULT_COST_S.
COSTS_S = {
    "tests.test_dataset": 189.0,
    "tests.test_reliability": 133.0,
    "tests.test_planner": 105.0,
    "tests.test_cli": 94.0,
    "tests.test_flight_predictor": 89.0,
    "tests.test_input_fuzz": 74.0,
    "tests.test_rehearsal": 71.0,
    "tests.test_learning": 70.0,
    "tests.test_grasp_monitor": 66.0,
    "tests.test_branching": 63.0,
    "tests.test_episode": 63.0,
    "tests.test_first_throw_tolerance": 56.0,
    "tests.test_throw_cache": 45.0,
    "tests.test_static_hold": 30.0,
    "tests.test_install": 28.0,
    "tests.test_replay": 28.0,
    "tests.test_episode_benchmark": 25.0,
    "tests.test_examples": 25.0,
    "tests.test_release_correction": 22.0,
    "tests.test_grasp": 21.0,
    "tests.test_catch_plan": 20.0,
    "tests.test_station": 17.0,
    "tests.test_notebook": 14.0,
    "tests.test_api": 12.0,
    "tests.test_noise_curve": 11.0,
    "tests.test_search": 10.0,
}
DEFAULT_COST_S = 3.0


def modules(names: list[str]) -> list[str]:
    if names:
        return names
    return sorted(f"tests.{p.stem}" for p in (REPO / "tests").glob("test_*.py"))


def shards(names: list[str], jobs: int) -> list[list[str]]:
    """Longest first, each to the shard with the least cost so far."""
    loads = [[0.0, []] for _ in range(jobs)]
    for name in sorted(names, key=lambda n: -COSTS_S.get(n, DEFAULT_COST_S)):
        load = min(loads, key=lambda entry: entry[0])
        load[0] += COSTS_S.get(name, DEFAULT_COST_S)
        load[1].append(name)
    return [sorted(mods) for _, mods in loads if mods]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--jobs", type=int, default=2,
                        help="shards run at once (default 2)")
    parser.add_argument("modules", nargs="*",
                        help="test modules, e.g. tests.test_station "
                             "(default: every tests/test_*.py)")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error(f"--jobs: got {args.jobs}, expected at least 1")
    start = time.perf_counter()
    plan = shards(modules(args.modules), args.jobs)
    with tempfile.TemporaryDirectory() as tmp:
        runs = []
        for k, mods in enumerate(plan):
            log = open(Path(tmp) / f"shard{k}.log", "w+")
            # Each shard its own process group, so that an interrupt reaches
            # its workers too.
            process = subprocess.Popen(
                [sys.executable, "-m", "tests.shard", *mods], cwd=REPO,
                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
            runs.append((k, mods, log, process, time.perf_counter()))
            print(f"shard {k}: {len(mods)} modules", flush=True)
        failed = []
        try:
            pending = list(runs)
            while pending:
                for run in list(pending):
                    k, mods, log, process, t0 = run
                    if process.poll() is None:
                        continue
                    pending.remove(run)
                    log.seek(0)
                    print(f"\n===== shard {k} ({', '.join(mods)}): exit "
                          f"{process.returncode}, "
                          f"{time.perf_counter() - t0:.0f} s =====",
                          flush=True)
                    sys.stdout.write(log.read())
                    sys.stdout.flush()
                    if process.returncode != 0:
                        failed.append(k)
                time.sleep(0.5)
        except KeyboardInterrupt:
            for _, _, _, process, _ in runs:
                if process.poll() is None:
                    os.killpg(process.pid, signal.SIGTERM)
            return 130
    print(f"\n{len(plan)} shards, {time.perf_counter() - start:.0f} s: "
          + (f"shard(s) {failed} FAILED" if failed else "all passed"),
          flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
