"""The regrasp library: what the learning phase learned, per object, in YAML.

The applying phase (paper §II) reads it to throw and catch an object in one
throw "with the exact same regrasp parameters attained in learning phase".
Those parameters hold only for the throw they were learned with, so an entry
keeps its provenance: the scenario (file and a digest of its values) and the
object's features; `apply` refuses an entry whose scenario or object differs.

The file (the command line's default: `regrasp_library.yaml` under its
`--out-dir`, by default `out/`):

    format: regrasp_drake.library
    version: 1
    objects:
      table1-row2:
        object_source: catalogue     # or the object file it came from
        object_features: {h_cm: …, r_cm: …, d_obj: …, v_conv: …}
        scenario: defaults           # or the scenario file
        scenario_digest: 3f2a…       # sha256 of the scenario's values
        code_version: 0.1.0
        catch_point: {t_s: …, p_WO: [x, y, z], axis_W: […], v_catch: …, tilt: …}
        p_WG: [x, y, z]              # the palm's grasp pose, [m]
        R_WG: [[…], […], […]]        # its rotation matrix, rows
        q_grasp: [6 joint angles]    # the arm there, [rad]
        side: paper                  # or mirrored
        h_catch: 0.2                 # [m]
        h_down: -0.05                # [m]
        cell: [4, 9]                 # (i_catch, i_down) of the grid
        throws: 2                    # the learning phase's throws, the watch
                                     # included (1: caught on the first throw)
        mode: watch                  # how the catch was planned: watch (a
                                     # watching throw first), first-throw (the
                                     # flight predictor) or at-release
        search: wavefront            # the search after the network's cell:
                                     # wavefront or map-prior

`mode` and `search` were added after the first libraries were written: an
entry without them reads them as None (not recorded).

Bounds (anything else is refused, naming the field): object names as in an
object file (safe in a file name); the object features within an object
file's bounds (|h_cm|, |r_cm| <= 0.3 m, d_obj 20 … 20 000 kg/m³, v_conv an
integer 0 … 128); t_s 0 … 60 s; |p_WO|, |p_WG| components <= 3 m; axis_W a
unit vector; |v_catch| <= 50 m/s; tilt 0 … 1; R_WG a rotation; q_grasp
within the PUMA 560's joint limits (sdf/puma560.sdf); h_catch, h_down in the
parameter space; cell in the grid. The file is read within the limits of
regrasp_drake/input_files.py (size, nesting, aliases, duplicate keys,
finite numbers).
"""

import dataclasses as dc
import math
from pathlib import Path

import numpy as np
import yaml
from pydrake.math import RigidTransform, RotationMatrix

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.input_files import check_format, load_yaml
from regrasp_drake.learning.search import SEARCHES
from regrasp_drake.parameter_space import (
    H_CATCH_RANGE,
    H_CATCH_VALUES,
    H_DOWN_RANGE,
    H_DOWN_VALUES,
)
from regrasp_drake.world.objects import DENSITY_RANGE, MAX_CENTER_M, NAME_PATTERN
from regrasp_drake.world.robot import arm_joint_limits

# Its file name when the command line is given none (under its --out-dir).
DEFAULT_LIBRARY = "regrasp_library.yaml"
_FORMAT = "regrasp_drake.library"
_VERSION = 1
_FEATURES = ("h_cm", "r_cm", "d_obj", "v_conv")
_CATCH_POINT = ("t_s", "p_WO", "axis_W", "v_catch", "tilt")
MODES = ("watch", "first-throw", "at-release")
# Fields an entry may lack (older libraries): they read as None.
_OPTIONAL = ("mode", "search", "chosen_by")
# Who can have chosen a learned cell (learning/planner.py Planner.name, then the
# search).
CHOSEN_BY = ("learned", "best_constant", "paper_network", "rehearsal",
             "search")


@dc.dataclass
class LearnedEntry:
    """One object's learned catch (units as in the module's docstring)."""
    object_source: str
    object_features: dict
    scenario: str
    scenario_digest: str
    code_version: str
    catch_point: dict
    p_WG: list
    R_WG: list
    q_grasp: list
    side: str
    h_catch: float
    h_down: float
    cell: list
    throws: int
    mode: str | None = None    # one of MODES; None: not recorded
    search: str | None = None  # wavefront or map-prior; None: not recorded
    # Who chose the catching cell (learning/planner.py Planner.name, or
    # "search"); None: not recorded.
    chosen_by: str | None = None

    @property
    def X_WG(self) -> RigidTransform:
        return RigidTransform(RotationMatrix(np.array(self.R_WG)),
                              np.array(self.p_WG))

    def as_dict(self) -> dict:
        return dc.asdict(self)


def load_library(path) -> dict[str, LearnedEntry]:
    """The entries of the library at path, by object name; {} when the file
    does not exist. Raises InputError naming the file and the field for a
    malformed file."""
    path = Path(path)
    if not path.exists():
        return {}
    data = load_yaml(path, "YAML regrasp library")
    check_format(data, path, _FORMAT)
    if data.get("version") != _VERSION:
        raise field_error(f"{path}: version", data.get("version"), str(_VERSION))
    unknown = [k for k in data if k not in ("format", "version", "objects")]
    if unknown:
        raise field_error(f"{path}: keys", unknown,
                          "only format, version and objects")
    objects = data.get("objects") or {}
    if not isinstance(objects, dict):
        raise field_error(f"{path}: objects", objects,
                          "a mapping from object names to entries")
    for name in objects:
        if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
            raise field_error(f"{path}: objects", name, "object names of 1 "
                              "to 64 letters, digits and ._+-")
    return {name: _entry(f"{path}: objects.{name}", raw)
            for name, raw in objects.items()}


def save_library(path, entries: dict[str, LearnedEntry]) -> Path:
    """Writes the entries to path (atomically: a reader never sees half a
    file; atomic_io.WriteError when it cannot be written, the old file
    kept). Returns path."""
    path = Path(path)
    data = {"format": _FORMAT, "version": _VERSION,
            "objects": {name: entries[name].as_dict() for name in sorted(entries)}}
    return atomic_io.write_text(path, yaml.safe_dump(
        data, sort_keys=False, default_flow_style=None, width=100))


def lock_path(path) -> Path:
    """The lock file beside a library (L.lock) that its updates hold."""
    path = Path(path)
    return path.with_name(path.name + ".lock")


def store(path, name: str, entry: LearnedEntry) -> Path:
    """Adds or replaces the entry of object `name` in the library at path,
    under the library's lock for the whole read-modify-write (runs that
    store at once wait for each other: none loses another's entry)."""
    with atomic_io.exclusive(lock_path(path), what=str(path), wait=True):
        entries = load_library(path)
        entries[name] = entry
        return save_library(path, entries)


def lookup(path, name: str) -> LearnedEntry:
    """The entry of object `name`; InputError saying to run `learn` first when
    there is none."""
    entries = load_library(path)
    if name not in entries:
        where = (f"{path} has no entry for it" if Path(path).exists()
                 else f"{path} does not exist")
        raise InputError(
            f"object {name}: nothing learned yet ({where}); run "
            f"`regrasp-drake learn` on it first (with the same --library)")
    return entries[name]


# ---- validation ---------------------------------------------------------
def _entry(where: str, raw) -> LearnedEntry:
    if not isinstance(raw, dict):
        raise field_error(where, raw, "a mapping of the entry's fields")
    names = [f.name for f in dc.fields(LearnedEntry)]
    missing = [n for n in names if n not in raw and n not in _OPTIONAL]
    if missing:
        raise InputError(f"{where}.{missing[0]}: missing")
    unknown = [k for k in raw if k not in names]
    if unknown:
        raise field_error(f"{where}: keys", unknown, f"only {names}")
    for n in ("object_source", "scenario", "scenario_digest", "code_version"):
        _string(f"{where}.{n}", raw[n])
    features = _mapping(f"{where}.object_features", raw["object_features"],
                        _FEATURES)
    for n in ("h_cm", "r_cm"):
        _number(f"{where}.object_features.{n}", features[n],
                -MAX_CENTER_M, MAX_CENTER_M, " m")
    _number(f"{where}.object_features.d_obj", features["d_obj"],
            *DENSITY_RANGE, " kg/m³")
    if not (type(features["v_conv"]) is int and 0 <= features["v_conv"] <= 128):
        raise field_error(f"{where}.object_features.v_conv",
                          features["v_conv"], "an integer in [0, 128]")
    point = _mapping(f"{where}.catch_point", raw["catch_point"], _CATCH_POINT)
    _number(f"{where}.catch_point.t_s", point["t_s"], 0.0, 60.0, " s")
    _number(f"{where}.catch_point.v_catch", point["v_catch"], -50.0, 50.0,
            " m/s")
    _number(f"{where}.catch_point.tilt", point["tilt"], 0.0, 1.0)
    _vector(f"{where}.catch_point.p_WO", point["p_WO"], 3, -3.0, 3.0, " m")
    _vector(f"{where}.catch_point.axis_W", point["axis_W"], 3, -1.0, 1.0)
    if abs(np.linalg.norm(np.array(point["axis_W"], float)) - 1.0) > 1e-3:
        raise field_error(f"{where}.catch_point.axis_W", point["axis_W"],
                          "a unit vector")
    _vector(f"{where}.p_WG", raw["p_WG"], 3, -3.0, 3.0, " m")
    R = raw["R_WG"]
    if not (isinstance(R, list) and len(R) == 3):
        raise field_error(f"{where}.R_WG", R, "3 rows of 3 numbers")
    for i, row in enumerate(R):
        _vector(f"{where}.R_WG[{i}]", row, 3)
    R = np.array(R, float)
    if (np.abs(R).max() > 1.0 + 1e-6  # (and no overflow in the product)
            or np.abs(R @ R.T - np.eye(3)).max() > 1e-6
            or abs(np.linalg.det(R) - 1.0) > 1e-6):
        raise field_error(f"{where}.R_WG",
                          [[round(x, 6) for x in row] for row in raw["R_WG"]],
                          "a rotation matrix (orthonormal, det +1)")
    _vector(f"{where}.q_grasp", raw["q_grasp"], 6)
    for i, (q, (lo, hi)) in enumerate(zip(raw["q_grasp"], arm_joint_limits())):
        _number(f"{where}.q_grasp[{i}]", q, lo, hi,
                f" rad (joint{i + 1}'s limits in puma560.sdf)")
    if raw["side"] not in ("paper", "mirrored"):
        raise field_error(f"{where}.side", raw["side"], "paper or mirrored")
    _number(f"{where}.h_catch", raw["h_catch"], *H_CATCH_RANGE, " m")
    _number(f"{where}.h_down", raw["h_down"], *H_DOWN_RANGE, " m")
    cell = raw["cell"]
    if not (isinstance(cell, list) and len(cell) == 2
            and all(type(k) is int for k in cell)
            and 0 <= cell[0] < len(H_CATCH_VALUES)
            and 0 <= cell[1] < len(H_DOWN_VALUES)):
        raise field_error(f"{where}.cell", cell,
                          f"[i_catch, i_down], integers below "
                          f"{len(H_CATCH_VALUES)} and {len(H_DOWN_VALUES)}")
    # First-throw mode can catch on throw 1 (no watching throw).
    if not (type(raw["throws"]) is int and raw["throws"] >= 1):
        raise field_error(f"{where}.throws", raw["throws"], "an integer >= 1")
    for n, allowed in (("mode", MODES), ("search", SEARCHES),
                       ("chosen_by", CHOSEN_BY)):
        if raw.get(n) is not None and raw[n] not in allowed:
            raise field_error(f"{where}.{n}", raw[n],
                              f"one of {list(allowed)} (or absent)")
    return LearnedEntry(**raw)


def _string(field, value):
    if not isinstance(value, str) or not value:
        raise field_error(field, value, "a non-empty string")


def _number(field, value, lo=-math.inf, hi=math.inf, unit=""):
    if not (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value) and lo <= value <= hi):
        expected = ("a finite number" if math.isinf(lo) and math.isinf(hi)
                    else f"a number in [{lo}, {hi}]{unit}")
        raise field_error(field, value, expected)


def _vector(field, value, n, lo=-math.inf, hi=math.inf, unit=""):
    if not (isinstance(value, list) and len(value) == n):
        raise field_error(field, value, f"a list of {n} numbers")
    for i, x in enumerate(value):
        _number(f"{field}[{i}]", x, lo, hi, unit)


def _mapping(field, value, keys) -> dict:
    if not isinstance(value, dict) or set(value) != set(keys):
        raise field_error(field, value, f"a mapping with exactly {list(keys)}")
    return value
