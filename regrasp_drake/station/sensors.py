"""The hand's sensors: infrared range sensors and a tactile bumper (paper §V.B).

Both are sampled systems: each holds its readings as discrete state, refreshed
by a periodic discrete update (and once at initialization), and exposes that
state through a state output port, so that reading an output costs no Python
between samples.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    Box,
    Capsule,
    Cylinder,
    GeometryId,
    QueryObject,
    SceneGraphInspector,
    Sphere,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import ContactResults, MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.systems.framework import LeafSystem

from regrasp_drake.errors import field_error

# The sphere trace stops when it is this close to a target surface (m); it is
# tightened to a tenth of a quantum for very short ranges.
_HIT_TOLERANCE_M = 1e-4
# A ray that grazes a surface takes many small steps; past this many, it is
# counted as a miss.
_MAX_TRACE_STEPS = 200


def quantize(distance_m: float, range_m: float, levels: int = 1000) -> int:
    """Returns the sensor level of a distance: floor(distance / range · levels),
    capped at `levels`, which means "nothing in range". A negative distance
    (the ray starts inside a target) reads 0."""
    if not distance_m < range_m:  # Also catches inf and nan.
        return levels
    return min(levels, max(0, math.floor(distance_m / range_m * levels)))


def unquantize(level: float, range_m: float, levels: int = 1000) -> float:
    """Returns the distance (m) at the middle of a level's bin, or inf for a
    level of `levels` or more (nothing in range)."""
    if level >= levels:
        return math.inf
    return (max(0.0, level) + 0.5) * range_m / levels


def _sphere_entry(p_WS, z_W, p_WC, radius_m) -> float:
    """Distance along the ray (p_WS, unit z_W) to where it enters the sphere
    (p_WC, radius_m): 0 if it starts inside, inf if it misses."""
    p_SC = p_WC - p_WS
    along = float(np.dot(p_SC, z_W))
    miss2 = float(np.dot(p_SC, p_SC)) - along * along
    if float(np.dot(p_SC, p_SC)) <= radius_m * radius_m:
        return 0.0
    if along < 0 or miss2 > radius_m * radius_m:
        return math.inf
    return along - math.sqrt(radius_m * radius_m - miss2)


def trace_ray(
    query_object: QueryObject,
    p_WS: np.ndarray,
    z_W: np.ndarray,
    range_m: float,
    target_ids: frozenset,
    tolerance_m: float = _HIT_TOLERANCE_M,
) -> float:
    """Returns the distance (m) along the ray from p_WS in the unit direction
    z_W to the first target geometry, or inf if none lies within `range_m`.

    Sphere tracing: at each point the smallest signed distance to a target
    geometry is a step that cannot pass through any target.
    """
    s = 0.0
    for _ in range(_MAX_TRACE_STEPS):
        p_WQ = p_WS + s * z_W
        distances = query_object.ComputeSignedDistanceToPoint(
            p_WQ, threshold=range_m - s
        )
        step = min(
            (d.distance for d in distances if d.id_G in target_ids),
            default=math.inf,
        )
        if step < tolerance_m:
            return s
        s += step
        if s >= range_m:
            return math.inf
    return math.inf


def _sphere_hits(o, d, center, radius):
    """Entry distance along rays (origins o, unit directions d: N×3) into
    balls (centers: 3 or M×3, radii: scalar or M, in the rays' frame): N, or
    N×M for M balls; 0 for an origin inside, inf for a miss."""
    oc = o[:, None, :] - np.atleast_2d(center)[None]
    b = np.einsum("nmk,nk->nm", oc, d)
    r2 = np.square(radius)
    c = np.einsum("nmk,nmk->nm", oc, oc) - r2
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    hit = (disc >= 0) & (root - b >= 0)
    entry = np.where(c <= 0, 0.0,
                     np.where(hit, np.maximum(-b - root, 0.0), np.inf))
    return entry if np.ndim(center) == 2 else entry[:, 0]


def _interval_entry(enter, leave):
    """The entry distance (>= 0) of rays into a convex set they cross on
    [enter, leave]; inf when they miss it or it lies behind them."""
    hit = (enter <= leave) & (leave >= 0)
    return np.where(hit, np.maximum(enter, 0.0), np.inf)


def _slab(o, d, half):
    """Per ray and slab, the parameter interval [lo, hi] inside |x| <= half
    (o, d: the rays' coordinate along the slab's axis; half broadcast)."""
    inside = np.abs(o) <= half
    parallel = np.abs(d) < 1e-15
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-half - o) / d
        t2 = (half - o) / d
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf),
                  np.minimum(t1, t2))
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf),
                  np.maximum(t1, t2))
    return lo, hi


class _CastTargets:
    """Closed-form ray casting against boxes, spheres, cylinders and capsules
    fixed in one frame F: every ray against every shape in a handful of
    array operations (a capsule is its cylinder and its two end balls)."""

    def __init__(self, shapes):
        """`shapes`: (X_FG, shape) pairs, every shape a Drake Box, Sphere,
        Cylinder or Capsule."""
        spheres, boxes, cylinders = [], [], []
        for X_FG, shape in shapes:
            R_GF = X_FG.rotation().matrix().T
            p_FG = X_FG.translation()
            if isinstance(shape, Sphere):
                spheres.append((p_FG, shape.radius()))
            elif isinstance(shape, Box):
                boxes.append((R_GF, p_FG, shape.size() / 2.0))
            else:
                half = shape.length() / 2.0
                cylinders.append((R_GF, p_FG, shape.radius(), half))
                if isinstance(shape, Capsule):
                    z_F = R_GF[2]
                    spheres += [(p_FG + half * z_F, shape.radius()),
                                (p_FG - half * z_F, shape.radius())]

        def stack(rows, k):
            return np.array([row[k] for row in rows], float)
        self._spheres = spheres and (stack(spheres, 0), stack(spheres, 1))
        self._boxes = boxes and (stack(boxes, 0), stack(boxes, 1),
                                 stack(boxes, 2))
        self._cylinders = cylinders and (
            stack(cylinders, 0), stack(cylinders, 1), stack(cylinders, 2),
            stack(cylinders, 3))

    @staticmethod
    def supports(shape) -> bool:
        return isinstance(shape, (Box, Sphere, Cylinder, Capsule))

    def entry(self, o, d) -> np.ndarray:
        """The distance along each ray (origins o, unit directions d: N×3,
        in F) to where it enters the first shape: 0 for an origin inside
        one, inf for a miss."""
        entries = [np.full(len(o), np.inf)]
        if self._spheres:
            entries.append(_sphere_hits(o, d, *self._spheres).min(axis=1))
        for shapes, interval in ((self._boxes, self._box_interval),
                                 (self._cylinders, self._cylinder_interval)):
            if shapes:
                R_GF, p_FG = shapes[0], shapes[1]
                o_G = np.einsum("mij,mnj->mni", R_GF, o[None] - p_FG[:, None])
                d_G = np.einsum("mij,nj->mni", R_GF, d)
                entries.append(_interval_entry(
                    *interval(o_G, d_G, *shapes[2:])).min(axis=0))
        return np.minimum.reduce(entries)

    @staticmethod
    def _box_interval(o, d, half):
        """[enter, leave] of rays (M×N×3, each box's frame) in the boxes
        (half sizes M×3)."""
        lo, hi = _slab(o, d, half[:, None, :])
        return lo.max(axis=2), hi.min(axis=2)

    @staticmethod
    def _cylinder_interval(o, d, radius, half_length):
        """[enter, leave] of rays (M×N×3, each cylinder's frame, its axis
        z) in the solid cylinders (radii and half lengths: M)."""
        enter, leave = _slab(o[..., 2], d[..., 2], half_length[:, None])
        a = d[..., 0] ** 2 + d[..., 1] ** 2
        b = o[..., 0] * d[..., 0] + o[..., 1] * d[..., 1]
        c = o[..., 0] ** 2 + o[..., 1] ** 2 - (radius * radius)[:, None]
        disc = b * b - a * c
        parallel = a < 1e-30
        with np.errstate(divide="ignore", invalid="ignore"):
            root = np.sqrt(np.maximum(disc, 0.0))
            lo = np.where(parallel, np.where(c <= 0, -np.inf, np.inf),
                          (-b - root) / a)
            hi = np.where(parallel, np.where(c <= 0, np.inf, -np.inf),
                          (-b + root) / a)
        miss = ~parallel & (disc < 0)
        lo = np.where(miss, np.inf, lo)
        hi = np.where(miss, -np.inf, hi)
        return np.maximum(enter, lo), np.minimum(leave, hi)


def ray_entry(shape, o, d) -> np.ndarray:
    """The distance along each ray (origins o, unit directions d: N×3, in the
    shape's frame G) to where it enters a Drake Box, Sphere, Cylinder or
    Capsule: 0 for an origin inside it, inf for a miss. Exact (closed form).
    Returns None for other shapes."""
    if not _CastTargets.supports(shape):
        return None
    return _CastTargets([(RigidTransform(), shape)]).entry(
        np.asarray(o, float), np.asarray(d, float))


class InfraredSensors(LeafSystem):
    """Infrared range sensors, each a ray from its frame's origin along the
    frame's +z axis, reading the distance to the first target geometry as a
    level in [0, levels]; `levels` means nothing within the sensor's range.

    Input port `query_object`: the SceneGraph's query output port.
    Output port `ir_levels`: one level per sensor (a vector of floats holding
    integers), sampled every `period_s` seconds and at initialization.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        sensor_frames: list[Frame],
        target_geometry_ids: list[GeometryId],
        ranges_m: list[float],
        *,
        period_s: float,
        levels: int = 1000,
        target_bound: tuple | None = None,
        inspector: SceneGraphInspector | None = None,
    ):
        """`target_bound`, optional: (body, radius_m), a sphere about the
        body's frame origin that holds every target geometry. Rays that miss
        it read nothing without tracing, and the others start tracing where
        they enter it (the same readings, far fewer distance queries).

        `inspector`, optional: the SceneGraph's model inspector. With it,
        target boxes, spheres, cylinders and capsules are ray-cast in closed
        form (all 13 rays at once) and only other shapes are sphere-traced;
        without it every target is sphere-traced."""
        LeafSystem.__init__(self)
        n = len(sensor_frames)
        if n == 0:
            raise field_error("sensor_frames", sensor_frames, "at least one frame")
        if len(ranges_m) != n:
            raise field_error("ranges_m", ranges_m, f"{n} ranges, one per sensor frame")
        for r in ranges_m:
            if not (r > 0 and math.isfinite(r)):
                raise field_error("ranges_m", ranges_m, "finite ranges > 0 (m)")
        if not target_geometry_ids:
            raise field_error(
                "target_geometry_ids", target_geometry_ids, "at least one id"
            )
        if not (period_s > 0 and math.isfinite(period_s)):
            raise field_error("period_s", period_s, "a finite period > 0 (s)")
        if not (isinstance(levels, int) and levels >= 1):
            raise field_error("levels", levels, "an integer >= 1")
        self._levels = levels
        self._ranges_m = [float(r) for r in ranges_m]
        self._target_ids = frozenset(target_geometry_ids)
        # Closed-form targets, per geometry frame F: (F's id, _CastTargets).
        self._cast = []
        if inspector is not None:
            traced, by_frame = [], {}
            for geometry_id in target_geometry_ids:
                shape = inspector.GetShape(geometry_id)
                if not _CastTargets.supports(shape):
                    traced.append(geometry_id)
                    continue
                by_frame.setdefault(inspector.GetFrameId(geometry_id), []).append(
                    (inspector.GetPoseInFrame(geometry_id), shape))
            self._cast = [(frame_id, _CastTargets(shapes))
                          for frame_id, shapes in by_frame.items()]
            self._target_ids = frozenset(traced)
        self._bound = None
        if target_bound is not None:
            body, radius_m = target_bound
            self._bound = (plant.GetBodyFrameIdOrThrow(body.index()), float(radius_m))
        # Per sensor: the geometry frame of its body and its fixed pose X_BS.
        self._frame_ids = []
        self._X_BS = []
        for frame in sensor_frames:
            body = frame.body()
            self._frame_ids.append(plant.GetBodyFrameIdOrThrow(body.index()))
            self._X_BS.append(frame.GetFixedPoseInBodyFrame())
        # The same rays grouped by body frame (usually all on the palm), as
        # origins p_BS and directions z_BS (k×3), so that one pose query per
        # body places them all.
        self._ray_groups = []
        for frame_id in dict.fromkeys(self._frame_ids):
            index = [i for i, f in enumerate(self._frame_ids) if f == frame_id]
            self._ray_groups.append((
                frame_id, np.array(index),
                np.array([self._X_BS[i].translation() for i in index]),
                np.array([self._X_BS[i].rotation().col(2) for i in index])))
        self._ranges = np.array(self._ranges_m)

        self._query_port = self.DeclareAbstractInputPort(
            "query_object", AbstractValue.Make(QueryObject())
        )
        state = self.DeclareDiscreteState(np.full(n, float(levels)))
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=period_s, offset_sec=0.0, update=self._sample
        )
        self.DeclareInitializationDiscreteUpdateEvent(update=self._sample)
        self.DeclareStateOutputPort("ir_levels", state)

    def num_sensors(self) -> int:
        """Returns the number of sensors (the size of `ir_levels`)."""
        return len(self._ranges_m)

    def ranges_m(self) -> list[float]:
        """Returns each sensor's range (m)."""
        return list(self._ranges_m)

    def levels(self) -> int:
        """Returns the level that means nothing in range."""
        return self._levels

    def read_levels(self, query_object: QueryObject) -> np.ndarray:
        """Returns each sensor's level for the geometry poses in query_object."""
        distances = np.full(len(self._ranges_m), np.inf)
        p_WS, z_W = self._rays(query_object)
        # Rays that cannot reach the target bound read nothing: when no ray
        # can (the object is far from the hand), nothing else is computed.
        live = np.ones(len(p_WS), bool)
        if self._bound is not None:
            p_WC = query_object.GetPoseInWorld(self._bound[0]).translation()
            live = _sphere_hits(p_WS, z_W, p_WC, self._bound[1]) < self._ranges
            if not live.any():
                return np.full(len(p_WS), float(self._levels))
        if self._cast:
            distances[live] = self._cast_distances(
                query_object, p_WS[live], z_W[live])
        if self._target_ids:
            distances = np.minimum(distances, self._trace_distances(query_object))
        return self._quantize(distances)

    def _quantize(self, distances_m: np.ndarray) -> np.ndarray:
        """`quantize` of every sensor's distance (m) at its range."""
        with np.errstate(invalid="ignore"):
            level = np.floor(distances_m / self._ranges * self._levels)
        in_range = distances_m < self._ranges  # False for inf and nan
        return np.where(in_range, np.clip(level, 0, self._levels),
                        float(self._levels))

    def _rays(self, query_object):
        """Every sensor's ray in the world: origins and unit directions (N×3)."""
        p_WS = np.empty((len(self._ranges_m), 3))
        z_W = np.empty_like(p_WS)
        for frame_id, index, p_BS, z_BS in self._ray_groups:
            X_WB = query_object.GetPoseInWorld(frame_id)
            R_WB = X_WB.rotation().matrix()
            p_WS[index] = p_BS @ R_WB.T + X_WB.translation()
            z_W[index] = z_BS @ R_WB.T
        return p_WS, z_W

    def _cast_distances(self, query_object, p_WS, z_W):
        """Closed-form distances along the rays (p_WS, z_W: N×3) to the first
        cast target (inf: none)."""
        distances = np.full(len(p_WS), np.inf)
        for frame_id, targets in self._cast:
            X_WF = query_object.GetPoseInWorld(frame_id)
            R_WF = X_WF.rotation().matrix()
            # Row vectors: p_F = R_FW (p_W - p_WF) is (p_W - p_WF) R_WF.
            distances = np.minimum(distances, targets.entry(
                (p_WS - X_WF.translation()) @ R_WF, z_W @ R_WF))
        return distances

    def _trace_distances(self, query_object):
        """Sphere-traced distances to the first traced target (inf: none)."""
        readings = np.full(len(self._ranges_m), np.inf)
        if self._bound is not None:
            p_WC = query_object.GetPoseInWorld(self._bound[0]).translation()
        for i, (frame_id, X_BS, range_m) in enumerate(
            zip(self._frame_ids, self._X_BS, self._ranges_m)
        ):
            X_WS = query_object.GetPoseInWorld(frame_id) @ X_BS
            p_WS, z_W = X_WS.translation(), X_WS.rotation().col(2)
            s0 = 0.0
            if self._bound is not None:
                s0 = _sphere_entry(p_WS, z_W, p_WC, self._bound[1])
                if s0 >= range_m:
                    continue
            tolerance_m = min(_HIT_TOLERANCE_M, 0.1 * range_m / self._levels)
            distance_m = s0 + trace_ray(
                query_object,
                p_WS + s0 * z_W,
                z_W,
                range_m - s0,
                self._target_ids,
                tolerance_m,
            )
            readings[i] = distance_m
        return readings

    def _sample(self, context, discrete_state):
        query_object = self._query_port.Eval(context)
        discrete_state.set_value(0, self.read_levels(query_object))


class TactileBumper(LeafSystem):
    """A tactile bumper: reads 1.0 while the bumper's geometry (one id, or a
    list: the palm's pads under it) touches any target geometry (a point
    pair or a hydroelastic contact surface), else 0.0.

    Input port `contact_results`: the plant's contact results output port.
    Output port `bumper`: a 1-vector, sampled every `period_s` seconds and at
    initialization.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        bumper_geometry_id: GeometryId | list[GeometryId],
        target_geometry_ids: list[GeometryId],
        period_s: float,
    ):
        LeafSystem.__init__(self)
        if not target_geometry_ids:
            raise field_error(
                "target_geometry_ids", target_geometry_ids, "at least one id"
            )
        if not (period_s > 0 and math.isfinite(period_s)):
            raise field_error("period_s", period_s, "a finite period > 0 (s)")
        self._bumper_ids = frozenset(
            bumper_geometry_id if isinstance(bumper_geometry_id, list)
            else [bumper_geometry_id])
        self._target_ids = frozenset(target_geometry_ids)
        self._contact_port = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults())
        )
        state = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=period_s, offset_sec=0.0, update=self._sample
        )
        self.DeclareInitializationDiscreteUpdateEvent(update=self._sample)
        self.DeclareStateOutputPort("bumper", state)

    def is_touching(self, contact_results: ContactResults) -> bool:
        """Returns True if any contact pairs the bumper with a target."""
        pairs = [
            (info.point_pair().id_A, info.point_pair().id_B)
            for info in map(
                contact_results.point_pair_contact_info,
                range(contact_results.num_point_pair_contacts()),
            )
        ]
        pairs += [
            (info.contact_surface().id_M(), info.contact_surface().id_N())
            for info in map(
                contact_results.hydroelastic_contact_info,
                range(contact_results.num_hydroelastic_contacts()),
            )
        ]
        for id_A, id_B in pairs:
            if (id_A in self._bumper_ids and id_B in self._target_ids) or (
                id_B in self._bumper_ids and id_A in self._target_ids
            ):
                return True
        return False

    def _sample(self, context, discrete_state):
        touching = self.is_touching(self._contact_port.Eval(context))
        discrete_state.set_value(0, [1.0 if touching else 0.0])
