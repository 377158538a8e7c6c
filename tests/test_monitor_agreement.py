"""benchmarks/monitor_agreement.py: counts each kind of cell, refuses what
is not a data set."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

from tests.refusals import load_script

monitor_agreement = load_script("benchmarks/monitor_agreement.py")


class AgreementTest(unittest.TestCase):
    def test_counts_each_kind(self):
        rows = [{"cell": [0, 0], "outcome": "caught", "held_by_contact": True},
                {"cell": [0, 1], "outcome": "dropped",
                 "held_by_contact": True, "drop_reason": "not_held"},
                {"cell": [0, 2], "outcome": "caught",
                 "held_by_contact": False},
                {"cell": [0, 3], "outcome": "dropped",
                 "held_by_contact": False},
                {"cell": [0, 4], "outcome": "failed",
                 "held_by_contact": None}]
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "cells").mkdir()
            (Path(tmp) / "cells" / "obj.jsonl").write_text(
                "".join(json.dumps(r) + "\n" for r in rows))
            out = Path(tmp) / "report.json"
            with contextlib.redirect_stdout(io.StringIO()) as printed:
                code = monitor_agreement.main([tmp, "--json", str(out)])
            report = json.loads(out.read_text())
        self.assertEqual(code, 0)
        self.assertEqual((report["cells"], report["agree"],
                          report["held_not_caught"],
                          report["caught_not_held"],
                          report["no_contact_verdict"]), (5, 2, 1, 1, 1))
        self.assertEqual([d["cell"] for d in
                          report["disagreeing_by_object"]["obj"]],
                         [[0, 1], [0, 2]])
        self.assertIn("agree in 2 of 5 cells", printed.getvalue())

    def test_not_a_data_set_refused(self):
        with tempfile.TemporaryDirectory() as tmp:
            for text, expected in ((None, "no cell rows"),
                                   ("{\"outcome\": 1}\n", "obj.jsonl:1")):
                if text is not None:
                    (Path(tmp) / "cells").mkdir(exist_ok=True)
                    (Path(tmp) / "cells" / "obj.jsonl").write_text(text)
                with contextlib.redirect_stderr(io.StringIO()) as err:
                    code = monitor_agreement.main(
                        [tmp, "--json", str(Path(tmp) / "r.json")])
                self.assertEqual(code, 2)
                self.assertIn(expected, err.getvalue())


if __name__ == "__main__":
    unittest.main()
