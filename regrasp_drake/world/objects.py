"""The objects the hand throws and catches, as data: a YAML catalogue of
rigid bodies made of simple pieces, with physically realizable mass
properties and the network's object features (paper §III-B and §V).

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

The objects themselves (pieces, mass distribution, v_conv, the plant body):
world/object_model.py.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram

from regrasp_drake.errors import InputError, field_error, quote
from regrasp_drake.input_files import load_yaml
from regrasp_drake.paths import SDF_DIR
from regrasp_drake.world.object_model import (
    AXES,
    GEOMETRY_TOLERANCE,
    MAX_BALLAST_DENSITY,
    MIN_BASE_DENSITY,
    ObjectSpec,
    Piece,
    count_convex_vertices,
    design_ballast,
)

CATALOGUE_PATH = SDF_DIR / "objects" / "catalogue.yaml"

# Physical bounds of an object (module docstring).
SIZE_RANGE_M = (0.001, 0.3)
MAX_CENTER_M = 0.3
MAX_PIECES = 16
MAX_GEOMETRIES = 100
MAX_OBJECTS = 1000
DENSITY_RANGE = (MIN_BASE_DENSITY, MAX_BALLAST_DENSITY)  # kg/m³
MASS_RANGE_KG = (0.001, 2.5)
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,63}")

SETS = ("train", "ablation", "test", "holdout")
_PIECE_KEYS = {
    "cylinder": ("radius", "length", "axis", "center"),
    "capsule": ("radius", "length", "axis", "center"),
    "box": ("size", "center"),
    "sphere": ("radius", "center"),
}
_OBJECT_KEYS = ("name", "set", "geometry", "density", "h_cm", "r_cm")


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
        if depth > GEOMETRY_TOLERANCE:
            raise field_error(
                f"{field}.pieces[{j}]",
                f"overlaps pieces[{i}] (a ball of radius {depth:.3g} m fits in both)",
                "pieces that do not overlap (they may touch)",
            )
        linked[i, j] = linked[j, i] = (
            _distance(pieces[i], pieces[j]) <= GEOMETRY_TOLERANCE
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
    if max(float(piece.depth(p_OCm)[0]) for piece in pieces) < -GEOMETRY_TOLERANCE:
        raise field_error(
            f"{field}.h_cm/r_cm",
            (h_cm, r_cm),
            f"a centre of mass (r_cm, h_cm, 0) inside the body of geometry {geometry}",
        )
    volume = sum(piece.volume for piece in pieces)
    base_density, ballast = design_ballast(pieces, density, p_OCm)
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
