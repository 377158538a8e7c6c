"""examples/throw_catch.py, the README's main command, as a user runs it."""

import json
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

ROOT = Path(__file__).parents[1]


def _example(*args):
    return subprocess.run(
        [sys.executable, str(ROOT / "examples" / "throw_catch.py"), *args],
        capture_output=True, text=True, timeout=300)


class ThrowCatchExampleTest(unittest.TestCase):
    def test_own_object_caught_with_replay_and_plot(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "spatula.html"
            result = _example("--object-file",
                              str(ROOT / "examples" / "my_object.yaml"),
                              "--object", "spatula-d250", "--out", str(out))
            self.assertEqual(result.returncode, 0, result.stderr)
            summary = json.loads(result.stdout[:result.stdout.rindex("}") + 1])
            self.assertEqual(summary["object"], "spatula-d250")
            # In the example's default target grasp (flip, +0 mm), which
            # the last line says first.
            self.assertTrue(summary["success"])
            self.assertRegex(result.stdout.strip().splitlines()[-1],
                             r"^flip, \+0 mm: in the target grasp \(held "
                             r"flip, [+-]\d+ mm, tilt \d+°\)$")
            self.assertGreater(out.stat().st_size, 100_000)
            self.assertGreater(out.with_suffix(".png").stat().st_size, 10_000)

    def test_missing_object_file_refused_in_one_line(self):
        result = _example("--object-file", "/nonexistent.yaml")
        self.assertEqual(result.returncode, 2)
        self.assertEqual(len(result.stderr.strip().splitlines()), 1,
                         result.stderr)
        self.assertIn("/nonexistent.yaml", result.stderr)


if __name__ == "__main__":
    unittest.main()
