"""The throw-and-catch station: physics of the flight, determinism, torque
limits, the state machine's phases and the grasp monitor's verdicts.

Episodes are simulated once per class (a few seconds each) and shared.
"""

import functools
import os
import re
import tempfile
import unittest
from pathlib import Path

import matplotlib.image
import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from regrasp_drake.episode.diagram import build_episode_diagram
from regrasp_drake.episode.episode import run_episode
from regrasp_drake.episode.replay import (
    CHROMIUM,
    make_meshcat,
    render_html_to_png,
    save_html,
)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.station.start_pose import start_poses
from regrasp_drake.station.station import (
    MakeStation,
    Station,
    make_arm_controller,
)
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world import robot
from regrasp_drake.world.objects import load_catalogue

OBJECT = "table1-row2"


def _free_flight(logs, scenario):
    """Samples where the object flies free: more than 5 cm from the palm
    sensors' reach and above the catch height, between release and landing."""
    z = logs.object_state[6]
    apex = int(np.argmax(z))
    far = logs.ir[:3].min(axis=0) >= scenario.sensors.levels
    # Walk out from the apex while nothing touches the object.
    lo = apex
    while lo > 0 and far[lo - 1] and logs.bumper[lo - 1] == 0:
        lo -= 1
    hi = apex
    while hi < len(z) - 1 and far[hi + 1] and z[hi + 1] > 0.3:
        hi += 1
    return slice(lo + 3, hi - 3)


def _setup(cls):
    cls.scenario = load_scenario(name="Fast")
    cls.ik = ArmIk()
    cls.obj = load_catalogue()[OBJECT]


@functools.cache
def _watched():
    """The Fast scenario's watching throw of OBJECT (the shipped one at a
    1 ms step), simulated once for the module."""
    scenario = load_scenario(name="Fast")
    return watch(scenario, load_catalogue()[OBJECT], ArmIk(scenario.directives))


class TestWatchedFlight(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        _setup(cls)
        cls.first = _watched()
        cls.second = watch(cls.scenario, cls.obj, cls.ik)

    def test_watching_throw_lands(self):
        self.assertEqual(self.first.outcome, "landed", self.first.message)

    def test_parabola_with_scenario_gravity(self):
        logs = self.first.logs
        window = _free_flight(logs, self.scenario)
        t = logs.t[window]
        self.assertGreater(len(t), 20, "too short a free flight to fit")
        # Centre of mass: p_WCm = p_WO + R_WO p_OCm.
        p_OCm = self.obj.p_OCm
        p = np.array([logs.object_state[4:7, k] + _rotation(
            logs.object_state[:4, k]) @ p_OCm for k in range(len(logs.t))]).T
        for axis in range(3):
            coefficients = np.polyfit(t - t[0], p[axis, window], 2)
            if axis == 2:
                self.assertAlmostEqual(
                    2 * coefficients[0], -self.scenario.gravity_m_per_s2,
                    delta=1e-3 * self.scenario.gravity_m_per_s2)
            else:
                self.assertLess(abs(2 * coefficients[0]), 1e-3 * 9.81)

    def test_angular_momentum_about_com_conserved(self):
        """Drake's discrete step is first order: H drifts by O(dt) at most.
        We check the drift is small at the scenario's step and shrinks at
        least in proportion to the step (conservation in the limit; the
        palm toss's object, spinning about one principal axis, drifts less
        than that: 13 times less at a quarter of the step)."""
        drift = _momentum_drift(self.first.logs, self.obj, self.scenario)
        self.assertLess(drift, 5e-4)
        dt = self.scenario.plant_config.time_step
        fine = load_scenario(name="Fast",
                             text=f"{{plant_config: {{time_step: {dt / 4}}}}}")
        fine_drift = _momentum_drift(watch(fine, self.obj, self.ik).logs,
                                     self.obj, fine)
        self.assertGreater(drift / fine_drift, 3.0)

    def test_flights_bit_identical(self):
        np.testing.assert_array_equal(self.first.logs.object_state,
                                      self.second.logs.object_state)

    def test_rises_above_catch_height(self):
        z = self.first.logs.object_state[6]
        self.assertGreaterEqual(
            z.max() - self.scenario.catch.catch_height_m, 0.45)

    def test_actuation_within_effort_limits(self):
        limits = np.concatenate([robot.ARM_EFFORT_LIMITS,
                                 np.full(10, robot.FINGER_EFFORT_LIMIT)])
        peak = np.abs(self.first.logs.actuation).max(axis=1)
        self.assertTrue(np.all(peak <= limits + 1e-9), f"peak {peak}")


class TestCatch(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        _setup(cls)
        cls.plan = plan_catch(cls.scenario, cls.obj, cls.ik, _watched())
        c = cls.scenario.catch
        cls.tmp = tempfile.TemporaryDirectory()
        cls.html = Path(cls.tmp.name) / "episode.html"
        meshcat = make_meshcat()
        cls.caught = run_episode(cls.scenario, cls.obj, ik=cls.ik,
                                 X_WG=cls.plan.X_WG,
                                 catch_parameters=(c.h_catch_m, c.h_down_m),
                                 meshcat=meshcat)
        save_html(meshcat, cls.html)
        # The hand waits 0.25 m to the side of the flight: a plain miss.
        X_WG = RigidTransform(cls.plan.X_WG.rotation(),
                              cls.plan.X_WG.translation() + [0.0, -0.25, 0.0])
        cls.missed = run_episode(cls.scenario, cls.obj, ik=cls.ik, X_WG=X_WG,
                                 catch_parameters=(c.h_catch_m, c.h_down_m))

    def test_default_parameters_catch(self):
        self.assertEqual(self.caught.outcome, "caught", self.caught.message)
        self.assertIsNotNone(self.caught.catch_time_s)

    def test_phases_in_papers_order(self):
        phases = self.caught.logs.phase.astype(int)
        order = [p for i, p in enumerate(phases) if i == 0 or p != phases[i - 1]]
        self.assertEqual(order, [int(p) for p in Phase if p != Phase.FAILED])

    def test_object_rests_in_palm_when_caught(self):
        logs = self.caught.logs
        on_palm = (np.all(logs.ir[:3, -1] < self.scenario.monitor.palm_grasp_level)
                   or logs.bumper[-1] == 1.0)
        self.assertTrue(on_palm)
        self.assertLess(np.linalg.norm(logs.object_state[10:13, -1]), 0.05)
        # Still where the hand waited, not on the ground.
        p_WO = logs.object_state[4:7, -1]
        self.assertLess(np.linalg.norm(p_WO - self.plan.X_WG.translation()), 0.1)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_replay_html_self_contained(self):
        text = self.html.read_text()
        self.assertGreater(len(text), 1_000_000)
        external = re.findall(r'<(?:script|link)[^>]+(?:src|href)=["\']?https?:',
                              text)
        self.assertEqual(external, [])

    @unittest.skipUnless(os.access(CHROMIUM, os.X_OK),
                         f"{CHROMIUM} absent (apt-get install -y chromium)")
    def test_replay_renders_a_scene(self):
        png = Path(self.tmp.name) / "episode.png"
        render_html_to_png(self.html, png)
        rgb = (matplotlib.image.imread(png)[..., :3] * 255).astype(np.uint8)
        colours = np.unique(rgb.reshape(-1, 3), axis=0)
        self.assertGreater(len(colours), 50, "a blank page")

    def test_hand_away_drops(self):
        self.assertEqual(self.missed.outcome, "dropped", self.missed.message)
        self.assertIsNone(self.missed.catch_time_s)


def _momentum_drift(logs, obj, scenario) -> float:
    """Largest change of the angular momentum about the CoM in free flight,
    relative to its size."""
    window = _free_flight(logs, scenario)
    M = obj.spatial_inertia()
    I_Cm_O = M.Shift(M.get_com()).CalcRotationalInertia().CopyToFullMatrix3()
    H = []
    for k in range(len(logs.t))[window]:
        R = _rotation(logs.object_state[:4, k])
        H.append(R @ I_Cm_O @ R.T @ logs.object_state[7:10, k])
    H = np.array(H)
    norm = np.linalg.norm(H[0])
    assert norm > 1e-6, "the object does not turn"
    return float(np.max(np.linalg.norm(H - H[0], axis=1)) / norm)


def _rotation(quaternion_wxyz):
    q = np.asarray(quaternion_wxyz, float)
    return RotationMatrix(Quaternion(q / np.linalg.norm(q))).matrix()



class TestStationPorts(unittest.TestCase):
    """The station alone, MakeStation's Diagram with its named ports
    exported, is a Diagram that something other than the catch controller
    can drive."""

    @classmethod
    def setUpClass(cls):
        _setup(cls)
        cls.diagram = MakeStation(cls.scenario, cls.obj)
        cls.station = Station.of(cls.diagram)

    def test_named_diagram(self):
        self.assertEqual(self.diagram.get_name(), "station")
        self.assertIs(self.station.diagram, self.diagram)

    def test_named_ports(self):
        self.assertEqual(
            sorted(self.diagram.get_input_port(i).get_name()
                   for i in range(self.diagram.num_input_ports())),
            ["arm_desired_acceleration", "arm_desired_state",
             "hand_desired_state"])
        self.assertEqual(
            sorted(self.diagram.get_output_port(i).get_name()
                   for i in range(self.diagram.num_output_ports())),
            ["arm_state", "body_poses", "bumper", "contact_results",
             "hand_state", "ir_levels", "net_actuation", "object_state",
             "query_object"])
        with self.assertRaisesRegex(KeyError, "no output port 'phase'"):
            self.station.GetOutputPort("phase")

    def test_held_arm_stays_and_ports_read_the_plant(self):
        """Driven by constant references (the arm held at its start, the
        fingers open), the arm stays put and holds the object up."""
        context = self.diagram.CreateDefaultContext()
        plant = self.station.plant
        plant_context = plant.GetMyMutableContextFromRoot(context)
        q0 = throw.start_q(self.scenario.throw)
        plant.SetPositions(plant_context, self.station.arm, q0)
        X_WO = start_poses(self.scenario, self.obj)[1]
        plant.SetFreeBodyPose(plant_context, self.station.object_body, X_WO)
        self.diagram.GetInputPort("arm_desired_state").FixValue(
            context, np.concatenate([q0, np.zeros(6)]))
        self.diagram.GetInputPort("arm_desired_acceleration").FixValue(
            context, np.zeros(6))
        self.diagram.GetInputPort("hand_desired_state").FixValue(
            context, np.zeros(20))
        simulator = Simulator(self.diagram, context)
        simulator.AdvanceTo(0.1)
        arm = self.diagram.GetOutputPort("arm_state").Eval(context)
        self.assertLess(np.abs(arm[:6] - q0).max(), 1e-3)
        state = self.diagram.GetOutputPort("object_state").Eval(context)
        np.testing.assert_array_equal(state, plant.GetPositionsAndVelocities(
            plant_context, self.station.object_body.model_instance()))
        # Still lying on the palm where it was laid, not fallen off.
        np.testing.assert_allclose(
            state[4:7], X_WO.translation(), atol=0.01)
        np.testing.assert_array_equal(
            self.station.Eval("object_state", context), state)

    def test_inverse_kinematics_of_other_directives_refused(self):
        other = robot.robot_directives()
        other[0].add_model.default_joint_positions = {"joint1": [0.1]}
        with self.assertRaisesRegex(ValueError, "ArmIk"):
            build_episode_diagram(self.scenario, self.obj, ik=ArmIk(other),
                                  X_WG=None)


def _held_references(scenario) -> dict:
    """Constant references for the station's inputs: the arm held at the
    throw's start, the fingers open."""
    q0 = throw.start_q(scenario.throw)
    return {"arm_desired_state": np.concatenate([q0, np.zeros(6)]),
            "arm_desired_acceleration": np.zeros(6),
            "hand_desired_state": np.zeros(20)}


def _lay_object(station: Station, scenario, obj, root_context) -> None:
    """The arm at the throw's start and the object lying in the palm, in
    the plant of `station` (nested anywhere in the root context's
    diagram)."""
    plant = station.plant
    plant_context = plant.GetMyMutableContextFromRoot(root_context)
    plant.SetPositions(plant_context, station.arm,
                       throw.start_q(scenario.throw))
    plant.SetFreeBodyPose(plant_context, station.object_body,
                          start_poses(scenario, obj)[1])


class TestStationNested(unittest.TestCase):
    """A Drake user's diagram with the station in it, as with
    manipulation's MakeHardwareStation."""

    @classmethod
    def setUpClass(cls):
        _setup(cls)

    def test_nested_in_five_lines(self):
        references = _held_references(self.scenario)
        # The five lines: the station nested, driven, built and simulated.
        builder = DiagramBuilder()
        station = builder.AddSystem(MakeStation(self.scenario, self.obj))
        for name, value in references.items():
            builder.Connect(builder.AddSystem(ConstantVectorSource(value)).get_output_port(), station.GetInputPort(name))  # noqa: E501
        simulator = Simulator(builder.Build())
        # (the object laid in the palm first, for a fact to check)
        context = simulator.get_mutable_context()
        _lay_object(Station.of(station), self.scenario, self.obj, context)
        simulator.AdvanceTo(0.1)
        arm = station.GetOutputPort("arm_state").Eval(
            station.GetMyContextFromRoot(context))
        self.assertLess(np.abs(arm[:6] - references["arm_desired_state"][:6])
                        .max(), 1e-3)

    def test_two_stations_in_one_builder(self):
        """Two stations side by side in one builder, each driven by its own
        references: both simulate, each plant on its own, alike."""
        builder = DiagramBuilder()
        stations = [builder.AddSystem(MakeStation(self.scenario, self.obj,
                                                  name=name))
                    for name in ("left", "right")]
        for station in stations:
            for name, value in _held_references(self.scenario).items():
                source = builder.AddSystem(ConstantVectorSource(value))
                builder.Connect(source.get_output_port(),
                                station.GetInputPort(name))
        diagram = builder.Build()
        simulator = Simulator(diagram)
        context = simulator.get_mutable_context()
        for station in stations:
            _lay_object(Station.of(station), self.scenario, self.obj, context)
        # The right one's object dropped from 5 cm higher: not the left's.
        right = Station.of(stations[1])
        plant_context = right.plant.GetMyMutableContextFromRoot(context)
        X_WO = right.plant.GetFreeBodyPose(plant_context, right.object_body)
        right.plant.SetFreeBodyPose(plant_context, right.object_body,
                                    RigidTransform(X_WO.rotation(),
                                                   X_WO.translation()
                                                   + [0, 0, 0.05]))
        simulator.AdvanceTo(0.1)
        states = [s.GetOutputPort("object_state").Eval(
            s.GetMyContextFromRoot(context)) for s in stations]
        # Both lie on their palms near where they were laid; the right one,
        # dropped, is still falling or bouncing, not where the left one is.
        p_WO = start_poses(self.scenario, self.obj)[1].translation()
        np.testing.assert_allclose(states[0][4:7], p_WO, atol=0.01)
        self.assertGreater(np.abs(states[1][4:7] - states[0][4:7]).max(),
                           1e-4)
        self.assertEqual(sorted(s.get_name() for s in stations),
                         ["left", "right"])


if __name__ == "__main__":
    unittest.main()


class TestArmController(unittest.TestCase):
    """Without an integral gain the arm's controller is Drake's
    InverseDynamicsController without its PID's integrator (continuous
    state): the same torques bit for bit."""

    def test_same_torques_as_drakes_controller(self):
        scenario = load_scenario()
        ours = make_arm_controller(scenario)
        self.assertEqual(ours.num_continuous_states(), 0)
        arm = scenario.arm
        drakes = InverseDynamicsController(
            robot.arm_control_plant(scenario.directives), arm.kp, arm.ki,
            arm.kd, has_reference_acceleration=True)
        self.assertEqual(drakes.num_continuous_states(), 6)
        rng = np.random.default_rng(7)
        for _ in range(20):
            inputs = {"estimated_state": rng.uniform(-3, 3, 12),
                      "desired_state": rng.uniform(-3, 3, 12),
                      "desired_acceleration": rng.uniform(-30, 30, 6)}
            torques = []
            for system in (ours, drakes):
                context = system.CreateDefaultContext()
                for name, value in inputs.items():
                    system.GetInputPort(name).FixValue(context, value)
                torques.append(system.GetOutputPort("actuation").Eval(context))
            np.testing.assert_array_equal(torques[0], torques[1])

    def test_integral_gain_keeps_drakes_controller(self):
        scenario = load_scenario(text="{arm: {ki: [1, 1, 1, 1, 1, 1]}}")
        controller = make_arm_controller(scenario)
        self.assertIsInstance(controller, InverseDynamicsController)
        self.assertEqual(controller.num_continuous_states(), 6)
