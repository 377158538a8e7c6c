"""The regrasp library file: round trip, and malformed files refused with the
field named."""

import dataclasses as dc
import tempfile
import unittest
from pathlib import Path

import numpy as np
import yaml
from pydrake.math import RigidTransform, RollPitchYaw

from regrasp_drake.errors import InputError
from regrasp_drake.learning.library import (
    LearnedEntry,
    load_library,
    lookup,
    save_library,
    store,
)
from regrasp_drake.station.scenario import load_scenario, scenario_digest


def _entry(**changes) -> LearnedEntry:
    X_WG = RigidTransform(RollPitchYaw(0.0, 0.0, -1.234), [0.88, -0.115, 0.743])
    entry = LearnedEntry(
        object_source="catalogue",
        object_features={"h_cm": -0.01, "r_cm": 0.0, "d_obj": 200.0,
                         "v_conv": 0},
        scenario="defaults", scenario_digest=scenario_digest(load_scenario()),
        code_version="0.1.0",
        catch_point={"t_s": 1.312, "p_WO": [0.88, -0.115, 0.775],
                     "axis_W": [0.939, 0.329, -0.105], "v_catch": -3.516,
                     "tilt": 0.105},
        p_WG=X_WG.translation().tolist(),
        R_WG=X_WG.rotation().matrix().tolist(),
        q_grasp=[0.227, -0.26, -0.853, -1.522, -1.472, 4.252], side="paper",
        h_catch=0.2, h_down=-0.05, cell=[4, 9], throws=2, mode="watch",
        search="wavefront")
    return dc.replace(entry, **changes)


class TestLibrary(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.path = Path(self.tmp.name) / "library.yaml"

    def tearDown(self):
        self.tmp.cleanup()

    def _write_entry(self, **changes):
        """Writes a library with one entry, some of its fields changed (None
        deletes the field)."""
        raw = _entry().as_dict()
        for key, value in changes.items():
            if value is None:
                del raw[key]
            else:
                raw[key] = value
        self.path.write_text(yaml.safe_dump(
            {"format": "regrasp_drake.library", "version": 1,
             "objects": {"obj": raw}}))

    def _refused(self, *fields):
        with self.assertRaises(InputError) as e:
            load_library(self.path)
        message = str(e.exception)
        self.assertEqual(len(message.splitlines()), 1)
        self.assertIn(str(self.path), message)
        for field in fields:
            self.assertIn(field, message)

    def test_round_trip_is_exact(self):
        entries = {"b-object": _entry(), "a-object": _entry(h_catch=0.08,
                                                            cell=[1, 13])}
        save_library(self.path, entries)
        loaded = load_library(self.path)
        self.assertEqual(loaded, entries)
        # The grasp pose comes back bit for bit: apply repeats the catch.
        np.testing.assert_array_equal(
            loaded["b-object"].X_WG.GetAsMatrix4(),
            _entry().X_WG.GetAsMatrix4())

    def test_store_adds_and_replaces(self):
        store(self.path, "x", _entry())
        store(self.path, "y", _entry(throws=7))
        store(self.path, "x", _entry(h_down=-0.1))
        loaded = load_library(self.path)
        self.assertEqual(sorted(loaded), ["x", "y"])
        self.assertEqual(loaded["x"].h_down, -0.1)
        self.assertEqual(loaded["y"].throws, 7)

    def test_missing_file_is_empty_and_lookup_says_learn_first(self):
        self.assertEqual(load_library(self.path), {})
        with self.assertRaises(InputError) as e:
            lookup(self.path, "table1-row2")
        self.assertIn("table1-row2", str(e.exception))
        self.assertIn("regrasp-drake learn", str(e.exception))
        store(self.path, "other", _entry())
        with self.assertRaises(InputError) as e:
            lookup(self.path, "table1-row2")
        self.assertIn("no entry", str(e.exception))

    def test_not_yaml_refused(self):
        self.path.write_text("objects: [unclosed\n")
        self._refused("YAML")

    def test_wrong_format_refused(self):
        self.path.write_text("format: something-else\nversion: 1\n")
        self._refused("format")
        self.path.write_text("format: regrasp_drake.library\nversion: 9\n")
        self._refused("version", "9")

    def test_missing_field_refused(self):
        self._write_entry(h_catch=None)
        self._refused("objects.obj.h_catch", "missing")

    def test_unknown_field_refused(self):
        self._write_entry(colour="red")
        self._refused("colour")

    def test_out_of_range_parameters_refused(self):
        for field, value in (("h_catch", 0.5), ("h_down", 0.02),
                             ("h_catch", "high"), ("cell", [10, 0]),
                             ("throws", 0), ("side", "left")):
            with self.subTest(field=field, value=value):
                self._write_entry(**{field: value})
                self._refused(f"objects.obj.{field}", str(value))

    def test_mode_and_search_recorded_or_absent(self):
        """An entry says how it was learned; an older entry without those
        fields loads with None (not recorded); other values are refused."""
        store(self.path, "new", _entry(mode="at-release", search="map-prior"))
        loaded = load_library(self.path)["new"]
        self.assertEqual((loaded.mode, loaded.search), ("at-release", "map-prior"))
        self._write_entry(mode=None, search=None)
        old = load_library(self.path)["obj"]
        self.assertEqual((old.mode, old.search), (None, None))
        self.assertEqual(old.h_catch, 0.2)
        for field, value in (("mode", "guess"), ("search", "random")):
            with self.subTest(field=field):
                self._write_entry(**{field: value})
                self._refused(f"objects.obj.{field}", value)

    def test_caught_on_the_first_throw_stored(self):
        """First-throw mode: an entry learned in 1 throw loads."""
        store(self.path, "first", _entry(throws=1))
        self.assertEqual(load_library(self.path)["first"].throws, 1)

    def test_malformed_pose_refused(self):
        self._write_entry(R_WG=[[1, 0, 0], [0, 1, 0], [0, 0, 2]])
        self._refused("R_WG", "rotation matrix")
        self._write_entry(p_WG=[0.8, 0.1])
        self._refused("p_WG", "3 numbers")
        self._write_entry(q_grasp=[0.0] * 5 + [float("nan")])
        self._refused("q_grasp[5]")

    def test_malformed_catch_point_refused(self):
        point = _entry().catch_point | {"v_catch": None}
        self._write_entry(catch_point=point)
        self._refused("catch_point.v_catch")


if __name__ == "__main__":
    unittest.main()
