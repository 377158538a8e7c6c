import math
import unittest

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder, Sphere
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    ContactModel,
    CoulombFriction,
    DiscreteContactApproximation,
)
from pydrake.multibody.tree import FixedOffsetFrame, SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.errors import InputError
from regrasp_drake.station.sensors import (
    InfraredSensors,
    TactileBumper,
    quantize,
    ray_entry,
    unquantize,
)

PALM_SIZE = (0.10, 0.10, 0.02)  # m; the palm's top face is at z = 0.01.
PALM_TOP_Z = 0.01
SPHERE_RADIUS = 0.03  # m
RANGE_M = 0.20  # m
LEVELS = 1000
PERIOD_S = 0.01  # s


def _build(period_s=PERIOD_S):
    """A welded palm box with four IR sensor frames and a free sphere, plus a
    bumper on the palm's collision box. Returns a dict of the parts."""
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    plant.set_contact_model(ContactModel.kPoint)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    friction = CoulombFriction(0.8, 0.6)

    palm = plant.AddRigidBody(
        "palm", SpatialInertia(0.3, np.zeros(3), UnitInertia.SolidBox(*PALM_SIZE))
    )
    plant.WeldFrames(plant.world_frame(), palm.body_frame())
    palm_id = plant.RegisterCollisionGeometry(
        palm, RigidTransform(), Box(*PALM_SIZE), "palm", friction
    )
    sphere = plant.AddRigidBody(
        "sphere",
        SpatialInertia(0.1, np.zeros(3), UnitInertia.SolidSphere(SPHERE_RADIUS)),
    )
    sphere_id = plant.RegisterCollisionGeometry(
        sphere, RigidTransform(), Sphere(SPHERE_RADIUS), "sphere", friction
    )
    # Sensors on the palm's top face, pointing up (+z), at these offsets (m):
    # centred, oblique hit, off to the side (misses a sphere above the centre).
    offsets = [(0.0, 0.0), (0.02, 0.0), (0.0, 0.045)]
    frames = [
        plant.AddFrame(
            FixedOffsetFrame(
                f"ir_{i}", palm.body_frame(), RigidTransform([x, y, PALM_TOP_Z])
            )
        )
        for i, (x, y) in enumerate(offsets)
    ]
    # A fourth sensor at x = -0.15, z = 0.10, turned so that its +z is world +x.
    frames.append(
        plant.AddFrame(
            FixedOffsetFrame(
                "ir_side",
                palm.body_frame(),
                RigidTransform(RollPitchYaw(0, math.pi / 2, 0), [-0.15, 0.0, 0.10]),
            )
        )
    )
    plant.Finalize()

    ir = builder.AddSystem(
        InfraredSensors(
            plant, frames, [sphere_id], [RANGE_M] * 4, period_s=period_s, levels=LEVELS
        )
    )
    builder.Connect(scene_graph.get_query_output_port(), ir.get_input_port())
    bumper = builder.AddSystem(TactileBumper(plant, palm_id, [sphere_id], period_s))
    builder.Connect(plant.get_contact_results_output_port(), bumper.get_input_port())
    diagram = builder.Build()
    return dict(
        diagram=diagram,
        plant=plant,
        scene_graph=scene_graph,
        sphere=sphere,
        ir=ir,
        bumper=bumper,
    )


# Each sensor's ray in the world frame: origin and unit direction.
SENSOR_RAYS = [
    ((0.0, 0.0, PALM_TOP_Z), (0.0, 0.0, 1.0)),
    ((0.02, 0.0, PALM_TOP_Z), (0.0, 0.0, 1.0)),
    ((0.0, 0.045, PALM_TOP_Z), (0.0, 0.0, 1.0)),
    ((-0.15, 0.0, 0.10), (1.0, 0.0, 0.0)),
]


def _expected_distance(ray, p_WC):
    """The distance (m) along `ray` to the sphere's surface centred at p_WC,
    or inf if the ray misses it (solves |o + s·u − c| = R for the least s ≥ 0);
    0 if the ray starts inside it."""
    o, u = np.array(ray[0]), np.array(ray[1])
    oc = np.asarray(p_WC) - o
    if oc @ oc <= SPHERE_RADIUS**2:
        return 0.0
    b = u @ oc
    disc = b * b - (oc @ oc - SPHERE_RADIUS**2)
    if disc < 0 or b - math.sqrt(disc) < 0:
        return math.inf
    return b - math.sqrt(disc)


class QuantizeTest(unittest.TestCase):
    def test_levels(self):
        self.assertEqual(quantize(0.0, 0.2), 0)
        self.assertEqual(quantize(0.1, 0.2), 500)
        self.assertEqual(quantize(0.1999, 0.2), 999)
        self.assertEqual(quantize(0.2, 0.2), 1000)
        self.assertEqual(quantize(math.inf, 0.2), 1000)
        self.assertEqual(quantize(-0.01, 0.2), 0)
        self.assertEqual(quantize(0.05, 0.1, levels=10), 5)

    def test_unquantize_inverts_within_half_a_quantum(self):
        for d in np.linspace(0.0, 0.1999, 37):
            self.assertAlmostEqual(
                unquantize(quantize(d, 0.2), 0.2), d, delta=0.2e-3 / 2 + 1e-12
            )
        self.assertEqual(unquantize(1000, 0.2), math.inf)


class InfraredSensorsTest(unittest.TestCase):
    def setUp(self):
        self.parts = _build()
        self.diagram = self.parts["diagram"]
        self.context = self.diagram.CreateDefaultContext()
        self.plant = self.parts["plant"]
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.ir = self.parts["ir"]

    def _levels_with_sphere_at(self, p_WC):
        self.context.SetTime(0.0)
        self.plant.SetFreeBodyPose(
            self.plant_context, self.parts["sphere"], RigidTransform(p_WC)
        )
        # Initialization samples the sensors once.
        Simulator(self.diagram, self.context).Initialize()
        return self.ir.get_output_port().Eval(
            self.ir.GetMyContextFromRoot(self.context)
        )

    def test_sphere_at_known_heights(self):
        for height in [0.05, 0.08, 0.123, 0.20]:
            p_WC = np.array([0.0, 0.0, height])
            levels = self._levels_with_sphere_at(p_WC)
            for i, ray in enumerate(SENSOR_RAYS):
                expected = quantize(_expected_distance(ray, p_WC), RANGE_M)
                self.assertLessEqual(abs(levels[i] - expected), 1, (height, i, levels))
            # The centred sensor hits; the one 4.5 cm aside misses the 3 cm sphere.
            self.assertLess(levels[0], LEVELS)
            self.assertEqual(levels[2], LEVELS)
        # The side sensor at z = 0.10 sees the sphere only within 3 cm of its height.
        self.assertEqual(self._levels_with_sphere_at([0.0, 0.0, 0.05])[3], LEVELS)
        self.assertLess(self._levels_with_sphere_at([0.0, 0.0, 0.123])[3], LEVELS)

    def test_out_of_range_reads_levels(self):
        # The sphere's bottom is 0.25 m above the sensors: beyond the 0.2 m range.
        levels = self._levels_with_sphere_at(
            [0.0, 0.0, PALM_TOP_Z + 0.25 + SPHERE_RADIUS]
        )
        np.testing.assert_array_equal(levels, [LEVELS] * 4)
        # Just inside the range it reads 999 or less.
        levels = self._levels_with_sphere_at(
            [0.0, 0.0, PALM_TOP_Z + 0.199 + SPHERE_RADIUS]
        )
        self.assertEqual(levels[0], quantize(0.199, RANGE_M))

    def test_sensor_direction_follows_its_frame(self):
        # The side sensor at (-0.15, 0, 0.10) looks along world +x.
        p_WC = np.array([0.0, 0.0, 0.10])
        levels = self._levels_with_sphere_at(p_WC)
        self.assertEqual(levels[3], quantize(0.15 - SPHERE_RADIUS, RANGE_M))

    def test_readings_change_only_at_the_sample_period(self):
        # The sphere falls from 0.2 m through the sensors' range onto the palm.
        self.plant.SetFreeBodyPose(
            self.plant_context, self.parts["sphere"], RigidTransform([0.0, 0.0, 0.20])
        )
        simulator = Simulator(self.diagram, self.context)
        simulator.Initialize()
        ir_context = self.ir.GetMyContextFromRoot(self.context)
        dt = 1e-3
        times, readings, heights = [], [], []
        for k in range(251):
            simulator.AdvanceTo(k * dt)
            times.append(self.context.get_time())
            readings.append(self.ir.get_output_port().Eval(ir_context).copy())
            heights.append(
                self.plant.EvalBodyPoseInWorld(
                    self.plant_context, self.parts["sphere"]
                ).translation()
            )
        changes = 0
        for k in range(1, len(times)):
            if np.array_equal(readings[k], readings[k - 1]):
                continue
            changes += 1
            # The update that changed it ran at t_{k-1}, a multiple of the period,
            # and saw the sphere where it was then or one plant step later (the
            # plant's own update at that time may come first).
            self.assertAlmostEqual(
                times[k - 1] / PERIOD_S, round(times[k - 1] / PERIOD_S), places=6
            )
            errors = [
                abs(
                    readings[k][0]
                    - quantize(_expected_distance(SENSOR_RAYS[0], p), RANGE_M)
                )
                for p in (heights[k - 1], heights[k])
            ]
            self.assertLessEqual(min(errors), 1, (times[k], readings[k], heights[k]))
        self.assertGreaterEqual(changes, 10)
        # Resting on the palm, the sphere reads 0 on the centred sensor.
        self.assertEqual(readings[-1][0], 0)

    def test_bad_arguments(self):
        plant = self.plant
        frame = plant.GetFrameByName("ir_0")
        sphere_id = plant.GetCollisionGeometriesForBody(self.parts["sphere"])[0]
        with self.assertRaisesRegex(InputError, "ranges_m"):
            InfraredSensors(plant, [frame], [sphere_id], [0.1, 0.2], period_s=0.01)
        with self.assertRaisesRegex(InputError, "period_s"):
            InfraredSensors(plant, [frame], [sphere_id], [0.1], period_s=0.0)


class RayEntryTest(unittest.TestCase):
    """Closed-form ray casting against known answers."""

    def _entry(self, shape, origin, direction):
        d = np.asarray(direction, float)
        return float(ray_entry(shape, np.array([origin], float),
                               np.array([d / np.linalg.norm(d)]))[0])

    def test_known_answers(self):
        box = Box(0.2, 0.1, 0.04)
        self.assertAlmostEqual(self._entry(box, [0, 0, -1], [0, 0, 1]), 0.98)
        self.assertAlmostEqual(self._entry(box, [-1, 0.04, 0], [1, 0, 0]), 0.9)
        self.assertEqual(self._entry(box, [-1, 0.06, 0], [1, 0, 0]), math.inf)
        self.assertEqual(self._entry(box, [0, 0, 0.01], [0, 1, 0]), 0.0)
        self.assertEqual(self._entry(box, [0, 0, 1], [0, 0, 1]), math.inf)
        cyl = Cylinder(0.05, 0.3)  # along z
        self.assertAlmostEqual(self._entry(cyl, [-1, 0, 0], [1, 0, 0]), 0.95)
        self.assertAlmostEqual(self._entry(cyl, [0, 0, -1], [0, 0, 1]), 0.85)
        self.assertAlmostEqual(self._entry(cyl, [0.03, 0, -1], [0, 0, 1]), 0.85)
        self.assertEqual(self._entry(cyl, [0.06, 0, -1], [0, 0, 1]), math.inf)
        self.assertEqual(self._entry(cyl, [-1, 0, 0.16], [1, 0, 0]), math.inf)
        cap = Capsule(0.05, 0.3)
        self.assertAlmostEqual(self._entry(cap, [0, 0, -1], [0, 0, 1]), 0.80)
        self.assertAlmostEqual(self._entry(cap, [-1, 0, 0.15], [1, 0, 0]), 0.95)
        self.assertAlmostEqual(self._entry(Sphere(0.1), [0, 0, 1], [0, 0, -1]), 0.9)

    def test_agrees_with_drake_signed_distance_for_every_shape(self):
        """Random poses of a box, a cylinder, a capsule and a sphere: where a
        sensor reads a distance, the ray's point there lies on the geometry's
        surface by Drake's signed distance, and the ray is outside just
        before it; where it reads nothing, no point along the ray is inside."""
        shapes = [Box(0.12, 0.05, 0.03), Cylinder(0.03, 0.15),
                  Capsule(0.02, 0.12), Sphere(0.04)]
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
        body = plant.AddRigidBody(
            "target", SpatialInertia(0.1, np.zeros(3), UnitInertia.SolidSphere(0.05)))
        ids = [plant.RegisterCollisionGeometry(
            body, RigidTransform(RollPitchYaw(0.3 * i, 0.2, -0.4 * i),
                                 [0.03 * i, -0.02 * i, 0.01]),
            shape, f"g{i}", CoulombFriction(0.5, 0.5))
            for i, shape in enumerate(shapes)]
        rng = np.random.default_rng(7)
        frames = [plant.AddFrame(FixedOffsetFrame(
            f"s{k}", plant.world_frame(),
            RigidTransform(RollPitchYaw(rng.uniform(-0.3, 0.3, 3)),
                           [rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05),
                            -0.25]))) for k in range(8)]
        plant.Finalize()
        diagram = builder.Build()
        context = diagram.CreateDefaultContext()
        plant_context = plant.GetMyMutableContextFromRoot(context)
        inspector = scene_graph.model_inspector()
        range_m, levels = 0.45, 100000  # fine levels: 4.5 µm
        for geometry_id in ids:
            name = str(inspector.GetShape(geometry_id))
            ir = InfraredSensors(plant, frames, [geometry_id], [range_m] * 8,
                                 period_s=0.01, levels=levels,
                                 inspector=inspector)
            self.assertEqual(len(ir._target_ids), 0, name)  # all closed form
            hits = misses = 0
            for trial in range(20):
                plant.SetFreeBodyPose(plant_context, body, RigidTransform(
                    RollPitchYaw(rng.uniform(-np.pi, np.pi, 3)),
                    [rng.uniform(-0.04, 0.04), rng.uniform(-0.04, 0.04),
                     rng.uniform(-0.05, 0.1)]))
                query = scene_graph.get_query_output_port().Eval(
                    scene_graph.GetMyContextFromRoot(context))

                def signed_distance(p_WQ):
                    return min(d.distance for d in query.ComputeSignedDistanceToPoint(
                        p_WQ, threshold=1.0) if d.id_G == geometry_id)

                read = ir.read_levels(query)
                p_WS, z_W = ir._rays(query)
                for level, p, z in zip(read, p_WS, z_W):
                    if level < levels:
                        hits += 1
                        s_lo = level * range_m / levels  # the bin's start
                        s_hi = s_lo + range_m / levels
                        # Inside (or on) the surface at the bin's end, outside
                        # before its start.
                        self.assertLess(signed_distance(p + s_hi * z), 1e-9, name)
                        if level > 0:
                            self.assertGreater(signed_distance(p + (s_lo - 1e-6) * z),
                                               0.0, name)
                    else:
                        misses += 1
                        for s in np.linspace(0.0, range_m, 301):
                            self.assertGreater(signed_distance(p + s * z), -1e-4, name)
            self.assertGreater(hits, 10, name)  # the comparison saw the shape
            self.assertGreater(misses, 10, name)

    def test_target_bound_changes_no_reading(self):
        """The station's early-out (rays that cannot reach the object's
        bounding sphere about its frame origin read nothing, uncomputed)
        gives the readings of casting every ray, for an L-shaped object in
        random poses around the palm."""
        from pydrake.systems.framework import DiagramBuilder

        from regrasp_drake.station.scenario import load_scenario
        from regrasp_drake.station.station import add_station
        from regrasp_drake.world.objects import resolve_object
        scenario = load_scenario()
        obj = resolve_object(name="table1-row4")
        builder = DiagramBuilder()
        station = add_station(builder, scenario, obj)
        diagram = builder.Build()
        plant = station.plant
        scene_graph, bounded = station.scene_graph, station.infrared
        unbounded = InfraredSensors(
            plant, [plant.GetFrameByName(f"ir{i}", station.hand)
                    for i in range(1, 14)],
            list(plant.GetCollisionGeometriesForBody(station.object_body)),
            bounded.ranges_m(), period_s=scenario.sensors.period_s,
            levels=bounded.levels(), inspector=scene_graph.model_inspector())
        context = diagram.CreateDefaultContext()
        plant_context = plant.GetMyMutableContextFromRoot(context)
        X_WP = plant.GetFrameByName("palm_surface", station.hand).CalcPoseInWorld(
            plant_context)
        rng = np.random.default_rng(11)
        seen = 0
        for _ in range(60):
            # Over the palm, 2-40 cm along its normal, 8 cm either side.
            p_PO = [rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08),
                    rng.uniform(0.02, 0.4)]
            plant.SetFreeBodyPose(plant_context, station.object_body,
                                  RigidTransform(
                                      RollPitchYaw(rng.uniform(-np.pi, np.pi, 3)),
                                      X_WP @ np.array(p_PO)))
            query = scene_graph.get_query_output_port().Eval(
                scene_graph.GetMyContextFromRoot(context))
            read = bounded.read_levels(query)
            np.testing.assert_array_equal(read, unbounded.read_levels(query))
            seen += int(np.sum(read < bounded.levels()))
        self.assertGreater(seen, 60)  # the sensors did see the object


class TactileBumperTest(unittest.TestCase):
    def test_sphere_dropped_on_bumper(self):
        parts = _build()
        diagram, plant, bumper = parts["diagram"], parts["plant"], parts["bumper"]
        context = diagram.CreateDefaultContext()
        plant_context = plant.GetMyMutableContextFromRoot(context)
        # Sphere bottom 0.10 m above the palm: it lands after sqrt(2·0.1/g) ≈ 0.143 s.
        plant.SetFreeBodyPose(
            plant_context,
            parts["sphere"],
            RigidTransform([0.0, 0.0, PALM_TOP_Z + SPHERE_RADIUS + 0.10]),
        )
        simulator = Simulator(diagram, context)
        simulator.Initialize()
        bumper_context = bumper.GetMyContextFromRoot(context)
        t_land = math.sqrt(2 * 0.10 / 9.81)
        readings = []
        for k in range(51):
            t = k * 0.01
            simulator.AdvanceTo(t)
            readings.append((t, bumper.get_output_port().Eval(bumper_context)[0]))
        falling = [r for t, r in readings if t < t_land - 0.01]
        resting = [r for t, r in readings if t > t_land + 0.1]
        self.assertTrue(all(r == 0.0 for r in falling), readings)
        self.assertTrue(resting and all(r == 1.0 for r in resting), readings)
        # It rests on the palm: its height is the palm top plus its radius.
        z = plant.EvalBodyPoseInWorld(plant_context, parts["sphere"]).translation()[2]
        self.assertAlmostEqual(z, PALM_TOP_Z + SPHERE_RADIUS, delta=1e-3)


class PalmInfraredLayoutTest(unittest.TestCase):
    """The hand's palm sensors IR 1-3 all see an object held across the palm.

    The catch plan lays the object's axis along the palm's y; the fingers
    wrap it from +x, the thumb from -x, and held objects come to rest with
    their axis within about 1 cm of the palm's centre line (measured in
    caught episodes: -11 to +10 mm) and up to about 15 mm above the palm.
    The grasp monitor needs every palm sensor below `palm_grasp_level`
    (0.07 m) or the bumper: a sensor that misses a held object turns a catch
    into a drop (a row across the palm did, for IR 3)."""

    def test_held_cylinders_seen_by_all_three(self):
        from regrasp_drake.station.scenario import load_scenario
        from regrasp_drake.world import robot

        scenario = load_scenario()
        reach_m = (scenario.monitor.palm_grasp_level / scenario.sensors.levels
                   * scenario.sensors.palm_range_m)
        plant = AddMultibodyPlantSceneGraph(DiagramBuilder(), 1e-3)[0]
        hand = robot.add_hand(plant)
        plant.Finalize()
        context = plant.CreateDefaultContext()
        palm = plant.GetFrameByName("palm", hand)
        X_PS = plant.GetFrameByName("palm_surface", hand).CalcPose(context, palm)
        X_PI = [plant.GetFrameByName(f"ir{i}", hand).CalcPose(context, palm)
                for i in (1, 2, 3)]
        # The cylinder's axis (its frame's z) along the palm's y.
        R_SC = RotationMatrix.MakeXRotation(math.pi / 2)
        checked = 0
        for radius in (0.02, 0.025, 0.03, 0.035):  # the catalogue's grips
            for dx in np.linspace(-0.01, 0.01, 5):
                for gap in (0.0, 0.015):
                    X_PC = X_PS @ RigidTransform(R_SC, [dx, 0.0, radius + gap])
                    X_CP = X_PC.inverse()
                    o = np.array([(X_CP @ X).translation() for X in X_PI])
                    d = np.array([(X_CP @ X).rotation().col(2) for X in X_PI])
                    hit = ray_entry(Cylinder(radius, 0.06), o, d)
                    self.assertTrue(
                        np.all(hit < reach_m),
                        f"radius {radius} m, {dx:+.3f} m off the centre "
                        f"line, {gap} m up: IR 1-3 read {hit} m")
                    checked += 1
        self.assertEqual(checked, 40)


if __name__ == "__main__":
    unittest.main()
