"""The scenario loader refuses what it cannot use, naming the field."""

import hashlib
import re
import tempfile
import unittest
from pathlib import Path

import numpy as np
import torch
from pydrake.math import RigidTransform
from pydrake.multibody.plant import DiscreteContactApproximation

from regrasp_drake.episode.diagram import build_episode_diagram, initialize
from regrasp_drake.errors import InputError
from regrasp_drake.input_files import parse_yaml
from regrasp_drake.parameter_space import cell_parameters, nearest_cell
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.mlp_system import CatchMlp
from regrasp_drake.station.scenario import (
    Scenario,
    load_scenario,
    scenario_digest,
    scenario_yaml,
)
from regrasp_drake.station.scenario_checks import check_catch_parameters
from regrasp_drake.world.objects import load_catalogue

TEST_SCENARIOS = Path(__file__).parent / "scenarios.yaml"


class TestScenario(unittest.TestCase):
    def _load(self, text):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "s.yaml"
            path.write_text(text)
            return load_scenario(path)

    def test_defaults_valid(self):
        self.assertIsInstance(load_scenario(), Scenario)

    def test_partial_file_keeps_defaults(self):
        s = self._load("plant_config:\n  time_step: 0.0005\n"
                       "contact:\n  friction_coefficient: 0.5\n")
        self.assertEqual(s.plant_config.time_step, 0.0005)
        self.assertEqual(s.plant_config.discrete_contact_approximation,
                         Scenario().plant_config.discrete_contact_approximation)
        self.assertEqual(s.contact.friction_coefficient, 0.5)
        self.assertEqual(s.sensors.levels, Scenario().sensors.levels)

    def test_unknown_key_refused(self):
        with self.assertRaisesRegex(InputError, "time_stpe_s"):
            self._load("time_stpe_s: 0.001\n")

    def test_out_of_range_refused_with_field(self):
        cases = {
            "plant_config:\n  time_step: -1\n": "plant_config.time_step",
            "plant_config:\n  discrete_contact_approximation: tamsi\n":
                "plant_config.discrete_contact_approximation",
            "plant_config:\n  contact_model: hydroelastic\n":
                "plant_config.contact_model",
            "sensors:\n  period_s: 0.00455\n": "sensors.period_s",
            "sensors:\n  approach_range_m: 0.2\n": "sensors.approach_range_m",
            "catch:\n  h_catch_m: 0.9\n": "catch.h_catch_m",
            "catch:\n  palm_across_com_fraction: 1.5\n":
                "catch.palm_across_com_fraction",
            "catch:\n  palm_toward_landing_end_m: -0.01\n":
                "catch.palm_toward_landing_end_m",
            "catch:\n  palm_toward_fingers_m: 0.05\n":
                "catch.palm_toward_fingers_m",
            "arm:\n  kp: [1, 2]\n": "arm.kp",
            "throw:\n  knot_times_s: [0, 0.2, 0.1]\n  knot_q_rad: "
            "[[0,0,0,0,0,0],[0,0,0,0,0,0],[0,0,0,0,0,0]]\n": "throw.knot_times_s",
        }
        for text, field in cases.items():
            with self.subTest(field=field):
                with self.assertRaises(InputError) as e:
                    self._load(text)
                self.assertIn(field, str(e.exception))
                self.assertEqual(len(str(e.exception).splitlines()), 1)

    def test_directives_without_the_hand_on_the_arm_refused(self):
        from regrasp_drake.world.robot import directives_yaml
        shipped = directives_yaml(None)
        for text, expected in (
                (shipped.replace("parent: puma560::link6", "parent: world"),
                 "the hand welded"),
                (shipped.replace("name: hand", "name: other_hand"),
                 "add_model entries named")):
            with self.subTest(expected=expected):
                with self.assertRaises(InputError) as e:
                    self._load(text)
                self.assertIn("directives: got", str(e.exception))
                self.assertIn(expected, str(e.exception))
                self.assertEqual(len(str(e.exception).splitlines()), 1)

    def test_wrong_type_refused_with_field(self):
        cases = {
            "plant_config:\n  time_step: fast\n":
                ("plant_config.time_step", "a number"),
            "plant_config:\n  time_stpe: 0.001\n":
                ("plant_config.time_stpe", "time_step"),
            "directives: 3\n": ("directives", "a list of mappings"),
            "directives:\n- add_model: {name: 3}\n":
                ("directives[0].add_model.name", "a string"),
            "catch:\n  move_to_grasp_s: soon\n":
                ("catch.move_to_grasp_s", "a number"),
            "catch: 5\n": ("catch", "a mapping"),
            "sensors:\n  levels: [1, 2]\n": ("sensors.levels", "an integer"),
            "throw:\n  noise:\n    seed: 1.5\n":
                ("throw.noise.seed", "an integer"),
            "throw:\n  knot_q_rad: [[0, 0], [0, x]]\n":
                ("throw.knot_q_rad[1][1]", "a number"),
            "arm:\n  kp: 3\n": ("arm.kp", "a list of numbers"),
            "catch:\n  palm_across_com_fractoin: 0\n":
                ("catch.palm_across_com_fractoin", "palm_across_com_fraction"),
            "- a\n": ("the scenario", "a mapping"),
        }
        for text, (field, expected) in cases.items():
            with self.subTest(field=field):
                with self.assertRaises(InputError) as e:
                    self._load(text)
                message = str(e.exception)
                # The file first, then the field.
                self.assertRegex(message, r"^\S+\.yaml: " + re.escape(field)
                                 + ":")
                self.assertIn(expected, message)
                self.assertEqual(len(message.splitlines()), 1)

    def test_not_yaml_refused(self):
        with self.assertRaisesRegex(InputError, "not valid YAML at line 2, column 1"):
            self._load("plant_config: [unclosed\n")

    def test_empty_file_is_the_defaults(self):
        for text in ("", "# nothing changed\n"):
            self.assertEqual(self._load(text), load_scenario())

    def test_missing_file_refused(self):
        with self.assertRaisesRegex(InputError, "--scenario"):
            load_scenario("/nonexistent/scenario.yaml")

    def test_scenario_digest_tracks_every_value(self):
        scenario = load_scenario()
        digest = scenario_digest(scenario)
        self.assertEqual(digest, scenario_digest(load_scenario()))
        scenario.catch.return_s += 0.01
        self.assertNotEqual(digest, scenario_digest(scenario))

    def test_old_names_still_read(self):
        s = self._load("time_step_s: 0.0005\n"
                       "contact:\n  discrete_contact_approximation: sap\n")
        self.assertEqual(s.plant_config.time_step, 0.0005)
        self.assertEqual(s.plant_config.discrete_contact_approximation, "sap")
        self.assertEqual(s.time_step_s, 0.0005)
        with self.assertRaisesRegex(InputError, "^\\S+: time_step_s: the old "
                                    "name of plant_config.time_step"):
            self._load("time_step_s: 0.0005\nplant_config: {time_step: 0.001}\n")

    def test_default_is_the_named_default(self):
        self.assertEqual(load_scenario(), Scenario())
        self.assertEqual(load_scenario(name="Default"), Scenario())
        self.assertEqual(len(Scenario().directives), 4)
        self.assertNotEqual(load_scenario(text="{catch: {return_s: 0.4}}"),
                            Scenario())

    def test_named_scenarios_from_a_file(self):
        text = ("A: {catch: {return_s: 0.4}}\n"
                "B:\n  plant_config: {time_step: 0.0005}\n")
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "named.yaml"
            path.write_text(text)
            self.assertEqual(load_scenario(path, name="A").catch.return_s, 0.4)
            b = load_scenario(path, name="B")
            self.assertEqual(b.plant_config.time_step, 0.0005)
            self.assertEqual(b.catch.return_s, Scenario().catch.return_s)
            with self.assertRaisesRegex(InputError,
                                        r"^--scenario-name: got 'C', .*'A'"):
                load_scenario(path, name="C")

    def test_scenario_text_overrides_one_field(self):
        s = load_scenario(text="{catch: {return_s: 0.4}, "
                               "plant_config: {time_step: 0.0005}}")
        self.assertEqual(s.catch.return_s, 0.4)
        self.assertEqual(s.plant_config.time_step, 0.0005)
        # The other fields of the sections it names keep their values.
        self.assertEqual(s.catch.h_catch_m, Scenario().catch.h_catch_m)
        self.assertEqual(s.plant_config.contact_model, "point")
        for text, field in (("{catch: {return_s: 9}}", "catch.return_s"),
                            ("{catch: {retrun_s: 0.4}}", "catch.retrun_s"),
                            ("{catch: [", "not valid YAML")):
            with self.subTest(text):
                with self.assertRaises(InputError) as e:
                    load_scenario(text=text)
                self.assertIn(field, str(e.exception))
                self.assertIn("--scenario-text", str(e.exception))
                self.assertEqual(len(str(e.exception).splitlines()), 1)

    def test_parameter_space(self):
        check_catch_parameters(0.40, -0.14)
        check_catch_parameters(0.0, 0.0)
        for h_catch, h_down, field in ((0.41, -0.05, "h_catch_m"),
                                       (0.2, 0.01, "h_down_m"),
                                       (0.2, -0.15, "h_down_m"),
                                       (float("nan"), -0.05, "h_catch_m")):
            with self.assertRaisesRegex(InputError, field):
                check_catch_parameters(h_catch, h_down)


def _leaves(tree, prefix=""):
    """{dotted field: value} of a parsed scenario, lists as one value."""
    if isinstance(tree, dict) and not prefix.endswith("directives"):
        return {k: v for key, item in tree.items()
                for k, v in _leaves(item, f"{prefix}.{key}" if prefix
                                    else key).items()}
    return {prefix: tree}


class OneOfEverythingTest(unittest.TestCase):
    """A scenario with every field away from its default and a directive
    list of its own (tests/scenarios.yaml) loads, and the station builds
    and steps from it."""

    @classmethod
    def setUpClass(cls):
        cls.scenario = load_scenario(TEST_SCENARIOS, name="OneOfEverything")
        cls.obj = load_catalogue()["table1-row2"]
        cls.ik = ArmIk(cls.scenario.directives)

    def test_every_field_away_from_its_default(self):
        ours = _leaves(parse_yaml(scenario_yaml(self.scenario), tags=True))
        default = _leaves(parse_yaml(scenario_yaml(Scenario()), tags=True))
        # An optional field is not written at its default (None).
        self.assertEqual(ours.keys() - default.keys(),
                         {"catch.preshape_distal_closure",
                          "catch.palm_max_tilt_rad",
                          "catch.lower_ends_moving"})
        self.assertEqual(default.keys() - ours.keys(), set())
        self.assertEqual([k for k in default if ours[k] == default[k]],
                         ["plant_config.contact_model",
                          "simulator_config.start_time"])

    def test_station_builds_and_steps(self):
        episode = build_episode_diagram(self.scenario, self.obj, ik=self.ik,
                                        X_WG=None)
        station = episode.station
        plant = station.plant
        self.assertEqual(plant.time_step(), 0.0005)
        self.assertEqual(plant.get_discrete_contact_approximation(),
                         DiscreteContactApproximation.kSap)
        self.assertTrue(plant.HasFrameNamed("camera_mount"))
        simulator = initialize(episode, self.scenario)
        simulator.AdvanceTo(0.02)
        # The object settles in the palm: it has moved by under a centimetre.
        X_WO = plant.EvalBodyPoseInWorld(
            plant.GetMyContextFromRoot(simulator.get_context()),
            station.object_body)
        self.assertLess(np.linalg.norm(
            X_WO.translation() - episode.X_WO_initial.translation()), 0.01)

    def test_station_builds_with_the_network(self):
        episode = build_episode_diagram(
            self.scenario, self.obj, ik=self.ik,
            X_WG=RigidTransform([0.8, 0.0, 0.7]),
            mlp_features=[-3.8, 0.0, 0.0, 0.05, 0.0])
        self.assertTrue(episode.diagram.HasSubsystemNamed("mlp"))

    def test_the_callers_network_predicts_the_cell(self):
        # A network that answers (0.11, -0.03) m whatever the features: the
        # episode's MLP system gives its nearest cell, (0.12, -0.03).
        model = CatchMlp()
        with torch.no_grad():
            model.output.weight.zero_()
            model.output.bias.zero_()
            model.output_mean.copy_(torch.tensor([0.11, -0.03], dtype=torch.float64))
        episode = build_episode_diagram(
            self.scenario, self.obj, ik=self.ik,
            X_WG=RigidTransform([0.8, 0.0, 0.7]),
            mlp_features=[-3.8, 0.0, 0.0, 0.05, 0.0], model=model)
        mlp = episode.controller.parameters
        context = episode.diagram.CreateDefaultContext()
        mlp.ExecuteInitializationEvents(mlp.GetMyMutableContextFromRoot(context))
        np.testing.assert_array_equal(
            episode.diagram.GetOutputPort("catch_parameters").Eval(context),
            cell_parameters(nearest_cell(0.11, -0.03)))
        self.assertEqual(cell_parameters(nearest_cell(0.11, -0.03)),
                         (0.12, -0.03))


if __name__ == "__main__":
    unittest.main()


class DigestTest(unittest.TestCase):
    """scenario_digest is kept by the scenario's repr: a change anywhere,
    down to Drake's configs and the directives' poses, is a new digest,
    the same as the YAML's."""

    def test_every_nested_value_changes_the_digest(self):
        base = load_scenario()
        digests = {scenario_digest(base)}
        self.assertEqual(scenario_digest(load_scenario()),
                         scenario_digest(base))
        for text in (
                "{plant_config: {stiction_tolerance: 0.0002}}",
                "{simulator_config: {accuracy: 0.001}}",
                "{catch: {preshape_distal_closure: 0.4}}",
                "{catch: {closing_order: thumb_first}}",
                "{throw: {toss: {spin_rad_per_s: 5.4}}}",
                "{regrasp: {target: keep}}"):
            digests.add(scenario_digest(load_scenario(text=text)))
        moved = load_scenario()
        X_PC = moved.directives[3].add_weld.X_PC
        X_PC.translation = X_PC.translation + [0.0, 0.0, 1e-9]
        digests.add(scenario_digest(moved))
        self.assertEqual(len(digests), 8)
        # What is kept is the YAML's digest (with no target, without the
        # landing's fields, which only a target reads, and without the
        # fingers' closing order at its default).
        text = scenario_yaml(moved)
        self.assertEqual(scenario_digest(moved), hashlib.sha256(re.sub(
            r"(?m)^  (follow_\w+|closing_order): .*\n", "", re.sub(
                r"(?m)^(landing_\w+|target_catch_time_step_s): .*\n", "",
                text[:text.rindex("regrasp:\n")])
        ).encode()).hexdigest()[:16])
        landing = "{landing_time_step_s: 0.000125}"
        self.assertEqual(scenario_digest(load_scenario(text=landing)),
                         scenario_digest(base))
        flip = load_scenario(text="{regrasp: {target: flip}}")
        self.assertNotEqual(scenario_digest(load_scenario(
            text="{regrasp: {target: flip}, landing_time_step_s: 0.0000625}")),
            scenario_digest(flip))
