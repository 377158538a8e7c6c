"""The PUMA 560 arm and the five-fingered hand: model files, names, poses and plants.

The models live in the repository's `sdf/` folder (package `regrasp_drake`):
`puma560.sdf` (standard-DH link frames, published masses and inertias, the paper's
servo torque limits), `hand.sdf` (10-DOF hand, in-plant PD finger servos) and
`puma560_hand.dmd.yaml` (arm welded to the world, palm welded to link6: the
scenario's default `directives`). See `sdf/README.md` for sources and choices.
"""

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
from pydrake.common.yaml import yaml_dump_typed
from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import (
    LoadModelDirectives,
    ModelDirective,
    ModelDirectives,
    Parser,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from regrasp_drake import memo
from regrasp_drake.paths import SDF_DIR

PACKAGE_NAME = "regrasp_drake"
PUMA_SDF = SDF_DIR / "puma560.sdf"
HAND_SDF = SDF_DIR / "hand.sdf"
ROBOT_DIRECTIVES = SDF_DIR / "puma560_hand.dmd.yaml"

ARM_MODEL_NAME = "puma560"
HAND_MODEL_NAME = "hand"

ARM_JOINTS = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
# Servo torque limits of the paper (section III.A), N·m.
ARM_EFFORT_LIMITS = np.array([150.0, 186.4, 89.4, 24.2, 20.1, 21.3])

FINGERS = ("thumb", "index", "middle", "ring", "little")
# Joint names in the order of the hand's actuators: knuckle (j1) then distal (j2).
HAND_JOINTS = tuple(f"{f}_j{k}" for f in FINGERS for k in (1, 2))
# The orders the fingers can close in (catch.closing_order): all at once,
# the thumb's two joints before the other fingers start, or after they end.
CLOSING_ORDERS = ("together", "thumb_first", "fingers_first")
# The bodies of each finger, proximal first.
FINGER_LINKS = {f: (f"{f}_proximal", f"{f}_distal") for f in FINGERS}
# The arm's bodies, base first (puma560.sdf).
ARM_LINKS = tuple(f"link{i}" for i in range(7))
# Every finger servo of the paper (section III.A), N·m.
FINGER_EFFORT_LIMIT = 10.0
# Finger joint speed limit, rad/s: 55 rev/min, the no-load speed of the ROBOTIS
# Dynamixel MX-106 (stall torque 10.0 N·m) at 14.8 V. Also each finger joint's
# <velocity> in hand.sdf. Drake does not enforce it: rate-limit finger commands.
FINGER_MAX_SPEED = 55.0 * 2.0 * np.pi / 60.0

# Named arm poses of the literature (Corke), rad.
QZ = np.zeros(6)  # upper arm horizontal along +x, forearm up
QR = np.array([0.0, np.pi / 2, -np.pi / 2, 0.0, 0.0, 0.0])  # arm straight up
QS = np.array([0.0, 0.0, -np.pi / 2, 0.0, 0.0, 0.0])  # arm stretched along +x
QN = np.array([0.0, np.pi / 4, np.pi, 0.0, np.pi / 4, 0.0])  # nominal, wrist down

# Finger joint positions, rad, in HAND_JOINTS order. Open: every finger straight in
# the palm plane. Closed: the position command of an envelope grasp, just short of
# the 1.6 rad flexion limit. Unobstructed, the phalanges would pass 2–3 cm inside
# the surface of a 6 cm cylinder lying across the palm, so a held object of 5–12 cm
# is wrapped and squeezed by the PD servos rather than merely touched.
HAND_OPEN = np.zeros(len(HAND_JOINTS))
HAND_CLOSED = np.full(len(HAND_JOINTS), 1.55)


@dataclass(frozen=True)
class RobotInstances:
    """The model instances of the PUMA arm and of the hand in one plant."""

    arm: ModelInstanceIndex
    hand: ModelInstanceIndex


@memo.lru_cache("arm joint limits")
def arm_joint_limits() -> tuple[tuple[float, float], ...]:
    """The six arm joints' position limits (lower, upper), rad, joint1 first,
    as puma560.sdf states them (read from the file, no plant built)."""
    joints = {j.get("name"): j for j in ET.parse(PUMA_SDF).iter("joint")}
    return tuple(
        (float(joints[f"joint{i}"].find("axis/limit/lower").text),
         float(joints[f"joint{i}"].find("axis/limit/upper").text))
        for i in range(1, 7))


def add_package_map(parser: Parser) -> None:
    """Registers sdf/package.xml so `package://regrasp_drake/...` URIs resolve."""
    package_map = parser.package_map()
    if not package_map.Contains(PACKAGE_NAME):
        package_map.AddPackageXml(str(SDF_DIR / "package.xml"))


def _parser(plant: MultibodyPlant) -> Parser:
    parser = Parser(plant)
    add_package_map(parser)
    return parser


def add_puma(plant: MultibodyPlant) -> ModelInstanceIndex:
    """Adds the PUMA 560 alone, its link0 welded to the world origin."""
    (arm,) = _parser(plant).AddModels(str(PUMA_SDF))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("link0", arm))
    return arm


def add_hand(
    plant: MultibodyPlant, X_WP: RigidTransform = RigidTransform()
) -> ModelInstanceIndex:
    """Adds the hand alone, its palm frame P welded to the world at X_WP."""
    (hand,) = _parser(plant).AddModels(str(HAND_SDF))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("palm", hand), X_WP)
    return hand


def robot_directives() -> list[ModelDirective]:
    """The shipped robot's model directives, sdf/puma560_hand.dmd.yaml (the
    hand mount transform lives there)."""
    return list(LoadModelDirectives(str(ROBOT_DIRECTIVES)).directives)


def add_puma_and_hand(
    plant: MultibodyPlant, directives: list[ModelDirective] | None = None
) -> RobotInstances:
    """Adds the robot by its model directives (default: robot_directives(),
    the PUMA welded to the world and the hand welded to its link6), which
    must add the models "puma560" and "hand"."""
    if directives is None:
        directives = robot_directives()
    ProcessModelDirectives(ModelDirectives(directives=directives), plant,
                           _parser(plant))
    return RobotInstances(
        arm=plant.GetModelInstanceByName(ARM_MODEL_NAME),
        hand=plant.GetModelInstanceByName(HAND_MODEL_NAME),
    )


def directives_yaml(directives: list[ModelDirective] | None) -> str:
    """The directives as YAML text (default: robot_directives()): Drake's
    directive structs compare by identity, their text by value."""
    if directives is None:
        directives = robot_directives()
    return yaml_dump_typed(ModelDirectives(directives=list(directives)))


def make_arm_control_plant(
    directives: list[ModelDirective] | None = None,
) -> MultibodyPlant:
    """Returns a finalized continuous-time arm-only plant (nq = nv = 6) for
    InverseDynamicsController and the inverse kinematics, from the robot's
    model directives (default: robot_directives()).

    The arm is added and placed as the directives say; the hand is one rigid
    body "hand", welded to the arm frame the directives weld the hand to,
    that carries the whole hand's mass and composite inertia about that
    frame, computed from the full hand model at HAND_OPEN, so the controller
    compensates the hand's weight and inertia. Reflected rotor inertias of
    the arm are included (parsed from the same SDF).
    """
    if directives is None:
        directives = robot_directives()
    full = MultibodyPlant(time_step=0.0)
    robot = add_puma_and_hand(full, directives)
    full.Finalize()
    context = full.CreateDefaultContext()
    full.SetPositions(context, robot.hand, HAND_OPEN)
    # The arm's frame F that carries the hand (link6 for the shipped robot).
    hand_prefix = f"{HAND_MODEL_NAME}::"
    arm_prefix = f"{ARM_MODEL_NAME}::"
    mounts = [d.add_weld.parent for d in directives
              if d.add_weld and d.add_weld.child.startswith(hand_prefix)]
    if len(mounts) != 1 or not mounts[0].startswith(arm_prefix):
        raise ValueError(f"model directives: the hand is welded to {mounts}, "
                         f"expected one frame of the arm ({arm_prefix}...)")
    mount_frame = full.GetFrameByName(mounts[0][len(arm_prefix):], robot.arm)
    # M_HF_F: the hand's spatial inertia about F's origin, expressed in F.
    M_HF_F = full.CalcSpatialInertia(
        context, mount_frame, full.GetBodyIndices(robot.hand))

    # The same directives without the hand and its weld.
    arm_only = [d for d in directives
                if not (d.add_model and d.add_model.name == HAND_MODEL_NAME)
                and not (d.add_weld
                         and d.add_weld.child.startswith(hand_prefix))]
    plant = MultibodyPlant(time_step=0.0)
    ProcessModelDirectives(ModelDirectives(directives=arm_only), plant,
                           _parser(plant))
    arm = plant.GetModelInstanceByName(ARM_MODEL_NAME)
    hand_body = plant.AddRigidBody("hand", arm, M_HF_F)
    plant.WeldFrames(
        plant.GetFrameByName(mount_frame.name(), arm), hand_body.body_frame(),
        RigidTransform())
    plant.Finalize()
    return plant


# Arm control plants by their directives' YAML text.
_ARM_CONTROL_PLANTS: dict[str, MultibodyPlant] = {}


def arm_control_plant(
    directives: list[ModelDirective] | None = None,
) -> MultibodyPlant:
    """make_arm_control_plant(directives), built once per directives and
    shared (a station's controller and the inverse kinematics only read
    it)."""
    key = directives_yaml(directives)
    if key not in _ARM_CONTROL_PLANTS:
        _ARM_CONTROL_PLANTS[key] = make_arm_control_plant(directives)
    return _ARM_CONTROL_PLANTS[key]


def exclude_robot_self_collisions(
    plant: MultibodyPlant, scene_graph: SceneGraph
) -> None:
    """Filters out every collision between two geometries of the arm and the hand.

    Arm and hand geometries still collide with everything else (object, ground).
    Acts on the instances named "puma560" and "hand" that are present (either or
    both). Call after the robot is added (before or after Finalize) and before any
    diagram context is created: it edits the SceneGraph model, not a context.
    """
    geometries = []
    for name in (ARM_MODEL_NAME, HAND_MODEL_NAME):
        if plant.HasModelInstanceNamed(name):
            instance = plant.GetModelInstanceByName(name)
            for index in plant.GetBodyIndices(instance):
                geometries += plant.GetCollisionGeometriesForBody(plant.get_body(index))
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(GeometrySet(geometries))
    )
