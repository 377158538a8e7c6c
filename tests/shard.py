"""One shard of the suite: `python -m tests.shard MODULE ...` runs each
test module in turn in this process, as `python -m unittest -v` would, and
prints each module's wall seconds (tests/__main__.py's COSTS_S come from
these lines); exits non-zero when any test fails."""

import sys
import time
import unittest


def main(names: list[str]) -> int:
    runner = unittest.TextTestRunner(stream=sys.stdout, verbosity=2)
    failed, costs = [], []
    for name in names:
        t0 = time.perf_counter()
        result = runner.run(unittest.defaultTestLoader.loadTestsFromName(name))
        costs.append((time.perf_counter() - t0, name))
        if not result.wasSuccessful():
            failed.append(name)
    print("\nmodule wall seconds:", flush=True)
    for seconds, name in sorted(costs, reverse=True):
        print(f"  {seconds:7.1f}  {name}")
    if failed:
        print(f"FAILED: {', '.join(failed)}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
