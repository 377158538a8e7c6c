"""The throw-and-catch station, a Drake Diagram with named, exported ports
as manipulation's hardware stations are (`MakeStation`): PUMA 560 + hand +
object in a MultibodyPlant with point contact; the infrared sensors and the
tactile bumper; PD servos for the fingers (in the plant when it is
discrete; on a continuous plant, which Drake's in-plant PD does not
support, the same PD outside it, see add_finger_servos); an
inverse-dynamics controller for the arm on its own arm-only plant. The
hardware only: the catch controller wired to it is
station/catch_controller.py's; one episode's diagram, which wires the two
with the loggers and Meshcat, and its simulator are episode/diagram.py's.

A Drake user nests it in a diagram of their own and wires its ports:

    builder = DiagramBuilder()
    station = builder.AddSystem(MakeStation(scenario, obj))
    builder.Connect(my_controller.get_output_port(),
                    station.GetInputPort("arm_desired_state"))
"""

import dataclasses as dc

import numpy as np
from pydrake.geometry import (
    SceneGraph,
)
from pydrake.multibody.plant import (
    MultibodyPlant,
)
from pydrake.multibody.tree import (
    ModelInstanceIndex,
    PdControllerGains,
    RigidBody,
)
from pydrake.systems.controllers import (
    InverseDynamics,
    InverseDynamicsController,
)
from pydrake.systems.framework import (
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    OutputPort,
)
from pydrake.systems.primitives import (
    Adder,
    MatrixGain,
    Multiplexer,
)

from regrasp_drake.station.plant import add_world, bumper_geometry
from regrasp_drake.station.scenario import Scenario
from regrasp_drake.station.sensors import InfraredSensors, TactileBumper
from regrasp_drake.world import robot
from regrasp_drake.world.object_model import OBJECT_MODEL_NAME, ObjectSpec

_IR_FRAMES = [f"ir{i}" for i in range(1, 14)]


# The station's ports: (name, what flows through it).
STATION_INPUTS = {
    "arm_desired_state": "the arm's desired q, v (12)",
    "arm_desired_acceleration": "the arm's desired v̇ (6)",
    "hand_desired_state": "the finger joints' desired q, v (20)",
}
STATION_OUTPUTS = {
    "arm_state": "the arm's q, v (12)",
    "hand_state": "the hand's q, v (20)",
    "object_state": "quaternion wxyz, p_WO, w_WO, v_WO (13)",
    "body_poses": "every body's X_WB",
    "contact_results": "the plant's ContactResults",
    "net_actuation": "the plant's net actuation (16), [N·m]",
    "query_object": "SceneGraph's QueryObject",
    "ir_levels": "the 13 infrared levels",
    "bumper": "the tactile bumper (1)",
}


@dc.dataclass
class Station:
    """The station in a diagram: the Diagram `MakeStation` builds (or, for
    a continuous plant, its systems added flat, see `add_station`), its
    systems, and its ports by name (`GetInputPort(name)`,
    `GetOutputPort(name)`, as a Diagram's exported ports are read)."""
    plant: MultibodyPlant
    scene_graph: SceneGraph
    arm: ModelInstanceIndex
    hand: ModelInstanceIndex
    object_body: RigidBody
    infrared: InfraredSensors
    bumper: TactileBumper
    inputs: dict[str, InputPort]
    outputs: dict[str, OutputPort]
    # The station's own Diagram; None when added flat (a continuous plant).
    diagram: Diagram | None = None

    @classmethod
    def of(cls, diagram: Diagram) -> "Station":
        """The systems and ports of a Diagram that `MakeStation` built."""
        plant = diagram.GetSubsystemByName("plant")
        body = plant.get_body(plant.GetBodyIndices(
            plant.GetModelInstanceByName(OBJECT_MODEL_NAME))[0])
        return cls(
            plant=plant, scene_graph=diagram.GetSubsystemByName("scene_graph"),
            arm=plant.GetModelInstanceByName(robot.ARM_MODEL_NAME),
            hand=plant.GetModelInstanceByName(robot.HAND_MODEL_NAME),
            object_body=body, infrared=diagram.GetSubsystemByName("infrared"),
            bumper=diagram.GetSubsystemByName("bumper"),
            inputs={n: diagram.GetInputPort(n) for n in STATION_INPUTS},
            outputs={n: diagram.GetOutputPort(n) for n in STATION_OUTPUTS},
            diagram=diagram)

    def GetInputPort(self, name: str) -> InputPort:
        return _port(self.inputs, name, "input")

    def GetOutputPort(self, name: str) -> OutputPort:
        return _port(self.outputs, name, "output")

    def Eval(self, name: str, root_context: Context):
        """The value of the output port `name` in the diagram's context."""
        port = self.GetOutputPort(name)
        return port.Eval(port.get_system().GetMyContextFromRoot(root_context))


def _port(ports: dict, name: str, kind: str):
    if name not in ports:
        raise KeyError(f"the station has no {kind} port {name!r}; expected "
                       f"one of {sorted(ports)}")
    return ports[name]


def MakeStation(scenario: Scenario, obj: ObjectSpec,
                name: str = "station") -> Diagram:
    """The station as a Diagram named `name`: the plant (PUMA + hand +
    `obj`) and its scene graph, the 13 infrared sensors and the tactile
    bumper, the fingers' PD servos (in the plant when it is discrete, beside
    it when continuous) and the arm's inverse-dynamics controller (on an
    arm-only plant built from the scenario's directives). Whatever drives it
    (the catch controller, or another) is wired to its exported ports
    (STATION_INPUTS, STATION_OUTPUTS):

    Input ports: `arm_desired_state` (q, v: 12), `arm_desired_acceleration`
    (6), `hand_desired_state` (the finger joints' q, v: 20).
    Output ports: `arm_state` (12), `hand_state` (20), `object_state` (13:
    quaternion wxyz, p_WO, w_WO, v_WO), `body_poses`, `contact_results`,
    `query_object`, `ir_levels` (13), `bumper` (1), `net_actuation` (16,
    [N·m]).

    Its systems inside are named "plant", "scene_graph", "infrared",
    "bumper" and "arm_controller" (`Station.of` finds them)."""
    builder = DiagramBuilder()
    parts = _add_station_systems(builder, scenario, obj)
    for port_name, port in parts.inputs.items():
        builder.ExportInput(port, port_name)
    for port_name, port in parts.outputs.items():
        builder.ExportOutput(port, port_name)
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram


def add_station(builder: DiagramBuilder, scenario: Scenario,
                obj: ObjectSpec, name: str = "station") -> Station:
    """Adds the station to `builder` (`MakeStation`'s Diagram, named
    `name`) and returns its systems and ports."""
    if scenario.plant_config.time_step > 0:
        return Station.of(builder.AddSystem(MakeStation(scenario, obj, name)))
    # Flat, its systems straight into `builder`, only for a continuous
    # plant: Drake's CENIC integrator needs the MultibodyPlant as a direct
    # child, named "plant", of the diagram it simulates.
    return _add_station_systems(builder, scenario, obj)


def _add_station_systems(builder: DiagramBuilder, scenario: Scenario,
                         obj: ObjectSpec) -> Station:
    """Adds the station's systems to `builder` (see `MakeStation`); the
    Station's ports are theirs."""
    # The physics: PUMA + hand, the object, the ground (see add_world).
    plant, scene_graph, instances, object_body, object_geometries = (
        add_world(builder, scenario, obj))
    bumper_geometries = bumper_geometry(plant, scene_graph, instances.hand,
                                        scenario.contact.palm)

    # Sensors: 13 infrared range sensors and the tactile bumper.
    s = scenario.sensors
    ir = builder.AddNamedSystem("infrared", InfraredSensors(
        plant, [plant.GetFrameByName(f, instances.hand) for f in _IR_FRAMES],
        object_geometries, [s.palm_range_m] * 3 + [s.approach_range_m] * 10,
        period_s=s.period_s, levels=s.levels,
        target_bound=(object_body, obj.bounding_radius + 1e-3),
        inspector=scene_graph.model_inspector()))
    builder.Connect(scene_graph.get_query_output_port(),
                    ir.GetInputPort("query_object"))
    bumper = builder.AddNamedSystem("bumper", TactileBumper(
        plant, bumper_geometries, object_geometries, s.period_s))
    builder.Connect(plant.get_contact_results_output_port(),
                    bumper.GetInputPort("contact_results"))

    # The fingers: PD servos in the plant, or beside a continuous one.
    if plant.time_step() > 0:
        hand_desired_state = plant.get_desired_state_input_port(instances.hand)
    else:
        servos = add_finger_servos(builder, plant, instances.hand)
        hand_desired_state = servos.get_input_port(0)

    # The arm: inverse dynamics on its own arm-only plant; the plant clamps
    # the torques to the servos' effort limits.
    arm_controller = builder.AddNamedSystem(
        "arm_controller", make_arm_controller(scenario))
    builder.Connect(plant.get_state_output_port(instances.arm),
                    arm_controller.GetInputPort("estimated_state"))
    builder.Connect(arm_controller.GetOutputPort("actuation"),
                    plant.get_actuation_input_port(instances.arm))

    # What drives the station, and what it shows.
    inputs = {
        "arm_desired_state": arm_controller.GetInputPort("desired_state"),
        "arm_desired_acceleration":
            arm_controller.GetInputPort("desired_acceleration"),
        "hand_desired_state": hand_desired_state,
    }
    outputs = {
        "arm_state": plant.get_state_output_port(instances.arm),
        "hand_state": plant.get_state_output_port(instances.hand),
        "object_state": plant.get_state_output_port(
            object_body.model_instance()),
        "body_poses": plant.get_body_poses_output_port(),
        "contact_results": plant.get_contact_results_output_port(),
        "net_actuation": plant.get_net_actuation_output_port(),
        "query_object": scene_graph.get_query_output_port(),
        "ir_levels": ir.GetOutputPort("ir_levels"),
        "bumper": bumper.GetOutputPort("bumper"),
    }
    return Station(
        plant=plant, scene_graph=scene_graph, arm=instances.arm,
        hand=instances.hand, object_body=object_body, infrared=ir,
        bumper=bumper, inputs=inputs, outputs=outputs)


def make_arm_controller(scenario: Scenario) -> Diagram:
    """The arm's inverse-dynamics controller, on the arm-only plant built
    from the scenario's directives: v̇* = v̇_d + kp (q_d - q) + kd (v_d - v)
    + ki ∫(q_d - q), and τ = M(q) v̇* + C(q, v) v - τ_g(q). Ports as Drake's
    InverseDynamicsController's: inputs `estimated_state`, `desired_state`,
    `desired_acceleration`; output `actuation` (B⁻¹ τ, the arm's actuation
    matrix B being square).

    With an integral gain it is Drake's InverseDynamicsController, whose PID
    integrates the error as continuous state. Without one (the shipped
    gains) it is the same diagram without the integrator: the error and the
    PD law as matrix gains, the same Adder and InverseDynamics. Both compute
    the same torques bit for bit (the integral's term is ki · 0 = 0;
    measured: the same episodes and success maps to the last bit), but
    continuous state makes the simulator integrate between the plant's
    discrete steps (runge_kutta3, about 6 % of a catch's wall time), for
    nothing."""
    arm = scenario.arm
    control_plant = robot.arm_control_plant(scenario.directives)
    if any(ki != 0.0 for ki in arm.ki):
        return InverseDynamicsController(
            control_plant, arm.kp, arm.ki, arm.kd,
            has_reference_acceleration=True)
    n = control_plant.num_positions()
    builder = DiagramBuilder()
    states = builder.AddSystem(Multiplexer([2 * n, 2 * n]))
    # (q_d - q, v_d - v), then kp (q_d - q) + kd (v_d - v).
    error = builder.AddSystem(MatrixGain(
        np.hstack([np.eye(2 * n), -np.eye(2 * n)])))
    pd = builder.AddSystem(MatrixGain(
        np.hstack([np.diag(arm.kp), np.diag(arm.kd)])))
    adder = builder.AddSystem(Adder(2, n))
    inverse_dynamics = builder.AddSystem(InverseDynamics(control_plant))
    builder.Connect(states.get_output_port(), error.get_input_port())
    builder.Connect(error.get_output_port(), pd.get_input_port())
    builder.Connect(pd.get_output_port(), adder.get_input_port(0))
    builder.Connect(adder.get_output_port(),
                    inverse_dynamics.get_input_port_desired_acceleration())
    builder.ExportInput(states.get_input_port(1), "estimated_state")
    builder.ConnectInput("estimated_state",
                         inverse_dynamics.get_input_port_estimated_state())
    builder.ExportInput(states.get_input_port(0), "desired_state")
    builder.ExportInput(adder.get_input_port(1), "desired_acceleration")
    actuation = builder.AddSystem(MatrixGain(
        np.linalg.inv(control_plant.MakeActuationMatrix())))
    builder.Connect(inverse_dynamics.get_output_port_generalized_force(),
                    actuation.get_input_port())
    builder.ExportOutput(actuation.get_output_port(), "actuation")
    return builder.Build()


def _take_out_pd_gains(plant: MultibodyPlant, hand) -> list[tuple]:
    """Removes the in-plant PD controllers of the hand's actuators and
    returns their gains, (kp
    [N·m/rad], kd [N·m·s/rad]) per actuator in the order of the hand's
    actuation input port."""
    gains = []
    for index in plant.GetJointActuatorIndices(hand):
        actuator = plant.get_joint_actuator(index)
        if not actuator.has_controller():
            raise RuntimeError(f"hand actuator {actuator.name()} has no "
                               "drake:controller_gains")
        g = actuator.get_controller_gains()
        gains.append((g.p, g.d))
        actuator.set_controller_gains(PdControllerGains(p=0.0, d=0.0))
    return gains


def add_finger_servos(builder: DiagramBuilder, plant: MultibodyPlant, hand):
    """The fingers' PD servos outside a continuous plant: the hand's
    in-plant PD controllers (sdf/hand.sdf's gains) are taken out of the
    plant and the same law is built beside it,
    u = kp (q_d - q) + kd (v_d - v), [N·m], fed to the
    hand's actuation input, where the plant clamps it to each actuator's
    effort limit (10 N·m, sdf/hand.sdf) as it clamps the in-plant PD's.
    Drake's own systems (a multiplexer and a matrix gain), so that CENIC,
    which linearizes the actuation by differencing the plant's state, runs
    no Python for it. Returns the multiplexer: its input 0 takes the desired
    state (q_d, v_d)."""
    gains = _take_out_pd_gains(plant, hand)
    n = len(gains)
    K = np.hstack([np.diag([g[0] for g in gains]),
                   np.diag([g[1] for g in gains])])
    # The desired state is in actuator order (as the in-plant PD's port);
    # the hand's state in its positions' and velocities' order: S picks,
    # per actuator, its joint's q and v out of the hand's state x.
    nq, nv = plant.num_positions(hand), plant.num_velocities(hand)
    q_of = list(plant.GetPositionsFromArray(hand, np.arange(
        plant.num_positions())))
    v_of = list(plant.GetVelocitiesFromArray(hand, np.arange(
        plant.num_velocities())))
    S = np.zeros((2 * n, nq + nv))
    for i, index in enumerate(plant.GetJointActuatorIndices(hand)):
        joint = plant.get_joint_actuator(index).joint()
        S[i, q_of.index(joint.position_start())] = 1.0
        S[n + i, nq + v_of.index(joint.velocity_start())] = 1.0
    # [x_d; x] -> K x_d - K S x.
    mux = builder.AddNamedSystem("finger_servo_inputs",
                                 Multiplexer([2 * n, nq + nv]))
    pd = builder.AddNamedSystem("finger_servos",
                                MatrixGain(np.hstack([K, -K @ S])))
    builder.Connect(plant.get_state_output_port(hand), mux.get_input_port(1))
    builder.Connect(mux.get_output_port(0), pd.get_input_port())
    builder.Connect(pd.get_output_port(), plant.get_actuation_input_port(hand))
    return mux
