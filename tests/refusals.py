"""Shared by the tests of the benchmark and study scripts: loading a script
as a module, and the bad-input assertion."""

import contextlib
import importlib.util
import io
import sys
from pathlib import Path


def load_script(path: str):
    """The script at `path` (from the repository's top, e.g.
    "benchmarks/noise_curve.py"), imported as the module named by
    its file name (registered in sys.modules, so that its functions pickle
    for a process pool)."""
    name = Path(path).stem
    path = Path(__file__).parents[1] / path
    # As when it runs (`python benchmarks/x.py`): the scripts beside it
    # import as modules.
    if str(path.parent) not in sys.path:
        sys.path.append(str(path.parent))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


class RefusalAssertions:
    """Mixin for a unittest.TestCase whose `main` attribute is a script's
    main(argv) function (set as a staticmethod)."""

    def assertRefused(self, argv, *fragments):
        """main(argv) exits with 2, its error naming every fragment."""
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = self.main(list(argv))
        self.assertEqual(code, 2, argv)
        for fragment in fragments:
            self.assertIn(fragment, err.getvalue())
