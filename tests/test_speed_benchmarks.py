"""benchmarks/tree_memory.py and dataset_benchmark.py: memory summed over a
process tree, and the refusals."""

import contextlib
import io
import sys
import unittest

from tests.refusals import load_script

tree_memory = load_script("benchmarks/tree_memory.py")
dataset_benchmark = load_script("benchmarks/dataset_benchmark.py")

# A child that starts a grandchild; each holds about 150 MB for a while.
_HOLD = ("import time; b = bytearray(150 * 2**20); b[::4096] = b'x' * "
         "len(b[::4096]); time.sleep(1.5)")
_TREE = (f"import subprocess, sys; p = subprocess.Popen([sys.executable, "
         f"'-c', {_HOLD!r}]); exec({_HOLD!r}); p.wait()")


class TreeMemoryTest(unittest.TestCase):
    def test_peak_sums_the_children(self):
        report = tree_memory.run_sampled([sys.executable, "-c", _TREE],
                                         interval_s=0.1)
        self.assertEqual(report["returncode"], 0)
        # Two processes of 150 MB each at once: more than one alone holds.
        self.assertGreater(report["peak_tree_rss_bytes"], 290 * 2**20)
        self.assertLess(report["peak_tree_rss_bytes"], 1 * 2**30)

    def test_exit_code_passed_on(self):
        with contextlib.redirect_stdout(io.StringIO()):
            code = tree_memory.main(["--", sys.executable, "-c",
                                     "raise SystemExit(3)"])
        self.assertEqual(code, 3)


class DatasetBenchmarkRefusalTest(unittest.TestCase):
    def test_bad_arguments_refused(self):
        for argv, expected in ((["--workers", "0"], "--workers"),
                               (["--full-run", "/no/such/dir"],
                                "--full-run")):
            with self.subTest(argv=argv), \
                    contextlib.redirect_stderr(io.StringIO()) as err, \
                    self.assertRaises(SystemExit) as exit_:
                dataset_benchmark.main(argv)
            self.assertEqual(exit_.exception.code, 2)
            self.assertIn(expected, err.getvalue())


if __name__ == "__main__":
    unittest.main()
