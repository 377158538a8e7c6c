import tempfile
import textwrap
import unittest
from pathlib import Path

import numpy as np
from pydrake.geometry import Role
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.errors import InputError
from regrasp_drake.world.object_model import (
    MAX_BALLAST_DENSITY,
    MIN_BASE_DENSITY,
    Piece,
    add_object,
    count_convex_vertices,
)
from regrasp_drake.world.objects import (
    load_catalogue,
    load_object_file,
    resolve_object,
)

TABLE1 = {  # name: (geometry, density kg/m³, h_cm m, r_cm m), paper Table 1.
    "table1-row1": ("test-object-1", 150, -0.010, 0.0),
    "table1-row2": ("test-object-1", 200, -0.010, 0.0),
    "table1-row3": ("test-object-1", 200, -0.020, 0.0),
    "table1-row4": ("test-object-2", 300, -0.055, 0.043),
    "table1-row5": ("test-object-2", 350, -0.055, 0.043),
}
SAMPLES = 200_000  # Monte-Carlo samples per region.


# Independent geometry for the Monte-Carlo integration: only the pieces' data
# (shape, sizes, axis, centre) and the ballast's data are used, not the
# module's own geometry code.


def _inside(piece, p):
    """Points p (N×3) inside the closed piece."""
    d = p - piece.center
    if piece.shape == "box":
        return np.all(np.abs(d) <= piece.size / 2, axis=1)
    if piece.shape == "sphere":
        return np.sum(d**2, axis=1) <= piece.radius**2
    axial = d[:, piece.axis]
    radial2 = np.sum(d**2, axis=1) - axial**2
    if piece.shape == "cylinder":
        return (np.abs(axial) <= piece.length / 2) & (radial2 <= piece.radius**2)
    beyond = np.maximum(np.abs(axial) - piece.length / 2, 0.0)  # capsule
    return radial2 + beyond**2 <= piece.radius**2


def _aabb(piece):
    """Lower and upper corners of the piece's axis-aligned bounding box."""
    if piece.shape == "box":
        half = piece.size / 2
    else:
        half = np.full(3, piece.radius)
        if piece.shape == "cylinder":
            half[piece.axis] = piece.length / 2
        elif piece.shape == "capsule":
            half[piece.axis] += piece.length / 2
    return piece.center - half, piece.center + half


def _integrate(density, lo, hi, inside, rng):
    """Mass (kg), first moment (kg·m) and inertia about the origin (kg·m²) of
    a uniform `density` over the points of the box [lo, hi] that `inside`
    accepts; and the accepted sample points."""
    p = lo + (hi - lo) * rng.random((SAMPLES, 3))
    p = p[inside(p)]
    dm = density * np.prod(hi - lo) / SAMPLES
    inertia = dm * (np.sum(p**2) * np.eye(3) - p.T @ p)
    return dm * len(p), dm * p.sum(axis=0), inertia, p


def _monte_carlo(spec, rng):
    """Mass, centre of mass and inertia about O of the object's density field
    (base density over the pieces plus the ballast's excess density)."""
    boxes = [_aabb(piece) for piece in spec.pieces]
    lo, hi = (
        np.min([b[0] for b in boxes], axis=0),
        np.max([b[1] for b in boxes], axis=0),
    )

    def in_body(p):
        return np.any([_inside(piece, p) for piece in spec.pieces], axis=0)

    m, first, inertia, p = _integrate(spec.base_density, lo, hi, in_body, rng)
    volume = m / spec.base_density
    ballast = spec.ballast
    if ballast is not None:
        sphere = Piece("sphere", ballast.center, radius=ballast.radius)
        m_b, first_b, inertia_b, p_b = _integrate(
            ballast.density - spec.base_density,
            *_aabb(sphere),
            lambda p: _inside(sphere, p),
            rng,
        )
        m, first, inertia = m + m_b, first + first_b, inertia + inertia_b
        assert in_body(p_b).all(), f"{spec.name}: ballast sticks out of the body"
    return m, first / m, inertia, volume, hi - lo, np.linalg.norm(p, axis=1).max()


def _write(directory, text):
    path = Path(directory) / "objects.yaml"
    path.write_text(textwrap.dedent(text))
    return path


GOOD_FILE = """\
geometries:
  g:
    pieces:
      - {shape: cylinder, radius: 0.02, length: 0.08, axis: y, center: [0, 0, 0],
         grasp: true}
      - {shape: box, size: [0.06, 0.02, 0.04], center: [0.01, 0.05, 0]}
objects:
  - {name: mine, set: train, geometry: g, density: 200, h_cm: 0.01, r_cm: 0.0}
  - {name: other, set: test, geometry: g, density: 300, h_cm: 0.045, r_cm: 0.02}
"""


class TestCatalogue(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.catalogue = load_catalogue()

    def test_sets_and_table1(self):
        sets = [spec.set for spec in self.catalogue.values()]
        self.assertEqual(sets, ["train"] * 48 + ["ablation"] * 8 + ["test"] * 5
                         + ["holdout"] * 6)
        train_geometries = {
            s.geometry for s in self.catalogue.values() if s.set == "train"
        }
        self.assertEqual(len(train_geometries), 9)
        for name, (geometry, density, h_cm, r_cm) in TABLE1.items():
            spec = self.catalogue[name]
            self.assertEqual(
                (spec.set, spec.geometry, spec.density), ("test", geometry, density)
            )
            np.testing.assert_array_equal(spec.p_OCm, [r_cm, h_cm, 0.0])
            self.assertEqual(spec.features()["d_obj"], density)
        self.assertTrue(train_geometries.isdisjoint({"test-object-1", "test-object-2"}))
        for name, spec in self.catalogue.items():
            if spec.set == "train":
                self.assertEqual(
                    name.rsplit("-", 1)[0], f"{spec.geometry}-d{spec.density:g}"
                )

    def test_mass_com_inertia_by_monte_carlo(self):
        rng = np.random.default_rng(20240501)
        for spec in self.catalogue.values():
            with self.subTest(spec.name):
                m, p_OCm, I_OO, volume, extent, farthest = _monte_carlo(spec, rng)
                self.assertTrue(
                    0.97 * spec.bounding_radius <= farthest <= spec.bounding_radius
                )
                self.assertAlmostEqual(spec.mass, spec.density * spec.volume, places=12)
                self.assertLess(abs(volume * spec.density / spec.mass - 1), 0.01)
                self.assertLess(abs(m / spec.mass - 1), 0.01)
                # CoM within 1 % of the object's largest extent (~1 mm).
                np.testing.assert_allclose(
                    p_OCm, spec.p_OCm, rtol=0, atol=0.01 * extent.max()
                )
                I_expected = (
                    spec.spatial_inertia().CalcRotationalInertia().CopyToFullMatrix3()
                )
                np.testing.assert_allclose(
                    np.diag(I_OO), np.diag(I_expected), rtol=0.03
                )

    def test_spatial_inertia_valid_and_consistent(self):
        for spec in self.catalogue.values():
            with self.subTest(spec.name):
                M_OO = spec.spatial_inertia()
                self.assertTrue(M_OO.IsPhysicallyValid())
                self.assertAlmostEqual(M_OO.get_mass(), spec.mass, places=12)
                np.testing.assert_allclose(M_OO.get_com(), spec.p_OCm, atol=1e-12)

    def test_density_field_is_realizable(self):
        for spec in self.catalogue.values():
            with self.subTest(spec.name):
                self.assertGreaterEqual(spec.base_density, MIN_BASE_DENSITY - 1e-9)
                self.assertLessEqual(spec.base_density, spec.density + 1e-9)
                if spec.ballast is None:
                    self.assertEqual(spec.base_density, spec.density)
                else:
                    self.assertGreater(spec.ballast.density, spec.base_density)
                    self.assertLessEqual(spec.ballast.density, MAX_BALLAST_DENSITY)

    def test_sizes_fit_the_hand(self):
        for spec in self.catalogue.values():
            with self.subTest(spec.name):
                self.assertTrue(0.04 <= 2 * spec.grasp_radius <= 0.09)
                self.assertTrue(0.06 <= spec.grasp_length <= 0.14)
                boxes = [_aabb(piece) for piece in spec.pieces]
                extent = np.max([b[1] for b in boxes], 0) - np.min(
                    [b[0] for b in boxes], 0
                )
                self.assertTrue(
                    0.03 <= extent.min() and extent.max() <= 0.12 + 1e-9, extent
                )

    def test_test_object_2_is_asymmetric_around_its_com(self):
        spec = self.catalogue["table1-row4"]
        in_body = [_inside(piece, spec.p_OCm[None, :])[0] for piece in spec.pieces]
        self.assertTrue(any(in_body))
        mirrored = spec.p_OCm * [-1, 1, 1]
        self.assertFalse(
            any(_inside(piece, mirrored[None, :])[0] for piece in spec.pieces)
        )

    def test_convex_vertices(self):
        self.assertEqual(self.catalogue["hammer-d100-1"].v_conv, 8)  # Fig. 4's first.
        self.assertEqual(self.catalogue["can-d100-1"].v_conv, 0)
        self.assertEqual(self.catalogue["stamp-d200-1"].v_conv, 4)
        self.assertEqual(self.catalogue["bracket-d150-1"].v_conv, 16)
        self.assertEqual(self.catalogue["table1-row4"].features()["v_conv"], 8)


class TestConvexVertices(unittest.TestCase):
    def _box(self, size, center):
        return Piece("box", np.array(center, float), size=np.array(size, float))

    def _cylinder(self, radius, length, center=(0, 0, 0)):
        return Piece(
            "cylinder", np.array(center, float), radius=radius, length=length, axis=1
        )

    def test_box_alone_has_8(self):
        self.assertEqual(
            count_convex_vertices((self._box([0.1, 0.05, 0.02], [0, 0, 0]),)), 8
        )

    def test_two_boxes_sharing_a_face_make_one_box(self):
        a = self._box([0.04, 0.02, 0.04], [0, 0.01, 0])
        b = self._box([0.04, 0.02, 0.04], [0, -0.01, 0])
        self.assertEqual(count_convex_vertices((a, b)), 8)

    def test_cylinder_with_a_box_on_its_side_keeps_8(self):
        # Tangent to the curved side: no corner touches the cylinder.
        box = self._box([0.02, 0.04, 0.02], [0.03, 0, 0])
        self.assertEqual(count_convex_vertices((self._cylinder(0.02, 0.08), box)), 8)

    def test_box_on_a_cylinder_end_face_loses_the_4_corners_on_it(self):
        box = self._box([0.02, 0.02, 0.02], [0, 0.05, 0])
        self.assertEqual(count_convex_vertices((self._cylinder(0.02, 0.08), box)), 4)
        # A head wider than the face: no corner rests on the face.
        head = self._box([0.06, 0.02, 0.06], [0, 0.05, 0])
        self.assertEqual(count_convex_vertices((self._cylinder(0.02, 0.08), head)), 8)

    def test_round_shapes_have_none(self):
        sphere = Piece("sphere", np.array([0, 0.06, 0]), radius=0.02)
        self.assertEqual(count_convex_vertices((self._cylinder(0.02, 0.08), sphere)), 0)


class TestObjectFiles(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def test_good_file_and_resolve(self):
        path = _write(self.tmp.name, GOOD_FILE)
        specs = load_object_file(path)
        self.assertEqual([s.name for s in specs], ["mine", "other"])
        self.assertEqual(specs[0].v_conv, 8)
        self.assertAlmostEqual(
            specs[0].mass, 200 * (np.pi * 0.02**2 * 0.08 + 0.06 * 0.02 * 0.04)
        )
        self.assertEqual(resolve_object(file=path).name, "mine")
        self.assertEqual(resolve_object(name="other", file=path).r_cm, 0.02)
        self.assertEqual(resolve_object(name="table1-row4").density, 300)
        with self.assertRaisesRegex(InputError, "object name.*nope.*catalogue.yaml"):
            resolve_object(name="nope")
        with self.assertRaises(InputError):
            resolve_object()

    def test_bad_files_name_the_field(self):
        box = "{shape: box, size: [0.06, 0.02, 0.04], center: [0.01, 0.05, 0]}"
        cases = {  # what is wrong: (replace this, by this, the message names)
            "unknown shape": ("{shape: box,", "{shape: cone,", "pieces[1].shape"),
            "unknown piece key": (
                "center: [0.01",
                "colour: red, center: [0.01",
                "geometries.g.pieces[1].colour",
            ),
            "unknown object key": (
                "r_cm: 0.0}",
                "r_cm: 0.0, mass: 1}",
                "objects[0].mass",
            ),
            "missing radius": ("radius: 0.02, ", "", "geometries.g.pieces[0].radius"),
            "missing density": ("density: 200, ", "", "objects[0].density"),
            "negative size": (
                "0.06, 0.02, 0.04",
                "0.06, -0.02, 0.04",
                "geometries.g.pieces[1].size[1]",
            ),
            "zero density": ("density: 200", "density: 0", "objects[0].density"),
            "string density": ("density: 200", "density: heavy", "objects[0].density"),
            "CoM outside": (
                "h_cm: 0.01, r_cm: 0.0",
                "h_cm: 0.01, r_cm: 0.03",
                "objects[0].h_cm/r_cm: got (0.01, 0.03), expected a centre of "
                "mass (r_cm, h_cm, 0) inside the body",
            ),
            "CoM unreachable": (
                "h_cm: 0.01, r_cm: 0.0",
                "h_cm: 0.059, r_cm: 0.039",
                "objects[0].h_cm/r_cm: got (0.059, 0.039), expected a centre "
                "of mass a ballast",
            ),
            "no grasp piece": (
                ",\n         grasp: true}",
                "}",
                "geometries.g.pieces[*].grasp",
            ),
            "grasp not along y": ("axis: y", "axis: x", "geometries.g.pieces[0]"),
            "grasp piece a box": (
                ",\n         grasp: true}",
                "}",
                "geometries.g.pieces[1]",
            ),
            "unknown geometry": (
                "geometry: g, density: 200",
                "geometry: h, density: 200",
                "objects[0].geometry",
            ),
            "overlap": (
                "[0.01, 0.05, 0]",
                "[0.01, 0.045, 0]",
                "geometries.g.pieces[1]",
            ),
            "loose piece": (
                "[0.01, 0.05, 0]",
                "[0.01, 0.06, 0]",
                "geometries.g.pieces[1]",
            ),
            "bad set": ("set: train", "set: spare", "objects[0].set"),
            "duplicate name": ("name: other", "name: mine", "objects[1].name"),
            "not YAML": ("objects:", "objects: {", "not valid YAML"),
        }
        for what, (old, new, field) in cases.items():
            with self.subTest(what):
                text = GOOD_FILE
                if what == "grasp piece a box":
                    text = text.replace(box, box[:-1] + ", grasp: true}")
                self.assertIn(old, text)
                path = _write(self.tmp.name, text.replace(old, new, 1))
                with self.assertRaises(InputError) as raised:
                    load_object_file(path)
                message = str(raised.exception)
                self.assertIn(field, message)
                self.assertIn(str(path), message)
                self.assertNotIn("\n", message)


ALL_AXES_FILE = """\
geometries:
  axes:
    pieces:
      - {shape: cylinder, radius: 0.02, length: 0.08, axis: y, center: [0, 0, 0],
         grasp: true}
      - {shape: cylinder, radius: 0.01, length: 0.04, axis: x, center: [0.04, 0, 0]}
      - {shape: capsule, radius: 0.01, length: 0.02, axis: z, center: [0, 0.05, 0]}
      - {shape: sphere, radius: 0.01, center: [0, -0.05, 0]}
objects:
  - {name: axes, set: train, geometry: axes, density: 250, h_cm: 0.0, r_cm: 0.01}
"""


class TestAddObject(unittest.TestCase):
    def _check_plant_body(self, spec):
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
        body = add_object(plant, spec, CoulombFriction(0.9, 0.7), model_name="thrown")
        plant.Finalize()
        context = builder.Build().CreateDefaultContext()
        self.assertTrue(body.is_floating_base_body())
        self.assertEqual(plant.GetModelInstanceName(body.model_instance()), "thrown")
        self.assertAlmostEqual(body.default_mass(), spec.mass)
        np.testing.assert_allclose(body.default_com(), spec.p_OCm, atol=1e-12)
        inspector = scene_graph.model_inspector()
        ids = plant.GetCollisionGeometriesForBody(body)
        self.assertEqual(len(ids), len(spec.pieces))
        for geometry_id in ids:
            properties = inspector.GetProximityProperties(geometry_id)
            mu = properties.GetProperty("material", "coulomb_friction")
            self.assertEqual((mu.static_friction(), mu.dynamic_friction()), (0.9, 0.7))
        frame_id = plant.GetBodyFrameIdOrThrow(body.index())
        visuals = inspector.GetGeometries(frame_id, Role.kIllustration)
        self.assertEqual(len(visuals), len(spec.pieces))
        # The collision shapes sit where the pieces are: at the default pose
        # (X_WO = I) a point is inside a geometry iff it is inside a piece.
        query = scene_graph.get_query_output_port().Eval(
            scene_graph.GetMyContextFromRoot(context)
        )
        rng = np.random.default_rng(7)
        points = rng.uniform([-0.03, -0.07, -0.03], [0.06, 0.07, 0.03], (400, 3))
        checked = 0
        for p in points:
            expected = any(_inside(piece, p[None, :])[0] for piece in spec.pieces)
            distances = [d.distance for d in query.ComputeSignedDistanceToPoint(p, 0.2)]
            if min(abs(d) for d in distances) > 1e-6:
                self.assertEqual(min(distances) < 0, expected, p)
                checked += expected
        self.assertGreater(checked, 20)

    def test_catalogue_object(self):
        self._check_plant_body(load_catalogue()["flashlight-d300-2"])

    def test_pieces_along_every_axis(self):
        with tempfile.TemporaryDirectory() as directory:
            (spec,) = load_object_file(_write(directory, ALL_AXES_FILE))
        self.assertEqual(spec.v_conv, 0)
        self._check_plant_body(spec)


if __name__ == "__main__":
    unittest.main()
