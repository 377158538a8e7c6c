"""The parameter space: 150 cells inside the paper's ranges."""

import json
import tempfile
import unittest
from pathlib import Path

from regrasp_drake.errors import InputError
from regrasp_drake.grid import (
    append_rows,
    check_resume,
    disagreements,
    ending,
    ending_counts,
    format_map,
    plan_path,
    read_rows,
)
from regrasp_drake.parameter_space import ENDINGS
from regrasp_drake.plots import plot_success_map


def _square(k):
    return {"k": k, "square": k * k}


class AppendRowsTest(unittest.TestCase):
    """Resumable JSON lines (open_rows, which append_rows and run_map use):
    rows appended as they finish, in the tasks' order; after a line cut by a
    kill, the cut line is gone and the next rows are whole lines, read
    back."""

    def test_rows_written_and_resumed(self):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "rows.jsonl"
            key = lambda row: row["k"]  # noqa: E731
            done = {}
            append_rows(_square, [3, 1, 2], path, done, key, workers=2,
                        label="test", unit="tasks")
            lines = path.read_text().splitlines()
            self.assertEqual(len(lines), 3)
            self.assertIn('"k": 3', lines[0])
            with path.open("a") as f:
                f.write('{"k": 4, "squ')  # a line cut by a kill
            resumed = read_rows(path, key=key)
            self.assertEqual(resumed, done)
            self.assertEqual(resumed[2], {"k": 2, "square": 4})
            todo = [k for k in range(1, 6) if k not in resumed]
            self.assertEqual(todo, [4, 5])
            append_rows(_square, todo, path, resumed, key, workers=2,
                        label="test", unit="tasks")
            self.assertEqual(read_rows(path, key=key),
                             {k: _square(k) for k in range(1, 6)})
            # Every line a whole row: a plain JSON-lines reader reads it.
            rows = [json.loads(line) for line in path.read_text().splitlines()]
            self.assertEqual(sorted(r["k"] for r in rows), [1, 2, 3, 4, 5])


class TestGrid(unittest.TestCase):
    def test_map_marks_outcomes(self):
        rows = {(0, 0): {"outcome": "caught"}, (0, 1): {"outcome": "dropped"}}
        text = format_map(rows)
        self.assertIn("1/2 cells catch", text)
        first_row = text.splitlines()[1].split()
        self.assertEqual(first_row[1:4], ["✓", "✗", "?"])
        # A row without a drop reason (an older file) is counted as other.
        self.assertIn("1 a timeout, or a row written without", text)

    def test_endings_from_reason_and_contacts(self):
        def row(outcome, reason=None, touching=()):
            return {"outcome": outcome, "drop_reason": reason,
                    "touching": list(touching)}
        cases = [
            (row("caught", touching=["palm", "index_distal"]), "caught"),
            (row("dropped", "not_held", ["palm", "thumb_proximal"]),
             "in_fingers"),
            (row("dropped", "not_held", ["link4", "palm"]), "on_arm"),
            (row("dropped", "not_held", ["palm"]), "loose"),
            (row("dropped", "below_palm"), "below_palm"),
            (row("dropped", "near_ground", ["world"]), "near_ground"),
            (row("failed"), "failed"),
            (row("timeout"), "other"),
        ]
        for r, expected in cases:
            self.assertEqual(ending(r), expected, r)
        counts = ending_counts(r for r, _ in cases)
        self.assertEqual(set(counts), set(ENDINGS))
        self.assertEqual(sum(counts.values()), len(cases))
        text = format_map({(0, j): r for j, (r, _) in enumerate(cases)})
        self.assertIn("1 not held: at rest against the arm", text)
        self.assertNotIn("disagree", text)  # no contact verdicts in the rows

    def test_disagreements_with_the_contacts(self):
        rows = {(0, 0): {"outcome": "caught", "held_by_contact": True},
                (0, 1): {"outcome": "dropped", "drop_reason": "not_held",
                         "held_by_contact": True},
                (0, 2): {"outcome": "caught", "held_by_contact": False},
                (0, 3): {"outcome": "dropped", "drop_reason": "below_palm",
                         "held_by_contact": False},
                (0, 4): {"outcome": "failed", "held_by_contact": None}}
        self.assertEqual(sorted(disagreements(rows)), [(0, 1), (0, 2)])
        self.assertIn("2 cell(s) where the contacts disagree with the grasp "
                      "monitor (held by contact: [0, 1] True, [0, 2] False)",
                      format_map(rows))


if __name__ == "__main__":
    unittest.main()


class ResumeCheckTest(unittest.TestCase):
    """A map's rows are resumed only when they come from the same object,
    catch point, scenario and plan (`check_resume`): before, a map begun for
    one object was resumed as another's and printed as its map."""

    SOURCE = {"object": "a", "catch_point": 1, "scenario_digest": "x",
              "plan": {"p_WG": [0.8, 0.0, 0.5]}}

    def test_new_map_records_its_source_and_resumes(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "g.jsonl"
            check_resume(out, self.SOURCE)
            self.assertEqual(json.loads(plan_path(out).read_text()),
                             self.SOURCE)
            out.write_text(json.dumps({"cell": [0, 0],
                                       "outcome": "caught"}) + "\n")
            check_resume(out, json.loads(json.dumps(self.SOURCE)))

    def test_other_sources_refused_naming_out(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "g.jsonl"
            check_resume(out, self.SOURCE)
            for key, value in (("object", "b"), ("catch_point", 2),
                               ("scenario_digest", "y"),
                               ("plan", {"p_WG": [0.8, 0.0, 0.49]})):
                with self.subTest(key=key):
                    with self.assertRaises(InputError) as e:
                        check_resume(out, self.SOURCE | {key: value})
                    message = str(e.exception)
                    self.assertTrue(message.startswith("--out: "))
                    self.assertIn(f"computed with another {key}", message)
                    self.assertNotIn("\n", message)

    def test_refusals_name_the_argument_that_named_the_map(self):
        # table1's maps in --maps-dir are checked as grid's --out is.
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "table1-row1.jsonl"
            check_resume(out, self.SOURCE, flag="--maps-dir")
            with self.assertRaises(InputError) as e:
                check_resume(out, self.SOURCE | {"object": "b"},
                             flag="--maps-dir")
            self.assertTrue(str(e.exception).startswith("--maps-dir: "))
            self.assertIn("give another --maps-dir", str(e.exception))

    def test_rows_without_source_or_a_corrupt_source_refused(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "g.jsonl"
            out.write_text(json.dumps({"cell": [0, 0],
                                       "outcome": "caught"}) + "\n")
            with self.assertRaises(InputError) as e:
                check_resume(out, self.SOURCE)
            self.assertIn("holds cells but no g.jsonl.plan.json", str(e.exception))
            self.assertFalse(plan_path(out).exists())
            plan_path(out).write_text("{")
            with self.assertRaises(InputError) as e:
                check_resume(out, self.SOURCE)
            self.assertIn("g.jsonl.plan.json: line 1: not valid JSON",
                          str(e.exception))


class SuccessMapPlotTest(unittest.TestCase):
    """`grid --plot`: a stored map of the data set (table1-row3's at the
    shipped step, which catches and drops) drawn by ending, with its label
    framed."""

    def test_plot_written(self):
        rows = read_rows(Path(__file__).parents[1] / "models" / "results"
                         / "maps" / "table1-row3.jsonl")
        self.assertEqual(len(rows), 150)
        with tempfile.TemporaryDirectory() as d:
            path = plot_success_map(rows, Path(d) / "m.png", title="row 3")
            self.assertEqual(path.read_bytes()[:8], b"\x89PNG\r\n\x1a\n")
            self.assertGreater(path.stat().st_size, 10_000)


class CatchPointPlanTest(unittest.TestCase):
    """`grid --catch-point K` plans as the data set does: table1-row3's second
    catch point is another moment than its first, at least
    CATCH_POINT_SEPARATION_S away; one beyond its flight's is refused."""

    def test_second_catch_point_and_one_too_many(self):
        from regrasp_drake.grid import plan_object
        from regrasp_drake.planning.ik import ArmIk
        from regrasp_drake.station.scenario import load_scenario
        from regrasp_drake.throw_catch import CATCH_POINT_SEPARATION_S
        from regrasp_drake.world.objects import resolve_object
        scenario, ik = load_scenario(name="Fast"), ArmIk()
        obj = resolve_object(name="table1-row3")
        first = plan_object(scenario, obj, ik, catch_point=1)
        second = plan_object(scenario, obj, ik, catch_point=2)
        # the moment a catching throw corrects its palm at (release_correction)
        self.assertEqual((first.moment, second.moment), (1, 2))
        first, second = first.as_dict(), second.as_dict()
        self.assertGreaterEqual(
            abs(second["catch_point"]["t_s"] - first["catch_point"]["t_s"]),
            CATCH_POINT_SEPARATION_S - 1e-4)
        with self.assertRaises(InputError) as e:
            plan_object(scenario, obj, ik, catch_point=9)
        self.assertRegex(str(e.exception),
                         r"^--catch-point: got 9, expected at most \d+: object "
                         r"table1-row3 has \d+ reachable catch point")


class ProgressTest(unittest.TestCase):
    """The progress bar is drawn on a terminal and left out of a log file
    or a pipe (tqdm's disable=None)."""

    def _drawn(self, tty: bool, enabled: bool = True) -> str:
        import contextlib
        import io

        from regrasp_drake.progress import bar

        class Stream(io.StringIO):
            def isatty(self):
                return tty
        stream = Stream()
        with contextlib.redirect_stderr(stream):
            with bar(25, "obj", enabled=enabled) as shown:
                for _ in range(25):
                    shown.update()
        return stream.getvalue()

    def test_drawn_on_a_terminal_only(self):
        self.assertIn("obj: 100%", self._drawn(tty=True))
        self.assertIn("25/25 [", self._drawn(tty=True))
        self.assertEqual(self._drawn(tty=False), "")
        self.assertEqual(self._drawn(tty=True, enabled=False), "")
