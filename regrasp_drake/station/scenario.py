"""The scenario: every physical constant of a throw-and-catch episode, with units.

One typed dataclass tree, as Drake's hardware_sim example writes it: Drake's
own `MultibodyPlantConfig` (`plant_config`), `SimulatorConfig`
(`simulator_config`) and the robot's model directives (`directives`) beside
the project's fields. It is loaded from YAML with
pydrake's `yaml_load_typed` (unknown keys and values of the wrong type are
refused first, naming the field: yaml_schema.check_schema), then range-checked field
by field. The defaults below are the shipped scenario; a scenario need only
name the fields it changes.

Named scenarios live in one YAML file (SCENARIOS_PATH: name -> scenario);
`load_scenario` reads a plain scenario file, or a name from such a file,
then merges YAML text over it (`--scenario-text '{catch: {return_s: 0.4}}'`).

Bounds (`validate`, station/scenario_checks.py): every field's range. The
file is read within the limits of regrasp_drake/input_files.py (size,
nesting, aliases, duplicate keys); `1e5` is a number; Drake's tags
(`!Rpy {deg: [...]}`) are read in the directives.

Over 500 lines because it is one schema: about 330 of them are the
dataclass tree, each field with its unit, meaning and source beside it.
"""

import copy
import dataclasses as dc
import hashlib
import re
import sys
import typing
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.multibody.parsing import ModelDirective
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import (
    SimulatorConfig,
)

from regrasp_drake import memo
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.input_files import Tagged, dump_yaml, load_yaml, parse_yaml
from regrasp_drake.paths import PACKAGE_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.station.scenario_checks import validate
from regrasp_drake.world.robot import (
    robot_directives,
)
from regrasp_drake.yaml_schema import check_schema

# The named scenarios (name -> scenario), and the one used by default.
SCENARIOS_PATH = PACKAGE_DIR / "scenarios.yaml"
DEFAULT_SCENARIO_NAME = "Default"


@dc.dataclass
class ContactConfig:
    # Coulomb friction coefficient (static = dynamic) of every surface, [-].
    friction_coefficient: float = 0.9
    # Point-contact stiffness of the object's surfaces, [N/m].
    point_stiffness_N_per_m: float = 100000.0
    # Hunt-Crossley dissipation of the object's surfaces, [s/m].
    hunt_crossley_dissipation_s_per_m: float = 10.0
    # The palm's collision geometry: "pads" (36 sphere pads over a lowered
    # box, the 8 under the bumper 1 mm prouder: smooth point contact for the
    # palm toss) or "box" (a flat box with the tactile bumper's thin box on
    # it, the finger throw's); sdf/hand.sdf holds both and the station keeps
    # one.
    palm: str = "pads"
    # The collision geometry of the objects' box pieces: "rounded" (Drake's
    # inset box with 8 corner spheres, world/objects.py
    # Piece.collision_shapes) or "exact" boxes.
    object_boxes: str = "rounded"


@dc.dataclass
class ArmControlConfig:
    # Inverse-dynamics controller gains, per arm joint: kp [1/s²], ki [1/s³],
    # kd [1/s] (they multiply joint errors in rad before the mass matrix).
    kp: list[float] = dc.field(default_factory=lambda: [900.0] * 6)
    ki: list[float] = dc.field(default_factory=lambda: [0.0] * 6)
    kd: list[float] = dc.field(default_factory=lambda: [60.0] * 6)


@dc.dataclass
class ThrowNoise:
    """Release noise: each throw's perturbation is drawn from a generator
    seeded with (seed, the throw's number), so a run is reproducible from its
    seed; zero deviations reproduce the deterministic throw exactly."""
    # Standard deviation of the moment the fingers open, [s].
    release_time_std_s: float = 0.0
    # Standard deviation of each arm joint's velocity offset at the release,
    # [rad/s] (a smooth pulse on the throw's reference, see
    # catch_state_machine.ThrowPerturbation).
    joint_velocity_std_rad_per_s: float = 0.0
    seed: int = 0

    def is_zero(self) -> bool:
        """No deviations: every throw is the deterministic one."""
        return (self.release_time_std_s == 0.0
                and self.joint_velocity_std_rad_per_s == 0.0)

    @classmethod
    def at_level(cls, level: float, seed: int) -> "ThrowNoise":
        """The release noise of level `level` (a number >= 0): release time
        std level x RELEASE_STD_PER_LEVEL_S, joint velocities level x
        JOINT_DV_STD_PER_LEVEL. Level 1 is the shipped noise every figure
        under noise is measured at (benchmarks/noise_curve.py)."""
        return cls(release_time_std_s=level * RELEASE_STD_PER_LEVEL_S,
                   joint_velocity_std_rad_per_s=level * JOINT_DV_STD_PER_LEVEL,
                   seed=seed)


# Release noise per level (ThrowNoise.at_level): the release time's std [s]
# and each arm joint's velocity offset std [rad/s].
RELEASE_STD_PER_LEVEL_S = 0.002
JOINT_DV_STD_PER_LEVEL = 0.03


@dc.dataclass
class PalmTossConfig:
    """The palm toss (station/palm_toss.py), used when throw.kind is
    "palm_toss": the object lies on the open palm; the palm lifts it straight
    up while rolling about its fingertip direction, then brakes harder than
    gravity so that the object leaves with the palm's velocity and spin. No
    finger touches it."""
    # Arm joint angles at rest, palm up, before the toss, [rad]: the palm at
    # (0.70, -0.15, 0.25) m, elbow up, away from the wrist's singularity
    # (q5 = 0). Of the palm-up poses at x 0.7-0.9 m, z 0.25-0.35 m, the one
    # whose toss needs the least of the servos' torque limits (inverse
    # dynamics along the toss, gravity and the motors' reflected inertia
    # included: 0.72 of a limit, the shoulder's; studies/palm_toss).
    start_q_rad: list[float] = dc.field(
        default_factory=lambda: [0.0, -0.0304, -2.8132, 0.0, 1.2728, -3.1416])
    # The palm's upward speed when it starts to brake, [m/s].
    launch_speed_m_per_s: float = 2.2
    # Duration of the lift from rest to the launch speed, [s].
    lift_s: float = 0.45
    # The brake's deceleration, [m/s²]: above gravity's, so the object
    # leaves the palm as the brake's deceleration passes g ...
    brake_deceleration_m_per_s2: float = 16.0
    # ... which it reaches in this rise time (a smoothstep), [s].
    brake_ramp_s: float = 0.03
    # The palm's roll rate about its fingertip direction at launch, [rad/s]:
    # the object's spin in flight.
    spin_rad_per_s: float = 5.5
    # The roll keeps its rate this long after the palm starts to brake (the
    # object leaves as the deceleration passes g, 17 ms into the brake),
    # [s]; the move to the grasp pose takes over from the moving arm then.
    spin_hold_s: float = 0.07
    # Over this time the move stops the roll, [s] (for the toss's own
    # trajectory, which runs on to rest).
    spin_stop_s: float = 0.15
    # The coordinated palm (station/palm_toss.py): while tilted by φ in the
    # lift, the palm also accelerates sideways by -(g + a_z) tan φ, as a
    # waiter carries a tray, so that no tilt tips a narrow-based object; its
    # roll first tilts forward so that the sideways motion is back at rest
    # when the palm brakes. Without it, objects resting on a narrow base
    # tipped in the lift (studies/palm_toss/FINDINGS.md).
    coordinated: bool = True


@dc.dataclass
class ThrowConfig:
    # The throw: "palm_toss" (the open palm tosses it, `toss` below; no
    # finger touches it) or "fingers" (the paper's: the fingers hold the
    # object through the arm's swing along the knots below and open at
    # release_time_s; its release is not converged in the time step,
    # studies/palm_toss/FINDINGS.md). knot_times_s, knot_q_rad,
    # release_time_s and hold_closure are the finger throw's alone.
    kind: str = "palm_toss"
    # Time the object is left to settle in the closed hand before the swing, [s].
    settle_s: float = 0.3
    # Arm joint knots of the throw (rad), at times `knot_times_s` (s) counted
    # from the end of the settling; a C2 cubic spline with zero end
    # velocities joins them. The first knot is the arm's initial pose.
    knot_times_s: list[float] = dc.field(
        default_factory=lambda: [0.0, 0.2687, 0.3693, 0.564])
    knot_q_rad: list[list[float]] = dc.field(
        default_factory=lambda: [
            [0.0, -0.7404, -0.9010, 0.0, 0.0706, 3.1416],
            [0.0, -0.4542, -0.5116, 0.0, -0.8712, 3.1416],
            [0.0, -0.0621, -0.7490, 0.0, -0.5681, 3.1416],
            [0.0, 0.4295, -1.6445, 0.0, 0.4274, 3.1416],
        ])
    # Time, counted like the knots, at which the fingers open, [s].
    release_time_s: float = 0.31
    # Hand joint positions while the object is held for the throw, as a
    # fraction of the closed posture, [-].
    hold_closure: float = 0.5
    # On a watching throw the arm parks out of the flight's way: the throw's
    # last knot with joint 1 turned by this much, [rad].
    park_joint1_offset_rad: float = 0.7
    # Release noise (default none: every throw identical). With the palm
    # toss, release_time_std_s delays the brake.
    noise: ThrowNoise = dc.field(default_factory=ThrowNoise)
    toss: PalmTossConfig = dc.field(default_factory=PalmTossConfig)


@dc.dataclass
class SensorConfig:
    # Sampling period of the infrared sensors and the tactile bumper, [s].
    period_s: float = 0.004
    # Range of the palm infrared sensors IR 1-3, [m] (paper §V.B: 10 cm).
    palm_range_m: float = 0.10
    # Range of the approach infrared sensors IR 4-13, [m] (>= the largest
    # h_catch of the parameter space, 0.40 m).
    approach_range_m: float = 0.50
    # Quantization levels over a sensor's range, [-] (paper: 1000).
    levels: int = 1000


@dc.dataclass
class CatchConfig:
    # Height of the object's origin at the catch point, [m]: the hand waits
    # under the watched flight where the object falls through this height.
    catch_height_m: float = 0.45
    # Catch points are looked for within this distance of catch_height_m, the
    # nearest first, [m].
    height_band_m: float = 0.3
    # A catch point needs the object's axis this close to horizontal,
    # |y_O · z_W| < tolerance, [-]. The palm turns about the fingertip
    # direction to lie parallel to the axis (paper §V: "the hand parallel with
    # the object at the moment of catching"): 0.3 is a 17° tilt, well inside
    # the 42° friction angle of the pads (mu = 0.9).
    tilt_tolerance: float = 0.3
    # The palm turns about the fingertip direction toward the object's axis
    # by at most this angle, [rad]; None: as far as tilt_tolerance allows
    # (arcsin 0.3, 17.5°: parallel to the axis at every catch point). 0: the
    # palm waits level whatever the axis's tilt.
    palm_max_tilt_rad: typing.Optional[float] = None
    # Under a grasp target, true: the palm's offsets from the centre of mass
    # along the object's axis are kept along the tilted palm's y, so that
    # the centre of mass projects along the palm's normal where the target
    # puts it; false (and always under "any"): horizontally, so a palm
    # tilted by α puts it h·tan α further (h its height above the palm:
    # +12 mm under keep, -7 mm under flip for Table 1 rows 1-2,
    # studies/landing).
    target_palm_com_along_normal: bool = True
    # Along the object's axis the palm is centred under the grasp piece, but
    # shifted so that the centre of mass is at most this far from the palm's
    # centre (the palm is 0.115 m wide along the axis), [m]: 0, under the
    # centre of mass.
    palm_com_margin_m: float = 0.0
    # ... then this far toward the end of the object that comes down first
    # at the catch moment (it turns end over end as it lands), [m] ...
    palm_toward_landing_end_m: float = 0.01
    # ... but under a grasp target (regrasp.target not "any") this far: the
    # palm waits for the grasp the object is to rest in, and the object
    # rests where it first touches, the plan's offset + 1.2 mm (median of 60
    # catches, studies/landing); the shift above, chosen when any hold
    # counted, moves every target's rest by ±10 mm. Under it, 12 of 60
    # Table 1 and held-out pairs × six targets land in the target grasp on
    # the first throw, 28 of 60 at 0 (both with the rest-to-rest lowering;
    # docs/regrasp.md, The landing), [m].
    target_palm_toward_landing_end_m: float = 0.0
    # ... and the palm this far toward its heel, so that the object lands
    # nearer the fingers (studies/hand_design: on the 115 mm palm, with the
    # two above, 23, 24, 20, 21, 20 of the 25 tolerance offsets caught at
    # the 85 mm palm's network cells for Table 1, against 23, 22, 23, 18, 17
    # under the grasp piece), [m].
    palm_toward_fingers_m: float = 0.01
    # Across the object's axis the palm's centre lies this fraction of the
    # way from the grasp piece's axis to the centre of mass: 1 under the
    # centre of mass (an object landing flat does not tip off the palm), 0
    # under the grasp piece (the fingers close around it), [-].
    palm_across_com_fraction: float = 1.0
    # Inverse kinematics of the grasp pose starts from these arm joint angles,
    # [rad]: the throw's last knot, where the move to the grasp pose starts.
    # Damped least squares converges to the solution nearest its seed, so the
    # move is the shortest one (an elbow-up posture); from an elbow-down seed
    # the shoulder and wrist travel up to 1.1 and 1.9 rad, saturate their
    # servos within move_to_grasp_s and reach the grasp pose 0.1-0.2 s late.
    ik_seed_q_rad: list[float] = dc.field(
        default_factory=lambda: [0.0, 0.4295, -1.6445, 0.0, 0.4274, 3.1416])
    # Duration of the arm's move from the end of the throw to the grasp
    # position, [s].
    move_to_grasp_s: float = 0.45
    # A grasp pose is used only if the move there needs at most this fraction
    # of every arm servo's torque limit (inverse dynamics of the move); the
    # rest is left to the feedback that corrects tracking errors, [-].
    max_move_torque_fraction: float = 0.9
    # The hand is at the grasp position when its wrist is this close, [m]
    # (paper Fig. 9: 0.001 m).
    grasp_tolerance_m: float = 0.001
    # With the palm toss, the fingers pre-shape after the throw to this
    # fraction of the closed posture, a cage that funnels the falling object
    # toward the palm, [-].
    preshape_closure: float = 0.3
    # The distal joints' pre-shape, as the same fraction, [-]; None: that of
    # the knuckles (preshape_closure). Knuckles flexed more than the distal
    # joints stand the fingers up as walls with their tips over the palm.
    preshape_distal_closure: typing.Optional[float] = None
    # The order the fingers close in once the catch triggers: "together"
    # (the paper's), "thumb_first" (the others start as the thumb arrives)
    # or "fingers_first" (the thumb starts as the others arrive); each
    # joint at its full speed. Neither other order holds more in the static
    # test (studies/landing_step/FINDINGS.md §9).
    closing_order: str = "together"
    # Speed at which the hand is lowered by |h_down|, [m/s].
    lower_speed_m_per_s: float = 1.0
    # Lowering stops when a palm infrared sensor reads below this, [level]
    # (paper Fig. 9: 600).
    palm_stop_level: int = 600
    # Duration of the return from the lowered to the grasp position, [s].
    return_s: float = 0.3
    # false (the paper's Fig. 9): the return starts from rest where the
    # lowering stopped, so the hand stops dead as the object lands. true:
    # it takes over from the lowering's moving state (position, velocity,
    # acceleration), so the hand goes on down as the object lands and turns
    # back smoothly within return_s, a cushion.
    return_from_motion: bool = True
    # false (the paper's Fig. 9): the lowering is a quintic from rest to
    # rest. true: its time law is 2τ³ - τ⁴, which ends moving down at twice
    # its mean speed (lower_speed_m_per_s) and goes on so until the return
    # takes over from that motion (needs return_from_motion): the palm
    # meets the falling object moving with it, and yields after, instead of
    # waiting for it at rest. None: true under a grasp target, false under
    # "any" (the paper's catch, Table 1 as the paper ran it). First throw,
    # Table 1 + held-out × six targets: 39 of 60 in the target grasp, 27 of
    # 60 false (docs/regrasp.md, The landing).
    lower_ends_moving: typing.Optional[bool] = None
    # The catch that follows the object (planning/follow.py): the palm
    # moves with the object's horizontal velocity at the planned catch
    # moment (follow_along) and turns with its pitch, about the palm's
    # fingertip axis (follow_pitch), over the contact, matched as far as
    # follow_max_torque_fraction of the servos' torque limits allows. None:
    # on under a grasp target, off under "any" (the paper's catch).
    follow_along: typing.Optional[bool] = False
    follow_pitch: typing.Optional[bool] = False
    # Its time law around the catch moment t_c (planning/follow.FollowLaw),
    # [s]: the palm reaches the object's motion over follow_ramp_s before
    # t_c, keeps it follow_hold_s after (the impact comes after t_c: the
    # palm lowers to meet the object), stops over follow_stop_s and comes
    # back to the planned grasp pose over follow_back_s.
    follow_ramp_s: float = 0.1
    follow_hold_s: float = 0.06
    follow_stop_s: float = 0.1
    follow_back_s: float = 0.3
    # The follow's largest acceleration, with the arm's weight, needs at
    # most this fraction of each arm servo's torque limit; a faster object
    # is followed at a fraction of its velocity, [-].
    follow_max_torque_fraction: float = 0.8
    # Where (h_catch, h_down) come from: "fixed" (the two values below) or
    # "mlp" (the network in `weights`).
    parameter_source: str = "fixed"
    # Fixed catch parameters, [m]: inside table1-row2's catching region
    # (h_catch >= 0.16 m with h_down <= -0.06 m catches it).
    h_catch_m: float = 0.28
    h_down_m: float = -0.12
    # Weights file of the MLP, relative to the repository's models/ directory
    # or absolute.
    weights: str = "catch_mlp.pt"


@dc.dataclass
class MonitorConfig:
    # A grasp is recognized when every palm infrared sensor reads below this
    # level for `ir_window_s`, or the bumper reads 1 for `bumper_window_s`
    # (paper §V.B).
    palm_grasp_level: int = 700
    ir_window_s: float = 0.15
    bumper_window_s: float = 0.15
    # Or when the fingers have closed on the object: the thumb and another
    # finger stopped short of their goal (a joint more than
    # `finger_stall_rad` short of its commanded angle, every joint of the
    # finger slower than `finger_rest_rad_per_s`) while a palm sensor sees
    # the object (an infrared sensor below `palm_grasp_level`, or the
    # bumper), for `finger_window_s`. An object held off the palm's centre
    # line, which one of the three palm rays misses, is recognized so.
    # 0.01 rad is 0.07 N·m of servo load (kp = 7 N·m/rad); a finger closed
    # on nothing stands within 0.001 rad of its goal, one pressing on the
    # object 0.02 rad or more short. 0.5 rad/s is a tenth of the servos'
    # speed: a finger closing freely moves at 5.8 rad/s; fingers pressing on
    # an object that settles in the hand move at a few tenths of a rad/s
    # for a while (Drake's Allegro example calls a finger stuck below 0.07
    # rad/s, which such settling resets; studies/grasp_monitor/FINDINGS.md).
    # false: the paper's two sensors alone.
    read_fingers: bool = True
    finger_stall_rad: float = 0.01
    finger_rest_rad_per_s: float = 0.5
    finger_window_s: float = 0.15
    # After the hand is back at the grasp position, the object must still be
    # held this long for the catch to count, [s].
    hold_s: float = 0.25
    # The object is dropped when its centre falls this far below the palm
    # surface, [m], or comes within `ground_clearance_m` of the ground.
    below_palm_m: float = 0.08
    ground_clearance_m: float = 0.05
    # The episode ends at this simulated time whatever happens, [s].
    max_time_s: float = 4.0


@dc.dataclass
class RegraspConfig:
    # The grasp the catch must end in (planning/grasp.py): "keep" (the
    # orientation in the palm as before the throw), "flip" (end over end),
    # "turn" (the wrist's half turn), or "any" (held at all: the paper's
    # criterion); `offset_mm`, the palm centre's position along the object's
    # axis from its centre of mass, [mm]. `with_target` also picks the
    # target's throw; a scenario naming a target keeps the throw it has.
    target: str = "any"
    offset_mm: float = 0.0
    # Whether a target the closed hand does not hold at rest (the static
    # test, episode/static_hold.py) is refused before the throw. Off by
    # default: the test still fails 5 of the 60 Table 1 and held-out pairs
    # that the catch lands in the target grasp at the shipped step, 4 of
    # them at half of it too (benchmarks/static_hold.py; studies/
    # landing_step).
    check_hold: bool = False


def _plant_config() -> MultibodyPlantConfig:
    return MultibodyPlantConfig(time_step=0.00025, contact_model="point",
                                discrete_contact_approximation="similar")


@dc.dataclass(eq=False)
class Scenario:
    # The MultibodyPlant (Drake's MultibodyPlantConfig): time_step [s], or 0
    # for a continuous plant (then simulator_config's integration_scheme
    # must be "cenic"); contact_model "point" (the object's stiffness and
    # dissipation in `contact` are point contact's);
    # discrete_contact_approximation "sap", "similar" or "lagged" (TAMSI
    # failed to converge on throw impacts; a continuous plant ignores it);
    # Drake's other settings at Drake's defaults.
    plant_config: MultibodyPlantConfig = dc.field(default_factory=_plant_config)
    # The discrete plant's time step from the throw's end on (the flight,
    # the move to the grasp pose and the catch), [s]; null: plant_config's
    # throughout. The episode is handed over to a plant with this step at
    # the release time (throw.release_time: the first sensor sample after
    # the throw ends), state for state (episode.diagram.continue_with). The release
    # converges at 0.25 ms, the catch at 1 ms (success maps at 1 against
    # 0.5 ms: benchmarks/map_convergence.py). Must be null on a continuous
    # plant.
    catch_time_step_s: float | None = 0.001
    # Under a grasp target (regrasp.target other than "any"), the catch's
    # step instead, from the release on (`catch_step_s`), [s]; null:
    # catch_time_step_s's. At 1 ms the fingers' closing and the hold after
    # the landing still change 7 first throws in 60 against half the step;
    # at 0.5 ms (with the landing at 0.125 ms) 1 in 60 against a quarter
    # (studies/landing_step/FINDINGS.md). The paper's `any` catch keeps
    # catch_time_step_s.
    target_catch_time_step_s: float | None = 0.0005
    # Under a grasp target (regrasp.target other than "any"), the plant's
    # step through the landing, [s]; null: the catch's (`catch_step_s`) to
    # the end. The episode is handed over to it (as at the release)
    # landing_lead_s before the object's centre of mass, in free flight from
    # its state at
    # the release time, falls to the palm's grasp pose. At 1 ms a 2-3.5 m/s
    # landing moves 2-3.5 mm a step into pads whose contact stops it within
    # a fraction of a millimetre, and several pads struck in one step act as
    # one inelastic impact: the step, not the contact, decides the landing
    # (studies/landing_step/FINDINGS.md). At 0.125 ms (with the catch at
    # 0.5 ms) 59 of 60 first throws end as at half of both steps. The
    # paper's `any` catch keeps catch_time_step_s throughout; a continuous
    # plant (plant_config.time_step 0) has no step to hand over to and
    # ignores it.
    landing_time_step_s: float | None = 0.000125
    # How long before that predicted fall the landing's step starts, [s]:
    # before the highest h_catch (0.40 m) can trigger the lowering, so that
    # a success map's cells, forked at their triggers, share it.
    landing_lead_s: float = 0.2
    # How long after that predicted fall the catch goes back to its step
    # (`catch_step_s`), [s]; null: the landing's step to the end. 0.15 s
    # covers the impact and its bounce: the first throws of Table 1 and the
    # held-out objects end the same with it as with the fine step to the
    # end (60 of 60 pairs; studies/landing_step/FINDINGS.md).
    landing_settle_s: float | None = 0.15
    # The simulator and its integrator (Drake's SimulatorConfig, applied
    # with ApplySimulatorConfig as hardware_sim does). Drake's default
    # (runge_kutta3) integrates only the controllers' continuous states
    # beside the discrete plant. "cenic", Drake's error-controlled convex
    # integrator, needs plant_config.time_step 0; its `accuracy` [-] then
    # sets the error it keeps each step within (smaller: more accurate).
    simulator_config: SimulatorConfig = dc.field(
        default_factory=SimulatorConfig)
    # The robot's model directives (default: sdf/puma560_hand.dmd.yaml, the
    # PUMA welded to the world, the hand to its flange); they must add the
    # models "puma560" and "hand", the hand welded to a link of the arm. The
    # arm-only plant of the inverse-dynamics controller and of the inverse
    # kinematics is built from these too (robot.make_arm_control_plant), so
    # a list that moves the arm or the hand's mount is planned and
    # controlled as the robot it builds (ArmIk(scenario.directives)).
    directives: list[ModelDirective] = dc.field(
        default_factory=robot_directives)
    # Gravity's magnitude, pointing along -z, [m/s²].
    gravity_m_per_s2: float = 9.81
    contact: ContactConfig = dc.field(default_factory=ContactConfig)
    arm: ArmControlConfig = dc.field(default_factory=ArmControlConfig)
    throw: ThrowConfig = dc.field(default_factory=ThrowConfig)
    sensors: SensorConfig = dc.field(default_factory=SensorConfig)
    catch: CatchConfig = dc.field(default_factory=CatchConfig)
    monitor: MonitorConfig = dc.field(default_factory=MonitorConfig)
    regrasp: RegraspConfig = dc.field(default_factory=RegraspConfig)

    def __reduce__(self):
        # Drake's config types do not pickle: a scenario travels to a worker
        # process (or a Ray task) as its YAML, every value, and is loaded
        # back from it there, so workers get the caller's scenario as data.
        # Drake's dump leaves out a null field, which the load would give
        # its default: those are carried beside it.
        return (_scenario_from_yaml, (scenario_yaml(self),
                                      _null_fields(self)))


    @property
    def time_step_s(self) -> float:
        """Deprecated: plant_config.time_step, [s] (read only)."""
        return self.plant_config.time_step

    def __eq__(self, other) -> bool:
        # Drake's config structs compare by identity: compare the values.
        return (isinstance(other, Scenario)
                and scenario_yaml(self) == scenario_yaml(other))


def _scenario_from_yaml(text: str, nulls=()) -> Scenario:
    scenario = yaml_load_typed(schema=Scenario, data=text)
    for path in nulls:
        owner = scenario
        for name in path[:-1]:
            owner = getattr(owner, name)
        setattr(owner, path[-1], None)
    return scenario


def _null_fields(value, path=()) -> list[tuple]:
    """The paths of the fields of a dataclass `value` (nested) that are
    None."""
    nulls = []
    for f in dc.fields(value) if dc.is_dataclass(value) else ():
        field = getattr(value, f.name)
        if field is None:
            nulls.append((*path, f.name))
        else:
            nulls += _null_fields(field, (*path, f.name))
    return nulls


def target_of(s: Scenario) -> Target:
    """The grasp the scenario's catches must end in."""
    return Target(s.regrasp.target, float(s.regrasp.offset_mm))


def with_target(s: Scenario, target: Target) -> Scenario:
    """`s` aiming for `target`, with the target's throw (the paper's "similar
    throwing": one throw for every object under a target): the palm toss
    with its spin for a flip (half a turn end over end by the catch), the
    same toss without spin for keep and turn (the object flies as it lay;
    the palm catches it from the start grasp's side, or from the other for
    a turn); `any` keeps the scenario's throw."""
    out = copy.deepcopy(s)
    out.regrasp = dc.replace(out.regrasp, target=target.kind,
                             offset_mm=float(target.offset_mm))
    if target.kind in ("keep", "turn"):
        out.throw.toss.spin_rad_per_s = 0.0
    return validate(out)


def lowers_moving(scenario: "Scenario") -> bool:
    """Whether the catch's lowering ends moving down (catch.lower_ends_moving;
    None: under a grasp target, with the cushioned return it needs; not
    under "any")."""
    moving = scenario.catch.lower_ends_moving
    if moving is None:
        return (scenario.regrasp.target != "any"
                and scenario.catch.return_from_motion)
    return bool(moving)


# What load_scenario's errors call its path, name and text: the command
# line's flags (the API passes its own arguments' names).
SCENARIO_FLAGS = ("--scenario", "--scenario-name", "--scenario-text")


def load_scenario(path: str | Path | None = None, *, name: str | None = None,
                  text: str | None = None,
                  names: tuple[str, str, str] = SCENARIO_FLAGS) -> Scenario:
    """Loads and validates a scenario.

    path: a scenario YAML file; with `name`, a file of named scenarios
    (name -> scenario) to take `name` from. Without either, the shipped
    default (DEFAULT_SCENARIO_NAME in SCENARIOS_PATH); `name` alone is one of
    SCENARIOS_PATH. text: YAML text (a flow mapping, say) whose fields
    replace the loaded scenario's, mappings merged key by key. names: what
    an InputError calls path, name and text (default: the flags)."""
    path_name, name_name, text_name = names
    if path is None:
        path, name = SCENARIOS_PATH, name or DEFAULT_SCENARIO_NAME
    path = Path(path)
    if not path.exists():
        raise field_error(path_name, str(path), "an existing YAML file")
    where = str(path)
    data = load_yaml(path, "YAML scenario file", tags=True)
    if name is not None:
        if not isinstance(data, dict) or name not in data:
            scenarios = list(data) if isinstance(data, dict) else []
            raise field_error(name_name, name, f"one of {scenarios[:20]} "
                                               f"(the scenarios in {path})")
        data, where = data[name], f"{path}: {name}"
    data = _checked(data, where)
    if text is not None:
        try:
            override = parse_yaml(text, tags=True)
        except InputError as e:
            raise InputError(f"{text_name}: {e}") from None
        data = _merged(data, _checked(override, text_name))
        where += f" with {text_name}"
    try:
        # The data as parsed above (1e5 a number), not the file again.
        scenario = yaml_load_typed(schema=Scenario, data=dump_yaml(data))
    except Exception as e:  # pydrake: RuntimeError/TypeError/yaml errors.
        first = (str(e).strip().splitlines()[0][:200] if str(e).strip()
                 else repr(e))
        raise InputError(f"{where}: {first}") from None
    try:
        return validate(scenario)
    except InputError as e:
        raise InputError(f"{where}: {e}") from None


# Deprecated names of moved fields, still read: (section, old) -> new path.
_ALIASES = {(None, "time_step_s"): ("plant_config", "time_step"),
            ("contact", "discrete_contact_approximation"):
                ("plant_config", "discrete_contact_approximation")}


def _checked(data, where: str) -> dict:
    """Parsed scenario YAML (None: an empty document, the defaults) with the
    deprecated names moved to their fields, checked against the schema
    (`check_schema`); InputError prefixed with `where`."""
    if data is None:
        return {}
    try:
        if isinstance(data, dict):
            data = dict(data)
            for (section, old), (new_section, new) in _ALIASES.items():
                holder = data if section is None else data.get(section)
                if not isinstance(holder, dict) or old not in holder:
                    continue
                if section is not None:
                    holder = data[section] = dict(holder)
                target = data.get(new_section)
                target = data[new_section] = (
                    dict(target) if isinstance(target, dict) else {})
                if new in target:
                    shown = f"{section}.{old}" if section else old
                    raise InputError(f"{shown}: the old name of "
                                     f"{new_section}.{new}, given with it")
                target[new] = holder.pop(old)
        # The loader's own messages do not name the section of a field.
        check_schema(data, Scenario, "")
    except InputError as e:
        raise InputError(f"{where}: {e}") from None
    return data


def _merged(base: dict, override: dict) -> dict:
    """`override`'s fields over `base`'s, mappings merged key by key."""
    merged = dict(base)
    for key, value in override.items():
        old = merged.get(key)
        if (isinstance(old, dict) and isinstance(value, dict)
                and not isinstance(old, Tagged)
                and not isinstance(value, Tagged)):
            value = _merged(old, value)
        merged[key] = value
    return merged


def merged_text(text: str, over: str) -> str:
    """YAML text: `over`'s fields over `text`'s, mappings merged key by key
    (as load_scenario merges its text over the scenario)."""
    return dump_yaml(_merged(parse_yaml(text, tags=True) or {},
                             parse_yaml(over, tags=True) or {}))


def with_time_step(scenario: Scenario, time_step_s: float) -> Scenario:
    """A validated copy of `scenario` whose plant steps by time_step_s
    through the throw (the catch's step, catch_time_step_s, unchanged; null
    if it would be finer than the throw's)."""
    copied = copy.deepcopy(scenario)
    copied.plant_config.time_step = float(time_step_s)
    for name in ("catch_time_step_s", "target_catch_time_step_s"):
        step = getattr(copied, name)
        if time_step_s == 0.0 or (step is not None and step < time_step_s):
            setattr(copied, name, None)
    return validate(copied)


def with_catch_time_step(scenario: Scenario, time_step_s: float) -> Scenario:
    """A validated copy of `scenario` whose plant steps by time_step_s from
    the throw's end on (catch_time_step_s, under a target too)."""
    copied = copy.deepcopy(scenario)
    copied.catch_time_step_s = float(time_step_s)
    copied.target_catch_time_step_s = None
    return validate(copied)


def catch_step_s(scenario: Scenario) -> float | None:
    """The plant's step from the release time on: under a grasp target,
    target_catch_time_step_s (when set), else catch_time_step_s (None: the
    throw's step throughout)."""
    if (scenario.regrasp.target != "any"
            and scenario.target_catch_time_step_s is not None
            and scenario.catch_time_step_s is not None):
        return scenario.target_catch_time_step_s
    return scenario.catch_time_step_s


def hands_over(scenario: Scenario) -> bool:
    """Whether an episode goes on at another plant step from the release
    time (`catch_step_s`; see catch_phase_scenario)."""
    step = catch_step_s(scenario)
    return step is not None and step != scenario.plant_config.time_step


def lands_at_own_step(scenario: Scenario) -> bool:
    """Whether a catching episode goes on at landing_time_step_s through the
    landing: under a grasp target, at a step other than the catch's."""
    step = scenario.landing_time_step_s
    catch = catch_step_s(scenario) or scenario.plant_config.time_step
    return (step is not None and step != catch and catch != 0.0
            and scenario.regrasp.target != "any")


def landing_phase_scenario(scenario: Scenario) -> Scenario | None:
    """The scenario a catching episode goes on under through the landing:
    the plant at landing_time_step_s; None when it has no step of its
    own."""
    if not lands_at_own_step(scenario):
        return None
    copied = copy.deepcopy(scenario)
    copied.plant_config.time_step = scenario.landing_time_step_s
    copied.catch_time_step_s = None
    copied.target_catch_time_step_s = None
    copied.landing_time_step_s = None
    return copied


def catch_phase_scenario(scenario: Scenario) -> Scenario | None:
    """The scenario an episode goes on under from the release time: the
    plant at `catch_step_s`; None when that is the throw's step."""
    if not hands_over(scenario):
        return None
    copied = copy.deepcopy(scenario)
    copied.plant_config.time_step = catch_step_s(scenario)
    return copied


def scenario_yaml(scenario: Scenario) -> str:
    """Every value of the scenario, as YAML. Drake's dump leaves out a null
    field, which a load would give its default: a top-level field null
    where its default is not (a step handed over to none) is written out,
    after the rest."""
    text = yaml_dump_typed(scenario, schema=Scenario)
    return text + "".join(
        f"{f.name}: null\n" for f in dc.fields(Scenario)
        if getattr(scenario, f.name) is None and f.default is not None)


def scenario_digest(scenario: Scenario) -> str:
    """A short sha256 of every value of the scenario: equal digests, same throw
    and same catch machinery. A scenario aiming for no target (regrasp at
    its defaults, `any`) digests as it did before the field existed, and
    without the landing's fields, so that the results recorded then still
    match it. Kept by the scenario's
    repr (every value, nested, Drake's configs included: a twentieth of the
    YAML's cost; scenarios equal in repr are equal in YAML)."""
    def compute():
        text = scenario_yaml(scenario)
        if scenario.regrasp == RegraspConfig():
            # Nor do the landing's fields, which only a target reads.
            text = re.sub(
                r"(?m)^(landing_\w+|target_catch_time_step_s): .*\n", "",
                text[:text.rindex("regrasp:\n")])
            # Nor the follow's, which is off under "any".
            text = re.sub(r"(?m)^  follow_\w+: .*\n", "", text)
        # The fingers' closing order at its default, "together", digests
        # as before the field existed, under any target.
        text = text.replace("\n  closing_order: together\n", "\n")
        return hashlib.sha256(text.encode()).hexdigest()[:16]
    # NumPy's arrays (Drake's transforms in the directives) in full: every
    # float as the shortest text that reads back the same, none elided.
    with np.printoptions(floatmode="unique", threshold=sys.maxsize):
        key = repr(scenario)
    return _DIGESTS.get(key, compute)


_DIGESTS = memo.Memo("scenario digests")
