"""The catch controller (`add_catch_controller`), built apart from the
station (station/station.py) and wired to its named ports, as a controller
is to a hardware station: the palm's grasp pose, the source of the catch
parameters (fixed, or the MLP), the catch state machine (Fig. 9) and the
grasp monitor (paper §V.B). What it is to do in an episode (its task) can
be set in a running context (`CatchController.set_task`)."""

import dataclasses as dc

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource

from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.follow import FOLLOW_SIZE, NO_FOLLOW
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import (
    CatchStateMachine,
    ThrowPerturbation,
)
from regrasp_drake.station.grasp_monitor import GraspMonitor
from regrasp_drake.station.mlp_system import CatchMlp, MlpSystem, load_weights
from regrasp_drake.station.scenario import Scenario
from regrasp_drake.station.station import Station
from regrasp_drake.world import robot
from regrasp_drake.world.object_model import ObjectSpec


class GraspPoseSource(LeafSystem):
    """Outputs the palm's grasp pose X_WG and how the palm follows the
    object (`palm_follow`: the catch moment and the palm's twist there,
    planning/follow.py; zeros, no follow), kept as parameters so that they
    can be set in a running simulation's context (`set_pose`,
    `set_follow`): a catch planned when the object is seen leaving the hand
    (`episode.episode.run_episode`'s `at_release`)."""

    def __init__(self, X_WG: RigidTransform):
        LeafSystem.__init__(self)
        self._index = self.DeclareAbstractParameter(AbstractValue.Make(X_WG))
        self.DeclareAbstractOutputPort(
            "X_WG", lambda: AbstractValue.Make(RigidTransform()),
            lambda context, out: out.set_value(
                context.get_abstract_parameter(self._index).get_value()))
        self._follow = self.DeclareNumericParameter(BasicVector(NO_FOLLOW))
        self.DeclareVectorOutputPort(
            "palm_follow", FOLLOW_SIZE,
            lambda context, out: out.SetFromVector(
                context.get_numeric_parameter(self._follow).get_value()))

    def set_pose(self, context, X_WG: RigidTransform) -> None:
        """Sets the pose in this system's context."""
        context.get_mutable_abstract_parameter(self._index).set_value(X_WG)

    def set_follow(self, context, follow) -> None:
        """Sets the follow (FOLLOW_SIZE values) in this system's
        context."""
        context.get_mutable_numeric_parameter(self._follow).SetFromVector(
            np.asarray(follow, float))


@dc.dataclass
class CatchController:
    """The catch controller's systems, wired to a station's ports."""
    state_machine: CatchStateMachine
    monitor: GraspMonitor
    grasp_pose: GraspPoseSource
    # The catch parameters' source: fixed (its value settable in a context),
    # or the MLP system (the network's grid cell).
    parameters: ConstantVectorSource | MlpSystem
    # The MLP's features (v_catch, h_cm, r_cm, d_obj, v_conv); None when
    # fixed.
    features: ConstantVectorSource | None = None

    def parameter_systems(self) -> list:
        """The systems of the catch parameters' source."""
        return [s for s in (self.parameters, self.features) if s is not None]

    def set_task(self, root_context, *, X_WG: RigidTransform | None = None,
                 catch_parameters=None, watching: bool | None = None,
                 follow=None) -> None:
        """Sets what this episode does in the diagram's context
        `root_context`, before the state machine reads it (at the release
        time: X_WG and whether it watches; at the trigger: the parameters):
        the palm's grasp pose X_WG, the fixed catch parameters (h_catch,
        h_down), [m], `watching` (a watching throw parks the arm and
        never catches) and `follow`, how the palm follows the object
        (planning/follow.plan_follow). None leaves a value as it is. The one place an
        episode's task is written into a running context (a kept throw going
        on as another episode, a catch planned at the release, a forked
        cell)."""
        if watching is not None:
            for system in (self.state_machine, self.monitor):
                system.set_watching(
                    system.GetMyMutableContextFromRoot(root_context), watching)
        if X_WG is not None:
            self.grasp_pose.set_pose(
                self.grasp_pose.GetMyMutableContextFromRoot(root_context),
                X_WG)
        if follow is not None:
            self.grasp_pose.set_follow(
                self.grasp_pose.GetMyMutableContextFromRoot(root_context),
                follow)
        if catch_parameters is not None:
            if not isinstance(self.parameters, ConstantVectorSource):
                raise ValueError("set_task: the catch parameters come from "
                                 "the MLP system in this diagram; expected "
                                 "fixed ones")
            source = self.parameters
            source.get_mutable_source_value(
                source.GetMyMutableContextFromRoot(root_context)
            ).SetFromVector(list(catch_parameters))


def add_catch_controller(builder: DiagramBuilder, station: Station,
                         scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                         X_WG: RigidTransform | None, catch_parameters=None,
                         mlp_features=None, model: CatchMlp | None = None,
                         perturbation: ThrowPerturbation = ThrowPerturbation()
                         ) -> CatchController:
    """Adds the catch controller to `builder` and wires it to `station`
    (added to the same builder): the grasp pose, the catch parameters'
    source, the catch state machine (Fig. 9) and the grasp monitor (paper
    §V.B), which stops the simulation at the outcome. Arguments as
    `build_episode_diagram`'s."""
    # The palm's grasp pose, settable in a running context.
    grasp = builder.AddNamedSystem("X_WG", GraspPoseSource(
        X_WG if X_WG is not None else RigidTransform()))
    # The catch parameters: fixed, or the grid cell the MLP predicts (with
    # the caller's network; by default the scenario's catch.weights).
    features = None
    if catch_parameters is not None:
        params = builder.AddNamedSystem(
            "catch_parameters", ConstantVectorSource(list(catch_parameters)))
    else:
        if model is None:
            model, _ = load_weights(MODELS_DIR / scenario.catch.weights)
        params = builder.AddNamedSystem("mlp",
                                        MlpSystem(model, grid_cells=True))
        features = builder.AddNamedSystem(
            "features", ConstantVectorSource(list(mlp_features)))
        builder.Connect(features.get_output_port(), params.get_input_port())

    # The catch state machine (Fig. 9).
    # A watching throw parks the arm out of the flight's way (set_task
    # makes a diagram watch or catch).
    watching = X_WG is None
    q_park = throw.end_state(scenario.throw, ik)[0].copy()
    q_park[0] += scenario.throw.park_joint1_offset_rad
    machine = builder.AddNamedSystem("catch_state_machine", CatchStateMachine(
        scenario, ik, robot.HAND_OPEN, robot.HAND_CLOSED,
        robot.FINGER_MAX_SPEED, park_q=q_park, watching=watching,
        perturbation=perturbation))
    builder.Connect(grasp.GetOutputPort("X_WG"), machine.GetInputPort("X_WG"))
    builder.Connect(grasp.GetOutputPort("palm_follow"),
                    machine.GetInputPort("palm_follow"))
    builder.Connect(station.GetOutputPort("ir_levels"),
                    machine.GetInputPort("ir_levels"))
    builder.Connect(params.get_output_port(),
                    machine.GetInputPort("catch_parameters"))
    builder.Connect(station.GetOutputPort("arm_state"),
                    machine.GetInputPort("arm_state"))
    for name in ("arm_desired_state", "arm_desired_acceleration",
                 "hand_desired_state"):
        builder.Connect(machine.GetOutputPort(name),
                        station.GetInputPort(name))

    # The grasp monitor (paper §V.B); it stops the simulation at the outcome.
    plant = station.plant
    palm = plant.GetBodyByName("palm", station.hand)
    monitor = builder.AddNamedSystem("grasp_monitor", GraspMonitor(
        scenario, station.object_body.index(), palm.index(),
        plant.GetFrameByName("palm_surface", station.hand)
        .GetFixedPoseInBodyFrame(),
        obj.bounding_radius, watching=watching))
    for name in ("ir_levels", "bumper", "hand_state", "body_poses"):
        builder.Connect(station.GetOutputPort(name),
                        monitor.GetInputPort(name))
    builder.Connect(machine.GetOutputPort("hand_desired_state"),
                    monitor.GetInputPort("hand_desired_state"))
    builder.Connect(machine.GetOutputPort("phase"), monitor.GetInputPort("phase"))
    return CatchController(state_machine=machine, monitor=monitor,
                           grasp_pose=grasp, parameters=params,
                           features=features)
