"""regrasp_drake/numerics.py: NumPy's and OpenBLAS's kernels pinned before
NumPy is imported, and left alone when the user chose or it is too late."""

import ast
import json
import os
import subprocess
import sys
import unittest
from pathlib import Path
from unittest import mock

from regrasp_drake import numerics

_AVX2 = {"avx2", "fma"} <= numerics._cpu_flags()
_PROBE = ("import regrasp_drake, json; from regrasp_drake import numerics; "
          "print(json.dumps(numerics.status()))")


def _status_in_a_fresh_process(**env) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in (
        "NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES",
        "OPENBLAS_CORETYPE")}
    out = subprocess.run([sys.executable, "-c", _PROBE], env=clean | env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


@unittest.skipUnless(_AVX2, "not an x86-64 CPU with AVX2 and FMA")
class PinTest(unittest.TestCase):
    def test_a_fresh_process_runs_the_avx2_kernels(self):
        status = _status_in_a_fresh_process()
        self.assertFalse(status["numpy_avx512_kernels"])
        self.assertEqual(status["openblas_coretype"], "Haswell")

    def test_the_users_choice_is_kept(self):
        status = _status_in_a_fresh_process(OPENBLAS_CORETYPE="Sandybridge")
        self.assertEqual(status["openblas_coretype"], "Sandybridge")
        # NumPy refuses both variables at once: with the user's
        # NPY_ENABLE_CPU_FEATURES the pin sets no NPY_DISABLE_CPU_FEATURES.
        status = _status_in_a_fresh_process(NPY_ENABLE_CPU_FEATURES="X86_V3")
        self.assertFalse(status["numpy_avx512_kernels"])

    def test_the_test_process_is_pinned(self):
        # tests/__init__.py imports the package before any NumPy import.
        self.assertFalse(numerics.status()["numpy_avx512_kernels"])

    def test_too_late_once_numpy_is_imported(self):
        with mock.patch.dict(os.environ, clear=True), \
                self.assertWarnsRegex(RuntimeWarning,
                                      "imported after NumPy"):
            numerics.pin()  # NumPy is loaded in this process: no effect.
            self.assertNotIn("OPENBLAS_CORETYPE", os.environ)
            self.assertNotIn("NPY_DISABLE_CPU_FEATURES", os.environ)

    def test_numpy_first_is_said_where_it_was_done(self):
        clean = {k: v for k, v in os.environ.items() if k not in (
            "NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES",
            "OPENBLAS_CORETYPE")}
        late = "import numpy\nimport regrasp_drake\n"
        out = subprocess.run([sys.executable, "-c", late], env=clean,
                             capture_output=True, text=True, check=True)
        self.assertIn("<string>:2: RuntimeWarning: regrasp_drake was "
                      "imported after NumPy", out.stderr)
        # Set before NumPy (by the user, or a pinned parent): nothing said.
        out = subprocess.run([sys.executable, "-c", late], env=clean | {
            "NPY_DISABLE_CPU_FEATURES": numerics.NUMPY_DISABLED,
            "OPENBLAS_CORETYPE": "Haswell"},
            capture_output=True, text=True, check=True)
        self.assertEqual(out.stderr, "")


def _first_import(path: Path) -> str | None:
    """The root module of the first module-level import in the script at
    `path` that is neither of the standard library nor a script beside it
    (those are checked themselves), or None."""
    siblings = {p.stem for p in path.parent.glob("*.py")}
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            roots = [a.name.split(".")[0] for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            roots = [node.module.split(".")[0]]
        else:
            continue
        for root in roots:
            if root not in sys.stdlib_module_names and root not in siblings:
                return root
    return None


class ScriptsTest(unittest.TestCase):
    """The pin cannot be applied from outside a process that imports NumPy
    before the package (NumPy reads the variables once, at import; only a
    .pth file of the environment's site-packages would run earlier, and
    setuptools installs none from pyproject.toml): so every script imports
    the package, or a module of it, before anything else that is not of
    the standard library."""

    def test_every_script_imports_the_package_before_numpy(self):
        root = Path(__file__).parents[1]
        scripts = sorted(p for d in ("benchmarks", "studies", "examples")
                         for p in (root / d).rglob("*.py"))
        self.assertGreater(len(scripts), 15)
        for path in scripts:
            with self.subTest(script=str(path.relative_to(root))):
                self.assertIn(_first_import(path), (None, "regrasp_drake"))


if __name__ == "__main__":
    unittest.main()
