"""studies/throws_summary/throws_summary.py: reading table1's results,
refusing bad ones."""

import json
import tempfile
import unittest
from pathlib import Path

from tests.refusals import load_script

summary = load_script("studies/throws_summary/throws_summary.py")


def _row(name, throws, caught=True, trials=None):
    row = {"object": name, "throws": throws, "caught": caught,
           "stopped": "caught" if caught else "max_throws"}
    if trials is not None:
        row["paper"] = {"trials": trials, "density": 200}
    return row


class ThrowsSummaryTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def _write(self, name, rows):
        (self.dir / name).write_text(json.dumps(rows))

    def test_rows_tagged_by_file_and_missing_files_listed(self):
        self._write("table1.json", [_row("table1-row4", 61, trials=2)])
        self._write("table1_ar_prior.json", [_row("table1-row4", 9)])
        rows, missing = summary.collect(self.dir)
        self.assertEqual(
            [(r["mode"], r["search"], r["throws"], r["paper_throws"])
             for r in rows],
            [("watch first", "wavefront", 61, 2),
             ("at release", "map-prior", 9, None)])
        # 2 sets x 3 modes x 2 searches, 2 of them present.
        self.assertEqual(len(missing), 10)
        self.assertIn("holdout_ft.json", missing)
        self.assertNotIn("table1.json", missing)

    def test_main_writes_the_picture_and_the_table(self):
        self._write("holdout_ft.json", [_row("holdout-x", 8, caught=False)])
        out = self.dir / "summary"
        self.assertEqual(summary.main(["--results", str(self.dir),
                                       "--out", str(out)]), 0)
        self.assertGreater(out.with_suffix(".png").stat().st_size, 10_000)
        table = json.loads(out.with_suffix(".json").read_text())
        self.assertEqual(table["rows"][0]["throws"], 8)
        self.assertFalse(table["rows"][0]["caught"])

    def test_malformed_results_refused_naming_file_and_field(self):
        for content, words in (
                ("{not json", ["not a readable JSON file"]),
                (json.dumps({"rows": []}), ["expected a list"]),
                (json.dumps([_row("x", "two")]), ["row 0", "'throws'", "'two'"]),
                (json.dumps([{"throws": 2}]), ["'object'"])):
            with self.subTest(content=content):
                (self.dir / "table1.json").write_text(content)
                with self.assertRaises(SystemExit) as e:
                    summary.collect(self.dir)
                message = str(e.exception.code)
                self.assertEqual(len(message.splitlines()), 1)
                self.assertIn("table1.json", message)
                for word in words:
                    self.assertIn(word, message)

    def test_no_results_at_all_refused(self):
        with self.assertRaises(SystemExit) as e:
            summary.main(["--results", str(self.dir),
                          "--out", str(self.dir / "s")])
        self.assertIn("no results files", str(e.exception.code))


if __name__ == "__main__":
    unittest.main()
