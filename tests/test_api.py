"""regrasp_drake/api.py, as a user calls it: a run's verdict, its cost in
throws, errors in the caller's words, and no state of the process changed."""

import os
import tempfile
import unittest
from pathlib import Path
from unittest import mock

import torch

import regrasp_drake as rd
from regrasp_drake import api
from regrasp_drake.errors import InputError


class _Stop(Exception):
    """Raised in place of the learning phase, once its arguments are seen."""


class OneThrowRunTest(unittest.TestCase):
    def test_one_throw_says_its_verdict_and_restores_torch(self):
        before = torch.get_num_threads()
        torch.set_num_threads(2)
        try:
            run = rd.regrasp(rd.load_object("table1-row2"), rd.Target("keep"),
                             watch=False, max_throws=1,
                             scenario=rd.load_scenario("Fast"), library=None,
                             replay=False, progress=None)
            self.assertEqual(torch.get_num_threads(), 2)
        finally:
            torch.set_num_threads(before)
        self.assertEqual(run.throws, 1)
        # Held keep, but more than 20° off the palm's axis: a miss, and
        # the line says so first.
        self.assertFalse(run.success)
        self.assertTrue(run.episode.caught)
        self.assertEqual(run.miss_reason, "tilted")
        self.assertRegex(run.regrasp_line(),
                         r"^keep, \+0 mm: missed, tilted \d+° > 20° "
                         r"\(held keep, [+-]\d+ mm, tilt \d+°\)$")


class ErrorsTest(unittest.TestCase):
    """Each names the argument the caller wrote, the value and what was
    expected, in one line."""

    @classmethod
    def setUpClass(cls):
        cls.obj = rd.load_object("table1-row2")

    def assertRefused(self, error, message, call, *args, **kwargs):
        with self.assertRaises(error) as refused:
            call(*args, **kwargs)
        self.assertEqual(str(refused.exception), message)

    def test_a_target_is_checked_when_made(self):
        self.assertRefused(
            InputError, "Target offset_mm: got 500, expected a number in "
            "[-100, +100] mm (the palm centre along the object's axis from "
            "its centre of mass)", rd.Target, "flip", offset_mm=500)
        self.assertRefused(
            InputError, "Target kind: got 'spin', expected one of keep, "
            "flip, turn, any", rd.Target, "spin")
        self.assertRefused(
            InputError, "target: got 'spin', expected a Target or one of its "
            "kinds (keep, flip, turn, any)", rd.regrasp, self.obj, "spin")

    def test_a_scenario_name_is_the_arguments(self):
        with self.assertRaises(InputError) as refused:
            rd.load_scenario("fast")
        self.assertTrue(str(refused.exception).startswith(
            "name: got 'fast', expected one of ['Default', 'Fast'"),
            str(refused.exception))

    def test_an_unknown_keyword_names_the_function_called(self):
        self.assertRefused(
            TypeError, "regrasp() got an unexpected keyword argument "
            "'max_throw'. Did you mean 'max_throws'?",
            rd.regrasp, self.obj, "keep", max_throw=1)

    def test_throws_too_few_for_a_watch(self):
        self.assertRefused(
            InputError, "max_throws: got 1, expected an integer >= 2 (the "
            "watching throw and one catch; watch=False catches on throw 1)",
            rd.regrasp, self.obj, "keep", max_throws=1)
        self.assertRefused(
            InputError, "at_release: got True with watch=True, expected "
            "watch=False (a catch planned at each release makes no watching "
            "throw)", rd.learn, self.obj, at_release=True)


class NoSideEffectsTest(unittest.TestCase):
    """What a call may leave behind, seen where the learning phase starts
    (mocked: no simulation)."""

    def learn_arguments(self, **kwargs) -> dict:
        seen = {}

        def learning_phase(scenario, obj, model, **options):
            seen.update(options, threads=torch.get_num_threads())
            raise _Stop

        with mock.patch.object(api, "learning_phase", learning_phase), \
                self.assertRaises(_Stop):
            rd.learn(rd.load_object("table1-row2"), progress=None,
                     replay=False, **kwargs)
        return seen

    def test_the_library_goes_to_the_working_directorys_out(self):
        before = torch.get_num_threads()
        with tempfile.TemporaryDirectory() as d:
            cwd = os.getcwd()
            os.chdir(d)
            try:
                seen = self.learn_arguments()
            finally:
                os.chdir(cwd)
            self.assertEqual(seen["library_path"],
                             Path("out") / "regrasp_library.yaml")
            self.assertTrue((Path(d) / "out").is_dir())
        # One thread while the network runs, the caller's count after.
        self.assertEqual(seen["threads"], 1)
        self.assertEqual(torch.get_num_threads(), before)

    def test_first_throw_is_a_deprecated_watch_false(self):
        with self.assertWarnsRegex(DeprecationWarning, "watch=False"):
            seen = self.learn_arguments(first_throw=True, library=None)
        self.assertIsNotNone(seen["flight_predictor"])
        self.assertIsNone(self.learn_arguments(library=None)
                          ["flight_predictor"])


if __name__ == "__main__":
    unittest.main()
