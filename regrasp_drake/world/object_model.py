"""An object as the simulation holds it: rigid pieces in the object frame
O, their mass distribution, the network's object features, and the plant
body `add_object` makes of them (paper §III-B and §V). world/objects.py
reads them from the catalogue's YAML.

Object frame O (paper Fig. 2): the origin is the geometric centre of the
object's cylindrically symmetric grasp piece, y is that piece's axis. The
centre of mass is p_OCm = (r_cm, h_cm, 0): h_cm along y, r_cm along x, z = 0.

Mass distribution. mass = density × volume (the pieces' summed volume). When
the centre of mass differs from the pieces' centroid, the body is made of a
base material of uniform density ``base_density`` over all pieces plus one
spherical ``ballast`` region of a higher density, wholly inside one piece,
whose centre lies on the ray from the centroid through the target centre of
mass; its position and radius are chosen to make the ballast density as low as
possible, with base density ≥ MIN_BASE_DENSITY (rigid foam) and ballast
density ≤ MAX_BALLAST_DENSITY (tungsten is 19 300 kg/m³). An object whose
centre of mass no such ballast can reach is refused.

v_conv, the number of convex vertices (paper §V: "the first left object shown
in Fig. 4 has 8 convex vertices"): the number of box corners that are corners
of the object's surface, i.e. box corners not inside nor on any other piece
(a corner resting on another piece's face is a concave junction, not a convex
vertex). Cylinders, capsules and spheres have none: their rims are edges, not
vertices. A box alone has 8; a handle with a box head wider than the handle
has 8; a box smaller than the handle's end face, set on it, has 4.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
from pydrake.geometry import (
    AddContactMaterial,
    Box,
    Capsule,
    Cylinder,
    ProximityProperties,
    Shape,
    Sphere,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import RigidBody, RotationalInertia, SpatialInertia

MIN_BASE_DENSITY = 20.0  # kg/m³, the lightest base material (rigid foam).
MAX_BALLAST_DENSITY = 20_000.0  # kg/m³, a little above tungsten (19 300).
# A box's collision box lies this far inside its faces (Piece.collision_shapes).
BOX_INSET_M = 0.0005
AXES = {"x": 0, "y": 1, "z": 2}
# Two pieces overlap when a ball of this radius fits inside both; they touch
# when they are closer than this. Also the tolerance of "a corner is on a
# piece" and "the centre of mass is inside the body".
GEOMETRY_TOLERANCE = 1e-6  # m
_GRASP_COLOR = np.array([0.85, 0.55, 0.25, 1.0])
_PIECE_COLOR = np.array([0.30, 0.50, 0.80, 1.0])


@dataclasses.dataclass(frozen=True, eq=False)
class Piece:
    """One solid piece of an object, axis-aligned in the object frame O.

    ``radius`` and ``length`` (m) for cylinder/capsule/sphere (no length for a
    sphere), ``size`` (m, full edges along x, y, z) for a box, ``axis`` the
    index (0, 1, 2 for x, y, z) of a cylinder's or capsule's axis, ``center``
    p_OPc (m), the piece's geometric centre in O.
    """

    shape: str
    center: np.ndarray
    radius: float | None = None
    length: float | None = None
    size: np.ndarray | None = None
    axis: int | None = None
    grasp: bool = False

    @property
    def volume(self) -> float:
        """Volume (m³)."""
        if self.shape == "box":
            return float(np.prod(self.size))
        if self.shape == "sphere":
            return 4.0 / 3.0 * math.pi * self.radius**3
        cylinder = math.pi * self.radius**2 * self.length
        if self.shape == "capsule":
            return cylinder + 4.0 / 3.0 * math.pi * self.radius**3
        return cylinder

    def unit_inertia_about_center(self) -> np.ndarray:
        """Rotational inertia (m⁵, i.e. kg·m² per kg/m³) of the piece at unit
        density about its centre, expressed in O (3×3)."""
        if self.shape == "box":
            a, b, c = self.size**2
            return self.volume / 12.0 * np.diag([b + c, a + c, a + b])
        r, m = self.radius, self.volume
        if self.shape == "sphere":
            return 0.4 * m * r**2 * np.eye(3)
        L = self.length
        m_cyl = math.pi * r**2 * L
        i_axial = 0.5 * m_cyl * r**2
        i_perp = m_cyl * (3.0 * r**2 + L**2) / 12.0
        if self.shape == "capsule":
            # Two hemispheres (a sphere's mass m_s) at the ends: each has
            # 2/5 m r² about a diameter of its flat face, shifted by L/2.
            m_s = 4.0 / 3.0 * math.pi * r**3
            i_axial += 0.4 * m_s * r**2
            i_perp += m_s * (0.4 * r**2 + L**2 / 4.0 + 3.0 * L * r / 8.0)
        inertia = np.full(3, i_perp)
        inertia[self.axis] = i_axial
        return np.diag(inertia)

    def depth(self, p_OQ: np.ndarray) -> np.ndarray:
        """For points Q (N×3, m): how deep each lies inside the piece (m),
        i.e. its distance to the piece's surface, negative outside (outside,
        its magnitude may be less than the distance)."""
        d = np.atleast_2d(p_OQ) - self.center
        if self.shape == "box":
            return np.min(self.size / 2.0 - np.abs(d), axis=1)
        if self.shape == "sphere":
            return self.radius - np.linalg.norm(d, axis=1)
        k = self.axis
        if self.shape == "capsule":
            d[:, k] -= np.clip(d[:, k], -self.length / 2.0, self.length / 2.0)
            return self.radius - np.linalg.norm(d, axis=1)
        axial = self.length / 2.0 - np.abs(d[:, k])
        d[:, k] = 0.0
        return np.minimum(axial, self.radius - np.linalg.norm(d, axis=1))

    def corners(self) -> np.ndarray:
        """A box's 8 corners p_OC (8×3, m); no corners for other shapes."""
        if self.shape != "box":
            return np.zeros((0, 3))
        signs = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
        return self.center + signs * self.size / 2.0

    def max_distance_from(self, p_OA: np.ndarray) -> float:
        """The largest distance (m) from point A to a point of the piece."""
        c = self.center - p_OA
        if self.shape == "box":
            return float(np.max(np.linalg.norm(self.corners() - p_OA, axis=1)))
        if self.shape == "sphere":
            return float(np.linalg.norm(c) + self.radius)
        k = self.axis
        ends = [c + s * self.length / 2.0 * np.eye(3)[k] for s in (-1.0, 1.0)]
        if self.shape == "capsule":
            return max(float(np.linalg.norm(e)) + self.radius for e in ends)
        # The farthest point of an end disc is on its rim.
        return max(
            math.hypot(e[k], np.linalg.norm(np.delete(e, k)) + self.radius)
            for e in ends
        )

    def drake_shape(self) -> Shape:
        """The pydrake Shape, in the frame given by X_OG()."""
        if self.shape == "box":
            return Box(*self.size)
        if self.shape == "sphere":
            return Sphere(self.radius)
        if self.shape == "capsule":
            return Capsule(self.radius, self.length)
        return Cylinder(self.radius, self.length)

    def collision_shapes(self, rounded: bool = True
                         ) -> list[tuple[RigidTransform, Shape]]:
        """The piece's collision geometry, (X_OG, shape) pairs. Curved
        pieces, and boxes unless `rounded`, are their own shape. A rounded
        box is Drake's inset box with corner
        spheres: the box shrunk by BOX_INSET_M on every side, and in each of
        its 8 corners a sphere of radius ρ = min(edge)/4 (at most 6 mm)
        touching the full box's three faces there. A corner or an edge
        meeting a surface then touches it at one smooth point instead of one
        that jumps between the box's corners from step to step (Drake's
        point contact between flat faces; the release would not converge in
        the time step, issue 26). The visual shape and the inertia are the
        exact box."""
        if self.shape != "box" or not rounded:
            return [(self.X_OG(), self.drake_shape())]
        rho = min(float(np.min(self.size)) / 4.0, 0.006)
        half = self.size / 2.0
        shapes = [(RigidTransform(self.center),
                   Box(*(self.size - 2.0 * BOX_INSET_M)))]
        for signs in itertools.product((-1.0, 1.0), repeat=3):
            signs = np.array(signs)
            shapes.append((RigidTransform(
                self.center + signs * (half - rho)), Sphere(rho)))
        return shapes

    def X_OG(self) -> RigidTransform:
        """Pose of the Drake shape's frame G in O (Drake's cylinders and
        capsules lie along their frame's z)."""
        if self.axis == 0:
            R_OG = RotationMatrix.MakeYRotation(math.pi / 2.0)
        elif self.axis == 1:
            R_OG = RotationMatrix.MakeXRotation(-math.pi / 2.0)
        else:
            R_OG = RotationMatrix()
        return RigidTransform(R_OG, self.center)


@dataclasses.dataclass(frozen=True, eq=False)
class Ballast:
    """A sphere of denser material inside the body: centre p_OB (m),
    ``radius`` (m), ``density`` (kg/m³, replacing the base material there)."""

    center: np.ndarray
    radius: float
    density: float


@dataclasses.dataclass(frozen=True, eq=False)
class ObjectSpec:
    """One object: its pieces and its mass distribution.

    ``density`` (kg/m³) is the mean density; the mass distribution is
    ``base_density`` (kg/m³) over all pieces except inside ``ballast`` (None
    for a uniform object). ``volume`` (m³). ``v_conv`` the number of convex
    vertices (see the module docstring).
    """

    name: str
    set: str
    geometry: str
    pieces: tuple[Piece, ...]
    density: float
    h_cm: float
    r_cm: float
    volume: float
    v_conv: int
    base_density: float
    ballast: Ballast | None

    @property
    def p_OCm(self) -> np.ndarray:
        """Centre of mass in O (m): (r_cm, h_cm, 0)."""
        return np.array([self.r_cm, self.h_cm, 0.0])

    @property
    def mass(self) -> float:
        """Mass (kg) = density × volume."""
        return self.density * self.volume

    @property
    def d_obj(self) -> float:
        """The network feature d_obj: the mean density (kg/m³)."""
        return self.density

    @property
    def grasp_piece(self) -> Piece:
        return next(piece for piece in self.pieces if piece.grasp)

    @property
    def grasp_radius(self) -> float:
        """Radius (m) of the grasp piece."""
        return self.grasp_piece.radius

    @property
    def grasp_length(self) -> float:
        """Length (m) of the grasp piece along y, a capsule's caps included."""
        piece = self.grasp_piece
        caps = 2.0 * piece.radius if piece.shape == "capsule" else 0.0
        return piece.length + caps

    @property
    def bounding_radius(self) -> float:
        """The largest distance (m) of a point of the body from O."""
        return max(piece.max_distance_from(np.zeros(3)) for piece in self.pieces)

    def features(self) -> dict[str, float]:
        """The network's object features (paper §V): h_cm, r_cm (m), d_obj
        (kg/m³), v_conv."""
        return dict(
            h_cm=self.h_cm, r_cm=self.r_cm, d_obj=self.d_obj, v_conv=self.v_conv
        )

    def spatial_inertia(self) -> SpatialInertia:
        """M_OO_O: the spatial inertia about O, expressed in O, integrated
        exactly over the base material and the ballast."""
        I_OO = np.zeros((3, 3))
        for piece in self.pieces:
            I_OO += self.base_density * _shift_from_center(
                piece.unit_inertia_about_center(), piece.volume, piece.center
            )
        if self.ballast is not None:
            sphere = Piece("sphere", self.ballast.center, radius=self.ballast.radius)
            I_OO += (self.ballast.density - self.base_density) * _shift_from_center(
                sphere.unit_inertia_about_center(), sphere.volume, sphere.center
            )
        p = self.p_OCm
        I_CmCm = I_OO - self.mass * (p @ p * np.eye(3) - np.outer(p, p))
        # Like Drake's, the off-diagonal entries are the negated products.
        moments = np.diag(I_CmCm)
        products = I_CmCm[0, 1], I_CmCm[0, 2], I_CmCm[1, 2]
        M_OO = SpatialInertia.MakeFromCentralInertia(
            self.mass, p, RotationalInertia(*moments, *products)
        )
        assert M_OO.IsPhysicallyValid()
        return M_OO


def _shift_from_center(I_cc: np.ndarray, mass: float, p_Oc: np.ndarray) -> np.ndarray:
    """Parallel-axis theorem: inertia about O from the inertia about c."""
    return I_cc + mass * (p_Oc @ p_Oc * np.eye(3) - np.outer(p_Oc, p_Oc))


# The model instance an episode's object is added as.
OBJECT_MODEL_NAME = "object"


def add_object(
    plant: MultibodyPlant,
    spec: ObjectSpec,
    friction: CoulombFriction,
    model_name: str = OBJECT_MODEL_NAME,
    rounded_boxes: bool = False,
) -> RigidBody:
    """Adds `spec` to `plant` (before Finalize) as a new model instance
    `model_name` holding one free rigid body (named after the object) whose
    body frame is the object frame O. Each piece i gets a collision geometry
    "collision_i" with `friction` (with `rounded_boxes`, a box piece gets
    "collision_i_k", k = 0..8: `Piece.collision_shapes`) and a visual
    "visual_i". Returns the body."""
    model = plant.AddModelInstance(model_name)
    body = plant.AddRigidBody(spec.name, model, spec.spatial_inertia())
    for i, piece in enumerate(spec.pieces):
        properties = ProximityProperties()
        AddContactMaterial(friction=friction, properties=properties)
        shapes = piece.collision_shapes(rounded=rounded_boxes)
        for k, (X_OG, shape) in enumerate(shapes):
            name = f"collision_{i}" if len(shapes) == 1 else f"collision_{i}_{k}"
            plant.RegisterCollisionGeometry(body, X_OG, shape, name, properties)
        X_OG, shape = piece.X_OG(), piece.drake_shape()
        color = _GRASP_COLOR if piece.grasp else _PIECE_COLOR
        plant.RegisterVisualGeometry(body, X_OG, shape, f"visual_{i}", color)
    return body


def count_convex_vertices(pieces: tuple[Piece, ...]) -> int:
    """v_conv: the box corners that lie neither inside nor on another piece."""
    count = 0
    for i, piece in enumerate(pieces):
        corners = piece.corners()
        if not len(corners):
            continue
        covered = np.zeros(len(corners), dtype=bool)
        for j, other in enumerate(pieces):
            if j != i:
                covered |= other.depth(corners) >= -GEOMETRY_TOLERANCE
        count += int(np.sum(~covered))
    return count


def design_ballast(
    pieces: tuple[Piece, ...], density: float, p_OCm: np.ndarray
) -> tuple[float, Ballast | None]:
    """The base density (kg/m³) and ballast that give mean density `density`
    and centre of mass p_OCm, with the lowest ballast density found.

    With base density ρ0 over the volume V, centroid c, and a ballast sphere
    of volume Vb, centre b, density ρb: the excess ballast mass
    (ρb − ρ0)·Vb = ρ·V·d/λ when b = c + λ·u, with u and d the direction and
    distance from c to p_OCm (λ ≥ d), and ρ0 = ρ·(1 − d/λ). Along the ray,
    the ballast is the largest sphere centred at b inside one piece.
    Returns a ballast denser than MAX_BALLAST_DENSITY when none is lighter,
    and the densest candidate when none meets ρ0 ≥ MIN_BASE_DENSITY.
    """
    volumes = np.array([piece.volume for piece in pieces])
    V = volumes.sum()
    p_Oc = volumes @ np.array([piece.center for piece in pieces]) / V
    offset = p_OCm - p_Oc
    d = float(np.linalg.norm(offset))
    if d < 1e-12:
        return density, None
    u = offset / d
    reach = 2.0 * max(piece.max_distance_from(p_Oc) for piece in pieces)

    def candidates(lam: np.ndarray):
        b = p_Oc + lam[:, None] * u
        radius = np.max([piece.depth(b) for piece in pieces], axis=0)
        base = density * (1.0 - d / lam)
        with np.errstate(divide="ignore"):
            vb = 4.0 / 3.0 * math.pi * np.maximum(radius, 0.0) ** 3
            ballast = base + density * V * d / (lam * vb)
        ok = (radius > GEOMETRY_TOLERANCE) & (base >= MIN_BASE_DENSITY)
        return b, radius, base, np.where(ok, ballast, math.inf)

    lam = np.linspace(d, d + reach, 2001)
    best = int(np.argmin(candidates(lam)[3]))
    step = lam[1] - lam[0]
    lam = np.linspace(max(d, lam[best] - step), lam[best] + step, 201)
    b, radius, base, ballast = candidates(lam)
    best = int(np.argmin(ballast))
    if not math.isfinite(ballast[best]):
        return density, Ballast(p_OCm, 0.0, math.inf)
    return float(base[best]), Ballast(
        b[best], float(radius[best]), float(ballast[best])
    )
