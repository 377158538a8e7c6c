"""The objects the hand throws and catches, as data: a YAML catalogue of
rigid bodies made of simple pieces, with physically realizable mass
properties and the network's object features (paper §III-B and §V).

Object frame O (paper Fig. 2): the origin is the geometric centre of the
object's cylindrically symmetric grasp piece, y is that piece's axis. The
centre of mass is p_OCm = (r_cm, h_cm, 0): h_cm along y, r_cm along x, z = 0.

File format (the catalogue, ``sdf/objects/catalogue.yaml``, and a user's own
object file alike)::

    geometries:
      hammer:
        pieces:
          - {shape: cylinder, radius: 0.02, length: 0.08, axis: y,
             center: [0, 0, 0], grasp: true}
          - {shape: box, size: [0.09, 0.03, 0.04], center: [0, 0.055, 0]}
    objects:
      - {name: hammer-d200-1, set: train, geometry: hammer, density: 200,
         h_cm: 0.02, r_cm: 0.0}

Pieces (lengths in metres, all axis-aligned in O):
  - ``cylinder``: ``radius``, ``length``, ``axis`` (x|y|z), ``center``.
  - ``capsule``: as a cylinder; ``length`` is the cylindrical part, the two
    hemispherical caps add ``radius`` at each end.
  - ``box``: ``size`` [x, y, z] (full edge lengths), ``center``.
  - ``sphere``: ``radius``, ``center``.
  - ``grasp`` (optional, default false): exactly one piece has it; it is a
    cylinder or a capsule with axis y centred at the origin.
Pieces must not overlap (they may touch) and must form one connected body.
Objects: ``name`` (unique), ``set`` (train|ablation|test|holdout),
``geometry`` (a key of the same file's ``geometries``), ``density`` (kg/m³,
the object's mean density, the feature d_obj), ``h_cm`` and ``r_cm`` (m).
Every key listed is required, unknown keys are refused.

Bounds (what a PUMA 560 with this hand can throw; anything else is refused):
  - ``name``: 1 to 64 letters, digits and ``._+-``, starting with a letter or
    digit (it names files, e.g. ``grid-<name>.jsonl``);
  - lengths (``radius``, ``length``, each ``size``): SIZE_RANGE_M, 1 mm to
    0.3 m; each ``center`` coordinate within ±MAX_CENTER_M (0.3 m);
  - at most MAX_PIECES pieces per geometry, MAX_GEOMETRIES geometries and
    MAX_OBJECTS objects per file;
  - ``density``: DENSITY_RANGE, 20 (rigid foam) to 20 000 kg/m³ (tungsten);
  - mass (density × volume): MASS_RANGE_KG, 1 g to 2.5 kg (the PUMA 560's
    rated payload);
  - ``h_cm``, ``r_cm``: the centre of mass inside the body (and a ballast
    that can put it there, below).
The file itself is read within the limits of regrasp_drake/input_files.py
(size, nesting, aliases, duplicate keys, finite numbers).

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
import re
from pathlib import Path

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
from pydrake.solvers import ClarabelSolver, MathematicalProgram

from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import load_yaml

CATALOGUE_PATH = (
    Path(__file__).resolve().parents[2] / "sdf" / "objects" / "catalogue.yaml"
)

MIN_BASE_DENSITY = 20.0  # kg/m³, the lightest base material (rigid foam).
MAX_BALLAST_DENSITY = 20_000.0  # kg/m³, a little above tungsten (19 300).
# Physical bounds of an object (module docstring).
SIZE_RANGE_M = (0.001, 0.3)
MAX_CENTER_M = 0.3
MAX_PIECES = 16
MAX_GEOMETRIES = 100
# A box's collision box lies this far inside its faces (Piece.collision_shapes).
BOX_INSET_M = 0.0005
MAX_OBJECTS = 1000
DENSITY_RANGE = (MIN_BASE_DENSITY, MAX_BALLAST_DENSITY)  # kg/m³
MASS_RANGE_KG = (0.001, 2.5)
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")

SETS = ("train", "ablation", "test", "holdout")
AXES = {"x": 0, "y": 1, "z": 2}
_PIECE_KEYS = {
    "cylinder": ("radius", "length", "axis", "center"),
    "capsule": ("radius", "length", "axis", "center"),
    "box": ("size", "center"),
    "sphere": ("radius", "center"),
}
_OBJECT_KEYS = ("name", "set", "geometry", "density", "h_cm", "r_cm")
# Two pieces overlap when a ball of this radius fits inside both; they touch
# when they are closer than this. Also the tolerance of "a corner is on a
# piece" and "the centre of mass is inside the body".
_GEOMETRY_TOLERANCE = 1e-6  # m
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


def add_object(
    plant: MultibodyPlant,
    spec: ObjectSpec,
    friction: CoulombFriction,
    model_name: str = "object",
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


def load_catalogue(path: Path | str = CATALOGUE_PATH) -> dict[str, ObjectSpec]:
    """The objects of the catalogue by name, training objects, then the
    ablation's, test and held-out objects, each set in file order."""
    specs = load_object_file(path)
    ordered = [s for group in SETS for s in specs if s.set == group]
    return {spec.name: spec for spec in ordered}


def load_object_file(path: Path | str) -> list[ObjectSpec]:
    """The objects of an object file (format in the module docstring), in file
    order. Raises InputError naming the file and the field on bad input."""
    path = Path(path)
    data = load_yaml(path, "YAML object file")
    try:
        return _parse_file(data)
    except InputError as e:
        raise InputError(f"{path}: {e}") from None


def resolve_object(
    name: str | None = None, file: Path | str | None = None
) -> ObjectSpec:
    """The object a user asks for: `name` from the catalogue; or the first
    object of `file`; or, given both, the object `name` of `file`."""
    if name is None and file is None:
        raise field_error("object", None, "an object name or an object file")
    if file is not None:
        specs = {spec.name: spec for spec in load_object_file(file)}
        source = str(file)
    else:
        specs = load_catalogue()
        source = str(CATALOGUE_PATH)
    if name is None:
        return next(iter(specs.values()))
    if name not in specs:
        examples = ", ".join(list(specs)[:3])
        raise field_error(
            "object name",
            name,
            f"one of the {len(specs)} names in {source} (the `name` keys of its "
            f"objects, e.g. {examples})",
        )
    return specs[name]


# Parsing and validation.


def _parse_file(data) -> list[ObjectSpec]:
    data = _mapping(data, "file", ("geometries", "objects"))
    geometries_data = _mapping(data["geometries"], "geometries")
    if len(geometries_data) > MAX_GEOMETRIES:
        raise field_error(
            "geometries",
            f"{len(geometries_data)} geometries",
            f"at most {MAX_GEOMETRIES}",
        )
    geometries = {
        name: _parse_geometry(value, f"geometries.{_key(name)}")
        for name, value in geometries_data.items()
    }
    objects = data["objects"]
    if not isinstance(objects, list) or not objects:
        raise field_error("objects", objects, "a non-empty list of objects")
    if len(objects) > MAX_OBJECTS:
        raise field_error(
            "objects", f"{len(objects)} objects", f"at most {MAX_OBJECTS}"
        )
    specs, names = [], set()
    for i, item in enumerate(objects):
        spec = _parse_object(item, f"objects[{i}]", geometries)
        if spec.name in names:
            raise field_error(f"objects[{i}].name", spec.name, "a name not used before")
        names.add(spec.name)
        specs.append(spec)
    return specs


def _key(name) -> str:
    """A mapping key as it appears in a field's name (cut when long)."""
    return name if isinstance(name, str) and len(name) <= 64 else quote(name)


def _mapping(value, field: str, keys: tuple[str, ...] | None = None) -> dict:
    """`value` as a dict; with `keys`, exactly those keys."""
    if not isinstance(value, dict) or not value:
        expected = (
            f"a mapping with keys {', '.join(keys)}" if keys else "a non-empty mapping"
        )
        raise field_error(field, value, expected)
    if keys is not None:
        _check_keys(value, field, required=keys)
    return value


def _check_keys(value: dict, field: str, required, optional=()) -> None:
    for key in value:
        if key not in required and key not in optional:
            allowed = ", ".join(tuple(required) + tuple(optional))
            raise field_error(
                f"{field}.{_key(key)}", value[key], f"no such key (keys: {allowed})"
            )
    for key in required:
        if key not in value:
            raise field_error(f"{field}.{key}", None, f"a value (missing key {key!r})")


def _number(value, field: str, bounds=(-math.inf, math.inf), unit="") -> float:
    """`value` as a float in [lo, hi] = bounds."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if ok and math.isfinite(value) and bounds[0] <= value <= bounds[1]:
        return float(value)
    if math.isinf(bounds[0]) and math.isinf(bounds[1]):
        raise field_error(field, value, "a finite number")
    raise field_error(field, value, f"a number in [{bounds[0]:g}, {bounds[1]:g}]{unit}")


def _vector(value, field: str, bounds) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        raise field_error(field, value, "a list of 3 numbers")
    return np.array(
        [_number(v, f"{field}[{i}]", bounds, " m") for i, v in enumerate(value)]
    )


def _parse_piece(value, field: str) -> Piece:
    if not isinstance(value, dict):
        raise field_error(field, value, "a mapping describing a piece")
    shape = value.get("shape")
    if not isinstance(shape, str) or shape not in _PIECE_KEYS:
        raise field_error(f"{field}.shape", shape, f"one of {', '.join(_PIECE_KEYS)}")
    _check_keys(
        value, field, required=("shape",) + _PIECE_KEYS[shape], optional=("grasp",)
    )
    grasp = value.get("grasp", False)
    if not isinstance(grasp, bool):
        raise field_error(f"{field}.grasp", grasp, "true or false")
    axis = None
    if "axis" in value:
        if not isinstance(value["axis"], str) or value["axis"] not in AXES:
            raise field_error(f"{field}.axis", value["axis"], "one of x, y, z")
        axis = AXES[value["axis"]]
    center = (-MAX_CENTER_M, MAX_CENTER_M)
    return Piece(
        shape=shape,
        center=_vector(value["center"], f"{field}.center", center),
        radius=_number(value["radius"], f"{field}.radius", SIZE_RANGE_M, " m")
        if "radius" in value
        else None,
        length=_number(value["length"], f"{field}.length", SIZE_RANGE_M, " m")
        if "length" in value
        else None,
        size=_vector(value["size"], f"{field}.size", SIZE_RANGE_M)
        if "size" in value
        else None,
        axis=axis,
        grasp=grasp,
    )


def _parse_geometry(value, field: str) -> tuple[Piece, ...]:
    value = _mapping(value, field, ("pieces",))
    if not isinstance(value["pieces"], list) or not value["pieces"]:
        raise field_error(
            f"{field}.pieces", value["pieces"], "a non-empty list of pieces"
        )
    if len(value["pieces"]) > MAX_PIECES:
        raise field_error(
            f"{field}.pieces", f"{len(value['pieces'])} pieces",
            f"at most {MAX_PIECES}"
        )
    pieces = tuple(
        _parse_piece(item, f"{field}.pieces[{i}]")
        for i, item in enumerate(value["pieces"])
    )
    grasp = [i for i, piece in enumerate(pieces) if piece.grasp]
    if len(grasp) != 1:
        raise field_error(
            f"{field}.pieces[*].grasp",
            f"{len(grasp)} grasp pieces",
            "exactly one grasp: true",
        )
    g = pieces[grasp[0]]
    if g.shape not in ("cylinder", "capsule") or g.axis != 1 or np.any(g.center != 0.0):
        axis = f" along {'xyz'[g.axis]}" if g.axis is not None else ""
        raise field_error(
            f"{field}.pieces[{grasp[0]}]",
            f"{g.shape}{axis} at {g.center.tolist()}",
            "a cylindrically symmetric grasp piece: a cylinder or capsule with "
            "axis y and center [0, 0, 0]",
        )
    _check_layout(pieces, field)
    return pieces


def _check_layout(pieces: tuple[Piece, ...], field: str) -> None:
    """Refuses overlapping pieces and pieces that do not form one body."""
    n = len(pieces)
    linked = np.eye(n, dtype=bool)
    for i, j in itertools.combinations(range(n), 2):
        depth = _common_depth(pieces[i], pieces[j])
        if depth > _GEOMETRY_TOLERANCE:
            raise field_error(
                f"{field}.pieces[{j}]",
                f"overlaps pieces[{i}] (a ball of radius {depth:.3g} m fits in both)",
                "pieces that do not overlap (they may touch)",
            )
        linked[i, j] = linked[j, i] = (
            _distance(pieces[i], pieces[j]) <= _GEOMETRY_TOLERANCE
        )
    reached = linked[0].copy()
    for _ in range(n):
        reached = np.any(linked[reached], axis=0)
    if not reached.all():
        loose = int(np.flatnonzero(~reached)[0])
        raise field_error(
            f"{field}.pieces[{loose}]",
            "not touching the other pieces",
            "pieces that form one connected body",
        )


def _add_membership(prog: MathematicalProgram, piece: Piece, p, margin) -> None:
    """Constrains point p (decision variables) to lie at least `margin` (an
    expression, m) inside the piece."""
    # Element by element: numpy's vectorized arithmetic on symbolic arrays
    # reports stale floating-point flags as warnings.
    d = [p[i] - float(piece.center[i]) for i in range(3)]
    if piece.shape == "box":
        for i in range(3):
            prog.AddLinearConstraint(d[i] <= piece.size[i] / 2.0 - margin)
            prog.AddLinearConstraint(-d[i] <= piece.size[i] / 2.0 - margin)
        return
    if piece.shape == "sphere":
        prog.AddLorentzConeConstraint(np.array([piece.radius - margin] + d))
        return
    k = piece.axis
    if piece.shape == "capsule":
        s = prog.NewContinuousVariables(1, "s")[0]
        prog.AddBoundingBoxConstraint(-piece.length / 2.0, piece.length / 2.0, s)
        d[k] = d[k] - s
        prog.AddLorentzConeConstraint(np.array([piece.radius - margin] + d))
        return
    prog.AddLinearConstraint(d[k] <= piece.length / 2.0 - margin)
    prog.AddLinearConstraint(-d[k] <= piece.length / 2.0 - margin)
    radial = [d[i] for i in range(3) if i != k]
    prog.AddLorentzConeConstraint(np.array([piece.radius - margin] + radial))


def _solve(prog: MathematicalProgram):
    result = ClarabelSolver().Solve(prog)
    if not result.is_success():
        return None
    return result


def _common_depth(a: Piece, b: Piece) -> float:
    """The radius (m) of the largest ball inside both pieces; ≤ 0 when their
    interiors do not meet."""
    prog = MathematicalProgram()
    p = prog.NewContinuousVariables(3, "p")
    t = prog.NewContinuousVariables(1, "t")[0]
    _add_membership(prog, a, p, t)
    _add_membership(prog, b, p, t)
    prog.AddLinearCost(-t)
    result = _solve(prog)
    return -math.inf if result is None else float(result.GetSolution(t))


def _distance(a: Piece, b: Piece) -> float:
    """The distance (m) between two pieces (0 when they touch)."""
    prog = MathematicalProgram()
    p = prog.NewContinuousVariables(3, "p")
    q = prog.NewContinuousVariables(3, "q")
    s = prog.NewContinuousVariables(1, "s")[0]
    _add_membership(prog, a, p, 0.0)
    _add_membership(prog, b, q, 0.0)
    prog.AddLorentzConeConstraint(np.array([s] + [p[i] - q[i] for i in range(3)]))
    prog.AddLinearCost(s)
    result = _solve(prog)
    return math.inf if result is None else float(result.GetSolution(s))


def _parse_object(value, field: str, geometries: dict) -> ObjectSpec:
    if not isinstance(value, dict):
        raise field_error(field, value, "a mapping describing an object")
    _check_keys(value, field, required=_OBJECT_KEYS)
    name = value["name"]
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        raise field_error(
            f"{field}.name", name, "1 to 64 letters, digits and ._+- (a "
            "name safe in a file name), starting with a letter or digit"
        )
    if not isinstance(value["set"], str) or value["set"] not in SETS:
        raise field_error(f"{field}.set", value["set"], f"one of {', '.join(SETS)}")
    geometry = value["geometry"]
    if not isinstance(geometry, str) or geometry not in geometries:
        raise field_error(
            f"{field}.geometry",
            geometry,
            f"one of the file's geometries ({', '.join(geometries)})",
        )
    density = _number(value["density"], f"{field}.density", DENSITY_RANGE, " kg/m³")
    h_cm = _number(value["h_cm"], f"{field}.h_cm")
    r_cm = _number(value["r_cm"], f"{field}.r_cm")
    pieces = geometries[geometry]
    mass = density * sum(piece.volume for piece in pieces)
    if not MASS_RANGE_KG[0] <= mass <= MASS_RANGE_KG[1]:
        raise field_error(
            f"{field}.density",
            density,
            f"a mass (density × the {geometry} volume) in "
            f"[{MASS_RANGE_KG[0]:g}, {MASS_RANGE_KG[1]:g}] kg, not {mass:.3g} kg",
        )
    p_OCm = np.array([r_cm, h_cm, 0.0])
    if max(float(piece.depth(p_OCm)[0]) for piece in pieces) < -_GEOMETRY_TOLERANCE:
        raise field_error(
            f"{field}.h_cm/r_cm",
            (h_cm, r_cm),
            f"a centre of mass (r_cm, h_cm, 0) inside the body of geometry {geometry}",
        )
    volume = sum(piece.volume for piece in pieces)
    base_density, ballast = _design_ballast(pieces, density, p_OCm)
    if ballast is not None and ballast.density > MAX_BALLAST_DENSITY:
        needs = (
            f"needs {ballast.density:.0f} kg/m³"
            if math.isfinite(ballast.density)
            else "no ballast sphere fits beyond it"
        )
        raise field_error(
            f"{field}.h_cm/r_cm",
            (h_cm, r_cm),
            f"a centre of mass a ballast of at most {MAX_BALLAST_DENSITY:.0f} "
            f"kg/m³ can reach with density {density:g} ({needs})",
        )
    return ObjectSpec(
        name=name,
        set=value["set"],
        geometry=geometry,
        pieces=pieces,
        density=density,
        h_cm=h_cm,
        r_cm=r_cm,
        volume=volume,
        v_conv=count_convex_vertices(pieces),
        base_density=base_density,
        ballast=ballast,
    )


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
                covered |= other.depth(corners) >= -_GEOMETRY_TOLERANCE
        count += int(np.sum(~covered))
    return count


def _design_ballast(
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
        ok = (radius > _GEOMETRY_TOLERANCE) & (base >= MIN_BASE_DENSITY)
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
