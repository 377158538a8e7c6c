"""The station on a continuous plant integrated by CENIC
(simulator_config.integration_scheme: cenic, plant_config.time_step: 0):
the scenario's checks, and the arm and the fingers following their
references through a palm toss."""

import tempfile
import unittest
from pathlib import Path

import numpy as np
from pydrake.systems.framework import EventStatus

from regrasp_drake.episode.diagram import build_episode_diagram, initialize
from regrasp_drake.errors import InputError
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.palm_toss import TossDesign
from regrasp_drake.station.scenario import Scenario, load_scenario
from regrasp_drake.world import robot
from regrasp_drake.world.objects import load_catalogue
from tests.refusals import RefusalAssertions, load_script

CENIC = ("{plant_config: {time_step: 0}, catch_time_step_s: null, "
         "simulator_config: "
         "{integration_scheme: cenic, accuracy: 1e-3}}")


class CenicScenarioTest(unittest.TestCase):
    def test_default_is_the_discrete_plant_and_drakes_integrator(self):
        s = load_scenario()
        self.assertEqual(s.plant_config.time_step, 0.00025)
        self.assertEqual(s.simulator_config.integration_scheme, "runge_kutta3")
        self.assertEqual(s, Scenario())

    def test_cenic_loads(self):
        s = load_scenario(name="Fast", text=CENIC)
        self.assertEqual(s.plant_config.time_step, 0.0)
        self.assertEqual(s.simulator_config.accuracy, 1e-3)

    def test_refusals_name_the_field(self):
        cases = {
            "{simulator_config: {integration_scheme: cenic}}":
                "simulator_config.integration_scheme: got 'cenic'",
            "{plant_config: {time_step: 0}}":
                "simulator_config.integration_scheme: got 'runge_kutta3'",
            "{simulator_config: {integration_scheme: rk99}}":
                "simulator_config.integration_scheme: got 'rk99'",
            "{simulator_config: {accuracy: 0}}": "simulator_config.accuracy",
            "{simulator_config: {start_time: 1}}":
                "simulator_config.start_time",
            "{simulator_config: {acuracy: 1}}": "simulator_config.acuracy",
        }
        for text, field in cases.items():
            with self.subTest(text=text):
                with self.assertRaises(InputError) as e:
                    load_scenario(text=text)
                self.assertIn(field, str(e.exception))
                self.assertEqual(len(str(e.exception).splitlines()), 1)


class CenicTrackingTest(unittest.TestCase):
    """One palm toss of table1-row2 under CENIC (accuracy 1e-3), to after
    the fingers' pre-shape; every integrator step records how far the arm
    and the fingers are from their references and the fingers' torques."""

    @classmethod
    def setUpClass(cls):
        cls.scenario = load_scenario(name="Fast", text=CENIC)
        obj = load_catalogue()["table1-row2"]
        episode = build_episode_diagram(cls.scenario, obj, ik=ArmIk(),
                                        X_WG=None)
        cls.station = episode.station
        simulator = initialize(episode, cls.scenario)
        plant, machine = cls.station.plant, episode.controller.state_machine
        hand_u = plant.get_net_actuation_output_port()
        hand_columns = [plant.get_joint_actuator(i).input_start()
                        for i in plant.GetJointActuatorIndices(
                            cls.station.hand)]
        rows = []

        def record(root):
            pc = plant.GetMyContextFromRoot(root)
            mc = machine.GetMyContextFromRoot(root)
            q_arm = plant.GetPositions(pc, cls.station.arm)
            q_hand = plant.GetPositions(pc, cls.station.hand)
            arm_ref = machine.GetOutputPort("arm_desired_state").Eval(mc)[:6]
            hand_ref = machine.GetOutputPort("hand_desired_state").Eval(mc)
            u = hand_u.Eval(pc)[hand_columns]
            rows.append((root.get_time(), np.max(np.abs(q_arm - arm_ref)),
                         np.max(np.abs(q_hand - hand_ref[:10])),
                         np.max(np.abs(u)), np.abs(hand_ref[10:]).max()))
            return EventStatus.Succeeded()

        simulator.set_monitor(record)
        design = TossDesign.of(cls.scenario.throw.toss)
        cls.t_throw_end = cls.scenario.throw.settle_s + design.handoff_s
        ramp = (cls.scenario.catch.preshape_closure * robot.HAND_CLOSED.max()
                / robot.FINGER_MAX_SPEED)
        cls.t_preshaped = cls.t_throw_end + ramp
        simulator.AdvanceTo(cls.t_preshaped + 0.15)
        cls.rows = np.array(rows)

    def _during(self, lo, hi):
        t = self.rows[:, 0]
        return self.rows[(t >= lo) & (t <= hi)]

    def test_the_fingers_are_not_in_plant_pd(self):
        # Drake's in-plant PD is for discrete plants; the continuous
        # station drives the fingers from outside the plant.
        plant = self.station.plant
        for i in plant.GetJointActuatorIndices(self.station.hand):
            self.assertFalse(plant.get_joint_actuator(i).has_controller())

    def test_arm_follows_the_toss(self):
        toss = self._during(self.scenario.throw.settle_s, self.t_throw_end)
        self.assertGreater(len(toss), 20)
        # Measured: 0.018 rad at accuracy 1e-3 (0.0015 rad on the 1 ms
        # discrete plant); the launch is at 2.2 m/s.
        self.assertLess(toss[:, 1].max(), 0.03)

    def test_fingers_follow_their_ramp_and_settle(self):
        ramp = self._during(self.t_throw_end, self.t_preshaped)
        self.assertGreater(ramp[:, 4].max(), 1.0, "the reference moves")
        # In-plant PD on the continuous plant lagged 0.39 rad here; the
        # discrete plant's in-plant PD lags 0.068 rad.
        self.assertLess(ramp[:, 2].max(), 0.1)
        settled = self._during(self.t_preshaped + 0.1, np.inf)
        self.assertGreater(len(settled), 0)
        self.assertLess(settled[:, 2].max(), 0.01)

    def test_finger_torques_within_the_servo_limit(self):
        self.assertLessEqual(self.rows[:, 3].max(), 10.0 + 1e-9)


class ReleaseConvergenceOptionsTest(RefusalAssertions, unittest.TestCase):
    """benchmarks/release_convergence.py's two-scenario options."""
    main = staticmethod(
        load_script("benchmarks/release_convergence.py").main)

    def test_bad_options_are_refused_before_any_work(self):
        with tempfile.TemporaryDirectory() as d:
            out = ["--objects", "table1-row2", "--out", d]
            self.assertRefused(["--fine-step-s", "0.0001",
                                "--fine-scenario-text", "{}", *out],
                               "--fine-step-s", "--fine-scenario-text")
            self.assertRefused(["--scenario-text", CENIC,
                                "--fine-scenario-text",
                                "{simulator_config: {accuracy: 2}}", *out],
                               "simulator_config.accuracy")
            self.assertRefused(["--scenario-name", "Nope", *out],
                               "--scenario-name: got 'Nope'")
            self.assertFalse((Path(d) / "rows.jsonl").exists())


if __name__ == "__main__":
    unittest.main()
