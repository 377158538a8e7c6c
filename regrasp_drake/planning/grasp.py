"""The grasp as data, and the regrasp targets a user can ask for.

A grasp is the object's pose in the palm once it is held, X_PO (P: the hand's
`palm_surface` frame, +x from the wrist to the fingertips, +z the palm normal;
O: the object's frame, y along its symmetry axis), read as:
  axis       which way the object's +y points along the palm's y, against
             the start grasp (how it lay on the palm before the throw):
             "same" or "reversed";
  offset_mm  the palm centre's position along the object's own y, from its
             centre of mass (h_cm), [mm]; positive toward the object's +y
             end. The start grasp lies at 0 (the object is laid with its
             centre of mass over the palm's centre) and so does today's
             plan (the palm under the centre of mass, 10 mm toward the end
             landing first, which the landing takes back);
  tilt_deg   the angle between the object's axis and the palm's y (0-90);
  side       for an object with an off-axis centre of mass (r_cm != 0): the
             palm direction its offset (sign(r_cm)·x_O) points most along:
             "fingertips" (+x_P), "wrist" (-x_P), "away" (+z_P, away from
             the palm) or "into" (-z_P).

A target names the grasp wanted relative to the start grasp: `keep` (the
same orientation in the palm), `flip` (end over end: half a turn about the
palm's x, which reverses the axis and turns the side about x), `turn` (the
wrist's half turn about the palm's normal: the axis reversed, the side
turned about z), `any` (held at all, the paper's criterion), each with an
`offset_mm` along the axis. For an object symmetric about its axis (r_cm =
0) flip and turn are the same grasp: only the axis tells them from keep.

The robot's own sensors see the same: the three infrared sensors along the
palm's centre line (ir1-ir3, 20 mm apart along y) read the object's
distance above the palm along its axis, which shows where the palm holds it
and, for a lopsided object, which end lies where; the bumper at the palm's
centre says whether the object lies on it. This module reads the grasp from
the plant's poses instead, exactly.
"""

import dataclasses as dc
import math

import numpy as np

from regrasp_drake.errors import InputError, field_error
from regrasp_drake.world.objects import ObjectSpec

TARGET_KINDS = ("keep", "flip", "turn", "any")
# The half turns, in the palm frame, that take the start grasp's orientation
# to each target's.
_TARGET_ROTATIONS = {
    "keep": np.eye(3),
    "flip": np.diag([1.0, -1.0, -1.0]),  # half a turn about the palm's x
    "turn": np.diag([-1.0, -1.0, 1.0]),  # half a turn about its normal
}
SIDES = {"fingertips": (0, 1.0), "wrist": (0, -1.0), "away": (2, 1.0),
         "into": (2, -1.0)}

# A held grasp meets its target when the axis is the right way round and
# within this angle of the palm's y, [deg] ...
AXIS_TOLERANCE_DEG = 20.0
# ... and the offset within this of the target's, [mm].
OFFSET_TOLERANCE_MM = 10.0
# The palm's length along its y (sdf/hand.sdf: 0.115 m), and how far inside
# its edge the centre of mass must stay for the object not to tip off it,
# [m] (the outermost pads' centres lie 5 mm inside the edge; their contact
# patches reach about as far again).
PALM_LENGTH_M = 0.115
COM_INSIDE_EDGE_M = 0.02
# The offsets a target may name, [mm], whatever the object (each object's
# reach is narrower: offset_range_mm).
OFFSET_LIMIT_MM = 100.0


@dc.dataclass(frozen=True)
class Target:
    """The grasp a regrasp aims for (module docstring)."""
    kind: str = "any"
    offset_mm: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.kind, str) and self.kind in TARGET_KINDS):
            raise field_error("Target kind", self.kind,
                              "one of " + ", ".join(TARGET_KINDS))
        if not (isinstance(self.offset_mm, (int, float))
                and not isinstance(self.offset_mm, bool)
                and math.isfinite(self.offset_mm)
                and abs(self.offset_mm) <= OFFSET_LIMIT_MM):
            raise field_error(
                "Target offset_mm", self.offset_mm,
                f"a number in [-{OFFSET_LIMIT_MM:g}, +{OFFSET_LIMIT_MM:g}] "
                "mm (the palm centre along the object's axis from its "
                "centre of mass)")

    def as_dict(self) -> dict:
        return {"kind": self.kind, "offset_mm": float(self.offset_mm)}

    def label(self) -> str:
        return f"{self.kind}, {self.offset_mm:+.0f} mm"

    @staticmethod
    def parse(text: str, flag: str = "--targets") -> "Target":
        """A target written KIND:OFFSET_MM (e.g. flip:30; KIND alone: +0
        mm); InputError naming `flag` otherwise."""
        kind, _, offset = text.partition(":")
        try:
            return Target(kind, float(offset or 0.0))
        except ValueError:
            raise InputError(f"{flag}: got {text!r}, expected KIND:OFFSET_MM "
                             f"with KIND one of {TARGET_KINDS}, e.g. "
                             "flip:30") from None


@dc.dataclass(frozen=True)
class Grasp:
    """A grasp read from X_PO (module docstring)."""
    axis: str
    offset_mm: float
    tilt_deg: float
    side: str | None
    # The object's orientation in the palm frame (3×3, rows of R_PO).
    R_PO: tuple

    def as_dict(self) -> dict:
        out = {"axis": self.axis,
               "offset_mm": round(float(self.offset_mm), 2),
               "tilt_deg": round(float(self.tilt_deg), 2)}
        if self.side is not None:
            out["side"] = self.side
        return out


def has_side(obj: ObjectSpec) -> bool:
    """Whether the object's grasp has a side: an off-axis centre of mass."""
    return obj.r_cm != 0.0


def _side_name(v_P) -> str:
    i = int(np.argmax([abs(v_P[0]), abs(v_P[2])]))
    axis = (0, 2)[i]
    sign = 1.0 if v_P[axis] >= 0.0 else -1.0
    return next(k for k, v in SIDES.items() if v == (axis, sign))


def measure(obj: ObjectSpec, R_PO, p_PO, start_R_PO=None) -> Grasp:
    """The grasp of an object at (R_PO, p_PO) [-, m] in the palm frame;
    `start_R_PO`, the start grasp's orientation, sets which way is "same"
    (None: the start itself, the object's +y along the palm's +y)."""
    R_PO = np.asarray(R_PO, float)
    p_PO = np.asarray(p_PO, float)
    y_P = R_PO[:, 1]
    reference = (np.array([0.0, 1.0, 0.0]) if start_R_PO is None
                 else np.asarray(start_R_PO, float)[:, 1])
    same = np.sign(y_P[1]) == np.sign(reference[1])
    # The palm centre in O: p_OP = -R_OP p_PO.
    p_OP = -R_PO.T @ p_PO
    side = (_side_name(R_PO @ (np.sign(obj.r_cm) * np.array([1.0, 0, 0])))
            if has_side(obj) else None)
    return Grasp(axis="same" if same else "reversed",
                 offset_mm=float(1e3 * (p_OP[1] - obj.h_cm)),
                 tilt_deg=math.degrees(math.acos(min(1.0, abs(y_P[1])))),
                 side=side, R_PO=tuple(map(tuple, R_PO)))


def target_orientation(target: Target, start: Grasp) -> np.ndarray:
    """R_PO, the object's orientation in the palm frame that `target` asks
    for: the start grasp's turned as the target turns it."""
    return _TARGET_ROTATIONS[target.kind] @ np.asarray(start.R_PO)


def expected(target: Target, obj: ObjectSpec, start: Grasp):
    """(y_P, side): the object's axis in the palm frame that `target` asks
    for, and its side (None for an object without one), from the start
    grasp."""
    R = target_orientation(target, start)
    side = (_side_name(R @ (np.sign(obj.r_cm) * np.array([1.0, 0, 0])))
            if has_side(obj) else None)
    return R[:, 1], side


@dc.dataclass(frozen=True)
class Verdict:
    """How an achieved grasp compares with its target: `success` (held in
    the target grasp), the axis error (the angle between the object's axis
    and the palm's y the way round the target asks for, [deg]: over 90 when
    it lies the wrong way round), the offset error [mm], and whether the
    side matches (None without a side, or for target `any`)."""
    success: bool
    axis_error_deg: float | None
    offset_error_mm: float | None
    side_ok: bool | None

    def as_dict(self) -> dict:
        def rounded(x):
            return None if x is None else round(float(x), 2)
        return {"axis_error_deg": rounded(self.axis_error_deg),
                "offset_error_mm": rounded(self.offset_error_mm),
                "side_ok": self.side_ok}


def judge(target: Target, obj: ObjectSpec, start: Grasp,
          achieved: Grasp | None, held: bool) -> Verdict:
    """Whether a held grasp meets `target` (module docstring): the axis the
    right way round and within AXIS_TOLERANCE_DEG of the palm's y, the side
    the target's where the object has one, the offset within
    OFFSET_TOLERANCE_MM of the target's. The tilt is judged against the
    palm's y, not against the start grasp's turned: an object lies in the
    hand as its shape and the fingers let it (a lopsided one tilted on the
    palm), whichever way it arrived. `any`: held."""
    if achieved is None:
        return Verdict(False, None, None, None)
    offset_error = achieved.offset_mm - target.offset_mm
    if target.kind == "any":
        return Verdict(held, None, offset_error, None)
    y_wanted, side_wanted = expected(target, obj, start)
    y_P = np.asarray(achieved.R_PO)[:, 1]
    axis_error = math.degrees(math.acos(float(np.clip(
        y_P[1] * np.sign(y_wanted[1]), -1.0, 1.0))))
    side_ok = None if side_wanted is None else achieved.side == side_wanted
    success = (held and axis_error <= AXIS_TOLERANCE_DEG
               and side_ok is not False
               and abs(offset_error) <= OFFSET_TOLERANCE_MM)
    return Verdict(success, axis_error, offset_error, side_ok)


MISS_REASONS = ("dropped", "wrong_way_round", "tilted", "off_offset")


def miss_reason(held: bool, error: dict | None, *,
                side_apart: bool = False) -> str | None:
    """Why a throw under a grasp target is not in it, from whether it held
    the object and its `grasp_error` (Verdict.as_dict): "dropped" (not
    held), "wrong_way_round" (the axis reversed from the target's, or the
    side another), "tilted" (the axis more than AXIS_TOLERANCE_DEG from the
    palm's y), "off_offset" (more than OFFSET_TOLERANCE_MM from the target's
    offset); None when it is in the target grasp. side_apart: the side
    another, with the axis the right way round, is "wrong_side" (the
    learning phase and the studies count it as wrong_way_round)."""
    if not held or not error or error.get("axis_error_deg") is None:
        return "dropped" if not held else None
    if error["axis_error_deg"] >= 90.0:
        return "wrong_way_round"
    if error.get("side_ok") is False:
        return "wrong_side" if side_apart else "wrong_way_round"
    if error["axis_error_deg"] > AXIS_TOLERANCE_DEG:
        return "tilted"
    if abs(error["offset_error_mm"]) > OFFSET_TOLERANCE_MM:
        return "off_offset"
    return None


def kind_of(obj: ObjectSpec, start: Grasp, achieved: Grasp) -> str | None:
    """Which of keep, flip and turn an achieved grasp is (its axis the way
    round and its side as the target's, whatever its tilt and offset; for
    an object without a side, a reversed axis is "flip"); None: none of
    them (the axis kept but the side turned)."""
    for kind in ("keep", "flip", "turn"):
        y_wanted, side_wanted = expected(Target(kind), obj, start)
        if (np.sign(np.asarray(achieved.R_PO)[1][1]) == np.sign(y_wanted[1])
                and achieved.side == side_wanted):
            return kind
    return None


def describe(target: dict, achieved: dict | None, error: dict | None, *,
             outcome: str = "dropped", message: str = "") -> str:
    """One line for a regrasp's result, its verdict first: "flip, +0 mm: in
    the target grasp (held flip, +3 mm, tilt 12°)" ("any, +0 mm: caught
    (held flip, ...)" for `any`), "keep, +0 mm: missed,
    tilted 29° > 20° (held keep, +2 mm, tilt 29°)", "flip, +0 mm: missed,
    dropped" (target, achieved and error: the dicts of Target.as_dict, of
    an episode's achieved grasp (None: not held) and of its grasp_error,
    Verdict.as_dict; outcome and message: the episode's, for one not
    held)."""
    asked = Target(target["kind"], target["offset_mm"]).label()
    if achieved is None:
        why = outcome if outcome in ("dropped", "failed") else (
            f"not held ({outcome})")
        return f"{asked}: missed, {why}" + (f": {message}" if message else "")
    held = (f"held {achieved.get('kind') or 'another grasp'}, "
            + describe_grasp(achieved))
    reason = miss_reason(True, error, side_apart=True)
    if reason is None:
        verdict = "caught" if target["kind"] == "any" else "in the target grasp"
        return f"{asked}: {verdict} ({held})"
    why = {"wrong_way_round": "wrong way round", "wrong_side": "wrong side",
           "tilted": (f"tilted {error['axis_error_deg']:.0f}° > "
                      f"{AXIS_TOLERANCE_DEG:.0f}°"),
           "off_offset": (f"off the offset by "
                          f"{abs(error['offset_error_mm']):.0f} mm > "
                          f"{OFFSET_TOLERANCE_MM:.0f} mm")}[reason]
    return f"{asked}: missed, {why} ({held})"


def describe_grasp(g: dict) -> str:
    """A grasp's dict (Grasp.as_dict) in a few words: "+3 mm, tilt 12°"
    and its side, if it has one."""
    side = f", {g['side']}" if g.get("side") else ""
    return f"{g['offset_mm']:+.0f} mm, tilt {g['tilt_deg']:.0f}°{side}"


def offset_range_mm(obj: ObjectSpec) -> tuple[float, float]:
    """The offsets a target may ask for, [mm]: the palm centre on the object
    (within its extent along the axis) and the centre of mass at least
    COM_INSIDE_EDGE_M inside the palm's edge."""
    ends = []
    for piece in obj.pieces:
        half = _half_extent_y(piece)
        ends += [piece.center[1] - half, piece.center[1] + half]
    reach = PALM_LENGTH_M / 2 - COM_INSIDE_EDGE_M
    lo = max(min(ends), obj.h_cm - reach) - obj.h_cm
    hi = min(max(ends), obj.h_cm + reach) - obj.h_cm
    return round(1e3 * lo, 1), round(1e3 * hi, 1)


def _half_extent_y(piece) -> float:
    """A piece's half extent along the object's y, [m]."""
    if piece.shape == "box":
        return piece.size[1] / 2
    if piece.shape == "sphere":
        return piece.radius
    if piece.axis == 1:
        return piece.length / 2 + (piece.radius if piece.shape == "capsule"
                                   else 0.0)
    return piece.radius


def check_reachable(target: Target, obj: ObjectSpec,
                    field: str = "target offset_mm") -> None:
    """Refuses a target offset outside `offset_range_mm` (InputError naming
    `field`, where the caller gave the offset)."""
    lo, hi = offset_range_mm(obj)
    if not lo - 1e-9 <= target.offset_mm <= hi + 1e-9:
        raise InputError(
            f"object {obj.name}: {field} {target.offset_mm:+g} is "
            f"out of reach, expected an offset in [{lo:+.1f}, {hi:+.1f}] mm "
            "(the palm centre on the object, its centre of mass "
            f"{1e3 * COM_INSIDE_EDGE_M:.0f} mm inside the palm's edge)")
