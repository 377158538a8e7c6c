"""One episode's diagram and its simulator: the station (station/station.py)
and the catch controller (station/catch_controller.py) wired top to bottom
with the loggers and Meshcat, and where the episode starts
(`build_episode_diagram`); a simulator at those initial conditions
(`initialize`); and the same state gone on with in a diagram built for
another plant step (`continue_with`, the handover at the release time). The
station keeps the hardware; what one episode is, is here."""

import dataclasses as dc

from pydrake.geometry import (
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import (
    ApplySimulatorConfig,
    InitializeParams,
    Simulator,
)
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.catch_controller import (
    CatchController,
    add_catch_controller,
)
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.mlp_system import CatchMlp, MlpSystem
from regrasp_drake.station.scenario import Scenario, hands_over
from regrasp_drake.station.start_pose import start_poses_on
from regrasp_drake.station.station import Station, add_station
from regrasp_drake.world import robot
from regrasp_drake.world.object_model import ObjectSpec


@dc.dataclass
class Loggers:
    """Signals logged at the sensors' rate."""
    object: VectorLogSink      # the object's state (13)
    ir: VectorLogSink          # the infrared levels (13)
    bumper: VectorLogSink      # (1)
    phase: VectorLogSink       # the state machine's phase (1)
    actuation: VectorLogSink   # the plant's net actuation (16), [N·m]
    arm: VectorLogSink         # the arm's state (12)
    params: VectorLogSink      # (h_catch, h_down), [m]


@dc.dataclass
class EpisodeDiagram:
    """One episode's diagram: the station, the catch controller wired to
    its ports, the loggers and Meshcat; and where the episode starts."""
    diagram: Diagram
    station: Station
    controller: CatchController
    loggers: Loggers
    meshcat: Meshcat | None
    # Before the throw (start_pose.start_poses_on): the palm (its
    # palm_surface frame) at the throw's start pose, and the object lying
    # in it.
    X_WP_initial: RigidTransform
    X_WO_initial: RigidTransform


def fixed_catch_parameters(scenario: Scenario, X_WG: RigidTransform | None,
                           catch_parameters=None, mlp_features=None):
    """The (h_catch, h_down) an episode's diagram holds fixed, [m]: those
    given; else, on a watching throw, or without `mlp_features` when the
    scenario's catch.parameter_source is "fixed", the scenario's
    catch.h_catch_m and h_down_m; else None (the MLP system predicts
    them from `mlp_features`)."""
    if catch_parameters is None and (
            X_WG is None or (mlp_features is None and
                             scenario.catch.parameter_source == "fixed")):
        return (scenario.catch.h_catch_m, scenario.catch.h_down_m)
    return catch_parameters


def build_episode_diagram(scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                          X_WG: RigidTransform | None, catch_parameters=None,
                          mlp_features=None, model: CatchMlp | None = None,
                          meshcat: Meshcat | None = None,
                          perturbation: ThrowPerturbation = ThrowPerturbation()
                          ) -> EpisodeDiagram:
    """One episode's diagram: the station, the catch controller wired to
    its ports, the loggers, Meshcat when asked; and the palm's and the
    object's poses before the throw.

    X_WG: the palm's grasp pose; None makes a watching throw (no catch).
    catch_parameters: (h_catch, h_down) in m, or None: the MLP system's
    grid cell for `mlp_features` (v_catch, h_cm, r_cm, d_obj, v_conv), with
    the network `model` (None: the scenario's catch.weights); without
    features, the scenario's fixed values unless its
    `catch.parameter_source` is "mlp" (fixed_catch_parameters).
    perturbation: this throw's release noise (ThrowPerturbation.draw from
    the scenario's throw.noise and the throw's number; default none).
    """
    catch_parameters = fixed_catch_parameters(scenario, X_WG, catch_parameters,
                                              mlp_features)
    builder = DiagramBuilder()
    # The station: plant, sensors, finger servos, arm controller.
    station = add_station(builder, scenario, obj)
    # The catch controller, wired to the station's ports; its arm IK is the
    # station's robot's.
    if robot.directives_yaml(ik.directives) != robot.directives_yaml(
            scenario.directives):
        raise ValueError("build_episode_diagram: the ArmIk was built for "
                         "other directives than the scenario's; expected "
                         "ArmIk(scenario.directives)")
    controller = add_catch_controller(
        builder, station, scenario, obj, ik=ik, X_WG=X_WG,
        catch_parameters=catch_parameters, mlp_features=mlp_features,
        model=model, perturbation=perturbation)
    # Where the episode starts: the object lying in the open palm.
    X_WP_initial, X_WO_initial = start_poses_on(
        station.plant, station.arm, station.hand, obj, scenario)
    # Loggers, sampled at the sensors' rate.
    loggers = add_loggers(builder, station, controller,
                          scenario.sensors.period_s)
    # Meshcat, when asked (loopback only; see replay.make_meshcat).
    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(
            builder, station.GetOutputPort("query_object"), meshcat,
            MeshcatVisualizerParams(publish_period=1 / 60))
    # The episode's own ports, then the diagram, named.
    export_episode_ports(builder, station, controller)
    diagram = builder.Build()
    diagram.set_name("episode")
    return EpisodeDiagram(diagram=diagram, station=station,
                          controller=controller, loggers=loggers,
                          meshcat=meshcat, X_WP_initial=X_WP_initial,
                          X_WO_initial=X_WO_initial)


# The episode diagram's output ports: the station's of its own name, and
# the catch controller's.
EPISODE_STATION_OUTPUTS = ("object_state", "arm_state", "hand_state",
                           "ir_levels", "bumper", "contact_results",
                           "query_object")


def export_episode_ports(builder: DiagramBuilder, station: Station,
                         controller: CatchController) -> None:
    """Exports the episode's output ports from `builder`:
    EPISODE_STATION_OUTPUTS (the station's), `phase` (the catch state
    machine's, catch_state_machine.Phase), `catch_parameters` (h_catch,
    h_down, [m], from the parameters' source) and `monitor_state` (the
    grasp monitor's, GraspMonitor). It has no input port: what an episode
    is to do is set in its context (CatchController.set_task)."""
    for name in EPISODE_STATION_OUTPUTS:
        builder.ExportOutput(station.GetOutputPort(name), name)
    builder.ExportOutput(controller.state_machine.GetOutputPort("phase"),
                         "phase")
    builder.ExportOutput(controller.parameters.get_output_port(),
                         "catch_parameters")
    builder.ExportOutput(
        controller.monitor.GetOutputPort("monitor_state"), "monitor_state")


def add_loggers(builder: DiagramBuilder, station: Station,
                controller: CatchController, period_s: float) -> Loggers:
    """Adds the loggers to `builder`: the station's and the catch
    controller's signals, sampled every `period_s`, [s]."""
    def log(port):
        return LogVectorOutput(port, builder, period_s)
    out = station.GetOutputPort
    return Loggers(
        object=log(out("object_state")), ir=log(out("ir_levels")),
        bumper=log(out("bumper")),
        phase=log(controller.state_machine.GetOutputPort("phase")),
        actuation=log(out("net_actuation")), arm=log(out("arm_state")),
        params=log(controller.parameters.get_output_port()))


def initialize(episode: EpisodeDiagram, scenario: Scenario) -> Simulator:
    """A simulator at the episode's initial conditions (identical each time):
    the arm at the throw's start pose, the hand open, the object lying in
    the palm (EpisodeDiagram.X_WO_initial); integrating as the scenario's
    simulator_config says."""
    simulator = Simulator(episode.diagram)
    ApplySimulatorConfig(scenario.simulator_config, simulator)
    station = episode.station
    plant = station.plant
    plant_context = plant.GetMyMutableContextFromRoot(
        simulator.get_mutable_context())
    plant.SetPositions(plant_context, station.arm,
                       throw.start_q(scenario.throw))
    plant.SetPositions(plant_context, station.hand, robot.HAND_OPEN)
    plant.SetFreeBodyPose(plant_context, station.object_body,
                          episode.X_WO_initial)
    if hand_idle_until_handover(scenario):
        lock_hand(plant, plant_context, station.hand)
    simulator.Initialize()
    return simulator


def hand_idle_until_handover(scenario: Scenario) -> bool:
    """Whether the fingers hold still, open, from the start to the release
    time's handover to the catch's plant step (episode.hand_over): the palm
    toss without release noise (a noisy throw may end, and the fingers
    start to pre-shape, before it), handed over at the release time
    (catch_time_step_s). Their joints are then locked through the throw
    (`lock_hand`): no finger touches the tossed object, and SAP leaves
    locked joints out of its solve. The catch's diagram, which the
    handover builds, starts with them free (continue_with copies the
    plant's state, not its parameters, where Drake keeps the locks)."""
    return (throw.is_toss(scenario.throw)
            and scenario.throw.noise.is_zero()
            and hands_over(scenario))


def lock_hand(plant: MultibodyPlant, plant_context, hand) -> None:
    """Locks every joint of the hand in plant_context (Joint::Lock: its
    velocity zeroed, the joint held where it is)."""
    for index in plant.GetJointIndices(hand):
        plant.get_joint(index).Lock(plant_context)


# How Drake says its contact solver or integrator failed: a RuntimeError
# whose message starts with one of these (SAP's and TAMSI's discrete
# updates, multibody/plant; CENIC's convex solve, multibody/cenic; an
# error-controlled integrator's step shrunk below its minimum,
# systems/analysis/integrator_base). That failure is what the simulated
# world did: the episode's outcome "failed". Any other exception is a bug
# and propagates.
SOLVER_FAILURES = (
    "The SAP solver failed to converge",
    "MultibodyPlant's discrete update solver failed to converge",
    "CenicIntegrator: optimization failed",
    "Error control wants to select step smaller than minimum allowed",
)


def is_solver_failure(error: BaseException) -> bool:
    """Whether `error` is Drake's contact solver or integrator failing
    (SOLVER_FAILURES)."""
    return (isinstance(error, RuntimeError)
            and str(error).lstrip().startswith(SOLVER_FAILURES))


def advance_to_outcome(simulator, episode: EpisodeDiagram, scenario,
                       t_final=None) -> str:
    """Advances until the grasp monitor (or a failure) ends the episode, or
    to t_final. Returns "" or the failure's message: an unreachable pose
    (the state machine's), or the first line of Drake's contact solver or
    integrator failure (`is_solver_failure`: recorded, not raised). Every
    other exception propagates."""
    if t_final is None:
        t_final = scenario.monitor.max_time_s + 1.0
    try:
        status = simulator.AdvanceTo(t_final)
    except RuntimeError as e:
        if not is_solver_failure(e):
            raise
        return str(e).strip().splitlines()[0]
    # An unreachable pose.
    if status.system() is episode.controller.state_machine:
        return status.message()
    return ""


def leaf_systems(diagram: Diagram):
    """The systems of `diagram` and of the diagrams nested in it (the
    station's, the arm controller's), depth first, in their diagrams'
    order: the systems that hold state."""
    for system in diagram.GetSystems():
        if isinstance(system, Diagram):
            yield from leaf_systems(system)
        else:
            yield system


def continue_with(simulator: Simulator, episode: EpisodeDiagram,
                  other: EpisodeDiagram, scenario: Scenario) -> Simulator:
    """A simulator of `other`, an episode diagram built like `episode` but
    for `scenario` (another plant time step, say), at `simulator`'s time and
    state: the plant's, the controller's and every system's of ours.
    SceneGraph's state is not copied (it holds the other diagram's geometry
    ids; its poses follow the plant's state). Continuing with `other` built
    for the same scenario reproduces `simulator`'s run bit for bit."""
    source = simulator.get_context()
    target = Simulator(other.diagram)
    ApplySimulatorConfig(scenario.simulator_config, target)
    context = target.get_mutable_context()
    context.SetTime(source.get_time())
    # The catch parameters' sources are paired apart: a catch whose MLP
    # predicts them may go on from a throw that held them fixed (a kept
    # throw, ThrowCache); its MLP then predicts them here.
    sources = [c.parameter_systems() for c in (episode.controller,
                                               other.controller)]
    pairs = list(zip(*[[s for s in leaf_systems(e.diagram)
                        if not any(s is p for p in kept)]
                       for e, kept in zip((episode, other), sources)],
                     strict=True))
    predict = None
    if [type(s) for s in sources[0]] == [type(s) for s in sources[1]]:
        pairs += zip(*sources)
    else:
        predict = other.controller.parameters
    for a, b in pairs:
        if type(a) is not type(b):
            raise ValueError(f"continue_with: {a.get_name()} and "
                             f"{b.get_name()}: not diagrams built alike")
        if isinstance(a, SceneGraph):
            continue
        context_a = a.GetMyContextFromRoot(source)
        context_b = b.GetMyMutableContextFromRoot(context)
        for i in range(context_a.num_discrete_state_groups()):
            value = context_a.get_discrete_state(i).value()
            # The catch state machine's table of references (computed at
            # the other plant step) is made again by `continue_at`, below;
            # a group of another size is left to it.
            if context_b.get_discrete_state(i).size() == value.size:
                context_b.SetDiscreteState(i, value)
        for i in range(context_a.num_abstract_states()):
            context_b.get_mutable_abstract_state(i).SetFrom(
                context_a.get_abstract_state(i))
        if context_a.num_continuous_states():
            context_b.SetContinuousState(
                context_a.get_continuous_state_vector().CopyToVector())
        if isinstance(a, MultibodyPlant):
            continue  # its parameters are the model's, built alike
        # Our systems' parameters: the catch parameters and the grasp pose,
        # which may have been set in the running context.
        for i in range(context_a.num_numeric_parameter_groups()):
            context_b.get_mutable_numeric_parameter(i).SetFromVector(
                context_a.get_numeric_parameter(i).get_value())
        for i in range(context_a.num_abstract_parameters()):
            context_b.get_mutable_abstract_parameter(i).SetFrom(
                context_a.get_abstract_parameter(i))
    # The catch state machine counts plant steps to find the sensors'
    # samples: count them at the other plant's step (unchanged at the same
    # step).
    machine = other.controller.state_machine
    machine.continue_at(machine.GetMyMutableContextFromRoot(context))
    if isinstance(predict, MlpSystem):
        predict.ExecuteInitializationEvents(
            predict.GetMyMutableContextFromRoot(context))
    # The state is already the one to go on from: no initialization events.
    target.Initialize(InitializeParams(suppress_initialization_events=True))
    return target

