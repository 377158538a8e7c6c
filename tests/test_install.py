"""The package as pip installs it: a wheel built from the checkout, installed
into a fresh virtualenv, run from a folder outside the checkout.

The virtualenv gets the wheel alone (--no-deps, no network); Drake, torch
and NumPy come from the running interpreter's site-packages through a .pth
line (a path only: its editable install of this checkout stays out).
"""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import unittest
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# What a wheel is built from (pyproject.toml's packages and package-dir).
SOURCES = ("pyproject.toml", "README.md", "regrasp_drake", "sdf", "models")


def _run(cmd, cwd, env=None):
    return subprocess.run([str(c) for c in cmd], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300)


class InstalledWheelTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        tmp = Path(cls.tmp.name)
        # Built from a copy: setuptools' build/ in the checkout would keep
        # files of earlier builds.
        src = tmp / "src"
        src.mkdir()
        for name in SOURCES:
            if (ROOT / name).is_dir():
                # (not the data sets and results, which the wheel leaves)
                skip = ("dataset_*", "results") if name == "models" else ()
                shutil.copytree(ROOT / name, src / name, ignore=shutil.
                                ignore_patterns("__pycache__", *skip))
            else:
                shutil.copy2(ROOT / name, src / name)
        built = _run([sys.executable, "-m", "pip", "wheel", "--no-deps",
                      "--no-build-isolation", "--no-index", "-w", tmp / "dist",
                      src], cwd=tmp)
        assert built.returncode == 0, built.stdout + built.stderr
        cls.wheel = next((tmp / "dist").glob("regrasp_drake-*.whl"))
        venv = tmp / "venv"
        made = _run([sys.executable, "-m", "venv", "--without-pip", venv],
                    cwd=tmp)
        assert made.returncode == 0, made.stderr
        cls.python = venv / "bin" / "python"
        site = _run([cls.python, "-c", "import sysconfig; print(sysconfig."
                     "get_paths()['purelib'])"], cwd=tmp).stdout.strip()
        Path(site, "running_interpreter.pth").write_text(
            sysconfig.get_paths()["purelib"] + "\n")
        cls.env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        # --ignore-installed: the running interpreter's editable install,
        # seen through the .pth, is neither taken for this one nor removed.
        installed = _run([sys.executable, "-m", "pip", "--python", cls.python,
                          "install", "--no-deps", "--no-index",
                          "--ignore-installed", cls.wheel], cwd=tmp,
                         env=cls.env)
        assert installed.returncode == 0, installed.stdout + installed.stderr
        cls.work = tmp / "work"  # outside the checkout
        cls.work.mkdir()

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def _command(self, *args):
        return _run([self.python.parent / "regrasp-drake", *args],
                    cwd=self.work, env=self.env)

    def test_wheel_holds_every_module_and_the_models(self):
        names = set(zipfile.ZipFile(self.wheel).namelist())
        modules = {str(p.relative_to(ROOT)) for p in
                   (ROOT / "regrasp_drake").rglob("*.py")
                   if "__pycache__" not in p.parts}
        self.assertEqual(modules - names, set())
        for name in ("sdf/package.xml", "sdf/puma560.sdf", "sdf/hand.sdf",
                     "sdf/puma560_hand.dmd.yaml", "sdf/objects/catalogue.yaml",
                     "models/catch_mlp.pt", "models/flight_predictor.json",
                     "models/offset_prior.json", "models/dataset/maps.npz",
                     "scenarios.yaml"):
            self.assertIn(f"regrasp_drake/{name}", names)

    def test_objects_and_catch_outside_the_checkout(self):
        listed = self._command("objects", "--json")
        self.assertEqual(listed.returncode, 0, listed.stderr)
        self.assertIn("table1-row2", {o["name"] for o in
                                      json.loads(listed.stdout)})
        caught = self._command(
            "catch", "--object", "table1-row2", "--h-catch", "0.32",
            "--h-down", "-0.07", "--scenario-name", "Fast", "--json",
            "catch.json", "--html", "catch.html")
        self.assertEqual(caught.returncode, 0, caught.stderr)
        summary = json.loads((self.work / "catch.json").read_text())
        self.assertEqual(summary["outcome"], "caught")
        self.assertGreater((self.work / "catch.html").stat().st_size, 100_000)
        # Bad input: one line, exit status 2, from the installed package too.
        refused = self._command("catch", "--object", "none-such", "--h-catch",
                                "0.2", "--h-down", "-0.05")
        self.assertEqual(refused.returncode, 2)
        self.assertIn("none-such", refused.stderr)

    def test_api_regrasp_outside_the_checkout(self):
        script = (
            "import regrasp_drake as rd, json, sys\n"
            "obj = rd.load_object('table1-row2')\n"
            "run = rd.regrasp(obj, rd.Target('flip'), watch=False,\n"
            "                 scenario=rd.load_scenario('Fast'))\n"
            "run.save_replay('replay.html'); run.plot('sensors.png')\n"
            "print(json.dumps([rd.__file__, run.success, run.throws,\n"
            "                  run.achieved_grasp['kind']]))\n")
        result = _run([self.python, "-c", script], cwd=self.work, env=self.env)
        self.assertEqual(result.returncode, 0, result.stderr)
        where, success, throws, kind = json.loads(
            result.stdout.strip().splitlines()[-1])
        self.assertTrue(where.startswith(str(self.python.parents[1])), where)
        self.assertEqual((success, throws, kind), (True, 1, "flip"))
        for name in ("replay.html", "sensors.png"):
            self.assertGreater((self.work / name).stat().st_size, 10_000)
        # Outputs given no path: ./out of the working directory.
        self.assertTrue((self.work / "out" / "regrasp_library.yaml").is_file())


if __name__ == "__main__":
    unittest.main()
