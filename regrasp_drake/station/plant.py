"""The physics of an episode: the scenario's MultibodyPlant with the robot
of its directives, the object, the ground and gravity, and the contact
geometry of the palm, the bumper and the object."""

import logging

from pydrake.geometry import (
    Box,
    HalfSpace,
    ProximityProperties,
    Role,
    RoleAssign,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    CoulombFriction,
)
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.station.scenario import Scenario
from regrasp_drake.world import robot
from regrasp_drake.world.object_model import ObjectSpec, add_object

# The tactile bumper stands this proud of the palm (paper: 3 x 6 x 0.1 cm).
BUMPER_THICKNESS_M = 0.001


class _NoDeformableGroundWarning(logging.Filter):
    """Drake (1.51) warns, each time the ground's half space is registered
    for contact, that a rigid half space takes no part in deformable
    contact. Nothing here is deformable: the warning only hides the lines
    that matter (a one-line error)."""

    def filter(self, record) -> bool:
        return not record.getMessage().startswith(
            "Rigid (non-deformable) half spaces are not currently supported "
            "for deformable contact")


logging.getLogger("drake").addFilter(_NoDeformableGroundWarning())


def add_world(builder: DiagramBuilder, scenario: Scenario, obj: ObjectSpec):
    """Adds the physics to `builder`: the scenario's MultibodyPlant (point
    contact, no air drag) with the robot of its directives (PUMA +
    hand welded to the world), the object a
    free body with the scenario's contact properties, the ground, gravity;
    finalized, robot self-collisions filtered. Returns (plant, scene_graph,
    robot instances, object body, the object's collision geometry ids)."""
    plant, scene_graph = AddMultibodyPlant(scenario.plant_config, builder)
    instances = robot.add_puma_and_hand(plant, scenario.directives)
    friction = CoulombFriction(scenario.contact.friction_coefficient,
                               scenario.contact.friction_coefficient)
    object_body = add_object(
        plant, obj, friction,
        rounded_boxes=scenario.contact.object_boxes == "rounded")
    plant.RegisterCollisionGeometry(
        plant.world_body(), RigidTransform(), HalfSpace(), "ground", friction)
    # Meshcat does not draw half spaces: the ground is drawn as a slab.
    plant.RegisterVisualGeometry(
        plant.world_body(), RigidTransform([0.0, 0.0, -0.01]),
        Box(4.0, 4.0, 0.02), "ground", [0.55, 0.55, 0.5, 1.0])
    plant.mutable_gravity_field().set_gravity_vector(
        [0.0, 0.0, -scenario.gravity_m_per_s2])
    plant.Finalize()
    robot.exclude_robot_self_collisions(plant, scene_graph)
    _keep_palm(plant, scene_graph, instances.hand, scenario.contact.palm)
    object_geometries = _set_object_contact(plant, scene_graph, object_body,
                                            scenario)
    return plant, scene_graph, instances, object_body, object_geometries


def _set_object_contact(plant, scene_graph, object_body, scenario):
    """Gives the object's collision geometries the scenario's point-contact
    stiffness, dissipation and friction; returns their ids."""
    inspector = scene_graph.model_inspector()
    source_id = plant.get_source_id()
    c = scenario.contact
    ids = list(plant.GetCollisionGeometriesForBody(object_body))
    for geometry_id in ids:
        props = ProximityProperties(inspector.GetProximityProperties(geometry_id))
        for name, value in (
                ("point_contact_stiffness", float(c.point_stiffness_N_per_m)),
                ("hunt_crossley_dissipation",
                 float(c.hunt_crossley_dissipation_s_per_m))):
            if props.HasProperty("material", name):
                props.UpdateProperty("material", name, value)
            else:
                props.AddProperty("material", name, value)
        scene_graph.AssignRole(source_id, geometry_id, props, RoleAssign.kReplace)
    return ids


def _palm_geometries(plant, scene_graph, hand) -> dict:
    """The palm's collision geometries by name (sdf/hand.sdf)."""
    inspector = scene_graph.model_inspector()
    palm = plant.GetBodyByName("palm", hand)
    return {inspector.GetName(g).split("::")[-1]: g
            for g in plant.GetCollisionGeometriesForBody(palm)}


def _keep_palm(plant, scene_graph, hand, palm: str) -> None:
    """Keeps the palm's collision geometry the scenario names
    (contact.palm): "box", the flat box and the bumper's thin box; or
    "pads", the sphere pads over a lowered box (named pads_*). The other
    set loses its proximity role."""
    for name, geometry_id in _palm_geometries(plant, scene_graph,
                                              hand).items():
        if name.startswith("pads_") != (palm == "pads"):
            scene_graph.RemoveRole(plant.get_source_id(), geometry_id,
                                   Role.kProximity)


def bumper_geometry(plant, scene_graph, hand, palm: str = "box"):
    """The tactile bumper's geometry: the thin box on the flat palm, or
    the pads under it on the padded palm (a list)."""
    geometries = _palm_geometries(plant, scene_graph, hand)
    if palm == "pads":
        ids = [g for name, g in geometries.items()
               if name.startswith("pads_bumper_")]
        if ids:
            return ids
    elif "bumper" in geometries:
        return geometries["bumper"]
    raise RuntimeError(f"the hand model has no bumper geometry for the "
                       f"palm {palm!r}")
