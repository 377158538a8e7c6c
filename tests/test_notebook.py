"""examples/regrasp.ipynb, executed on a real Jupyter kernel (nbclient), as
a user runs it: its printed grasps and the files it writes."""

import shutil
import tempfile
import unittest
from pathlib import Path

import nbclient
import nbformat

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOK = ROOT / "examples" / "regrasp.ipynb"


def _text(cell) -> str:
    return "".join(o.get("text", "") for o in cell.get("outputs", ())
                   if o.get("output_type") == "stream")


class RegraspNotebookTest(unittest.TestCase):
    def test_runs_and_regrasps_on_the_first_throw(self):
        notebook = nbformat.read(NOTEBOOK, as_version=4)
        # Kept without outputs: what is committed is what a user runs.
        self.assertFalse(any(c.get("outputs") for c in notebook.cells
                             if c.cell_type == "code"))
        with tempfile.TemporaryDirectory() as d:
            # Beside the object file it loads, writing into its own out/.
            shutil.copy(ROOT / "examples" / "my_object.yaml", d)
            nbclient.NotebookClient(
                notebook, timeout=300, kernel_name="python3",
                resources={"metadata": {"path": d}}).execute()
            out = Path(d) / "out"
            for name, least in (("table1-row2.html", 100_000),
                                ("table1-row2.png", 10_000),
                                ("spatula.html", 100_000),
                                ("regrasp_library.yaml", 100)):
                self.assertGreater((out / name).stat().st_size, least, name)
        text = "\n".join(_text(c) for c in notebook.cells
                         if c.cell_type == "code")
        self.assertIn("http", text)  # the live Meshcat's address
        self.assertIn("spatula-d250 {'h_cm'", text)
        # The catalogue object flipped, the own one kept, each on throw 1.
        # Each run's last line: the verdict first.
        self.assertIn("flip, +0 mm: in the target grasp (held flip", text)
        self.assertIn("keep, +0 mm: in the target grasp (held keep", text)
        self.assertEqual(text.count("success: True  throws: 1"), 2, text)
        self.assertEqual(text.count("achieved grasp: {"), 2, text)
        images = [o for c in notebook.cells for o in c.get("outputs", ())
                  if "image/png" in o.get("data", {})]
        self.assertEqual(len(images), 1)


if __name__ == "__main__":
    unittest.main()
