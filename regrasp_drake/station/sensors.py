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
# -1 and +1, to compute a quadratic's two roots -b ∓ √disc at once.
_MINUS_PLUS = np.array([-1.0, 1.0])[:, None, None]


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


class _CastTargets:
    """Closed-form ray casting against boxes, spheres, cylinders and capsules
    fixed in one frame F: every ray against every shape in two batches of
    array operations, one for balls (spheres, and a capsule's end balls) and
    one for solids (boxes, cylinders, and a capsule's cylinder).

    A solid is, in its own frame G, the points within three slabs
    |x_k| <= half_k and inside the infinite cylinder x_0² + x_1² <= r² about
    G's z axis: a box has r = inf, a cylinder half_0 = half_1 = inf. A ray is
    within an unbounded slab or cylinder over its whole length, so that bound
    changes no entry distance."""

    def __init__(self, shapes):
        """`shapes`: (X_FG, shape) pairs, every shape a Drake Box, Sphere,
        Cylinder or Capsule."""
        balls, solids = [], []
        for X_FG, shape in shapes:
            R_GF = X_FG.rotation().matrix().T
            p_FG = X_FG.translation()
            if isinstance(shape, Sphere):
                balls.append((p_FG, shape.radius()))
            elif isinstance(shape, Box):
                solids.append((R_GF, p_FG, shape.size() / 2.0, np.inf))
            else:
                half = shape.length() / 2.0
                solids.append((R_GF, p_FG, (np.inf, np.inf, half), shape.radius()))
                if isinstance(shape, Capsule):
                    z_F = R_GF[2]
                    balls += [(p_FG + half * z_F, shape.radius()),
                              (p_FG - half * z_F, shape.radius())]
        self._balls = None
        if balls:
            p_FC, radius = (np.array(column, float) for column in zip(*balls))
            self._balls = (p_FC, np.square(radius))
        self._solids = None
        if solids:
            R_GF, p_FG, half, radius = (np.array(column, float)
                                        for column in zip(*solids))
            half = half[:, None, :]
            self._solids = (
                R_GF,
                # Subtracted from the rays (origins, directions): p_FG, 0.
                np.stack((p_FG, np.zeros_like(p_FG)), axis=1)[:, :, None, :],
                np.stack((-half, half)),  # each slab's two faces
                half,
                np.square(radius)[:, None])

    @staticmethod
    def supports(shape) -> bool:
        return isinstance(shape, (Box, Sphere, Cylinder, Capsule))

    def entry(self, rays) -> np.ndarray:
        """The distance along each ray (`rays`: origins and unit directions,
        2×N×3, in F) to where it enters the first shape: 0 for an origin
        inside one, inf for a miss. Call it under
        np.errstate(divide="ignore", invalid="ignore"): a ray that misses a
        shape's quadric computes nan, a ray parallel to a slab divides by
        zero."""
        entries = [cast(rays, *targets) for cast, targets in (
            (_ball_entry, self._balls), (_solid_entry, self._solids))
            if targets is not None]
        return entries[0] if len(entries) == 1 else np.minimum(*entries)


def _ball_entry(rays, p_FC, r2):
    """Entry distance of N rays (origins and unit directions, 2×N×3) into
    the nearest of M balls (centres p_FC: M×3, squared radii r2: M or one for
    all): N; 0 for an origin inside one, inf for a miss."""
    o, d = rays
    p_CS = o[:, None, :] - p_FC  # N×M×3
    b = np.einsum("nmk,nk->nm", p_CS, d)
    c = np.einsum("nmk,nmk->nm", p_CS, p_CS) - r2
    disc = b * b - c
    root = np.sqrt(disc)  # nan where the line misses the ball
    # Where the ray leaves the ball: behind its origin, or nan, is a miss.
    leave = root - b
    entry = np.where(leave >= 0, np.maximum(-b - root, 0.0), np.inf)
    return np.minimum.reduce(np.where(c <= 0, 0.0, entry), axis=1)


def _solid_entry(rays, R_GF, shift, faces, half, r2):
    """Entry distance of N rays (origins and unit directions, 2×N×3, in F)
    into the nearest of M solids (see _CastTargets: rotations R_GF, shift
    p_FG and 0, slab faces ∓half, half sizes, squared radii), each ray
    clipped to the three slabs and the cylinder: N; 0 for an origin inside
    one, inf for a miss."""
    rays_G = np.einsum("mij,mpnj->pmni", R_GF, rays - shift)  # 2×M×N×3
    o, d = rays_G
    # Slabs: the ray's parameters at each slab's two faces.
    t = (faces - o) / d
    lo, hi = np.minimum(t[0], t[1]), np.maximum(t[0], t[1])
    parallel = np.abs(d) < 1e-15
    if parallel.any():  # in the slab over the whole ray, or nowhere
        inside = np.abs(o) <= half
        lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
        hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
    enter, leave = np.maximum.reduce(lo, axis=2), np.minimum.reduce(hi, axis=2)
    # Cylinder: |x_xy + s·d_xy|² = r², a·s² + 2b·s + c = 0.
    xy = rays_G[..., :2]
    products = xy[:, None] * xy[None]
    (oo, b), (_, a) = products[..., 0] + products[..., 1]
    c = oo - r2
    disc = b * b - a * c
    root = np.sqrt(disc)  # nan where the line misses the cylinder
    lo, hi = (-b + _MINUS_PLUS * root) / a
    along_axis = a < 1e-30
    if along_axis.any():  # in the cylinder over the whole ray, or nowhere
        inside = c <= 0
        lo = np.where(along_axis, np.where(inside, -np.inf, np.inf), lo)
        hi = np.where(along_axis, np.where(inside, np.inf, -np.inf), hi)
    enter, leave = np.maximum(enter, lo), np.minimum(leave, hi)
    # Hit: a non-empty interval not wholly behind the origin (nan: a miss).
    hit = (enter <= leave) & (leave >= 0)
    return np.minimum.reduce(np.where(hit, np.maximum(enter, 0.0), np.inf))


def ray_entry(shape, o, d) -> np.ndarray:
    """The distance along each ray (origins o, unit directions d: N×3, in the
    shape's frame G) to where it enters a Drake Box, Sphere, Cylinder or
    Capsule: 0 for an origin inside it, inf for a miss. Exact (closed form).
    Returns None for other shapes."""
    if not _CastTargets.supports(shape):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        return _CastTargets([(RigidTransform(), shape)]).entry(
            np.array([o, d], float))


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
        it read nothing without casting or tracing, and the others start
        tracing where they enter it (the same readings, far fewer distance
        queries).

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
        # The geometry frames whose poses a sample reads, each once.
        self._target_frames = list(dict.fromkeys(
            [frame_id for frame_id, _ in self._cast]
            + ([self._bound[0]] if self._bound is not None else [])))
        # Per sensor: the geometry frame of its body and its fixed pose X_BS.
        self._frame_ids = []
        self._X_BS = []
        for frame in sensor_frames:
            body = frame.body()
            self._frame_ids.append(plant.GetBodyFrameIdOrThrow(body.index()))
            self._X_BS.append(frame.GetFixedPoseInBodyFrame())
        # The same rays grouped by body frame (usually all on the palm), as
        # origins p_BS and directions z_BS (2×k×3), so that one pose query per
        # body places them all; `_order` puts the groups' rays back in
        # sensor order.
        self._ray_groups = []
        grouped = []
        for frame_id in dict.fromkeys(self._frame_ids):
            index = [i for i, f in enumerate(self._frame_ids) if f == frame_id]
            grouped += index
            self._ray_groups.append((frame_id, np.array([
                [self._X_BS[i].translation() for i in index],
                [self._X_BS[i].rotation().col(2) for i in index]])))
        self._order = np.argsort(grouped)
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
        rays = self._rays(query_object)
        X_WF = {frame_id: query_object.GetPoseInWorld(frame_id)
                for frame_id in self._target_frames}
        distances = np.full(len(self._ranges_m), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            if self._bound is None:
                if self._cast:
                    distances = self._cast_distances(X_WF, rays)
            else:
                # Rays that cannot reach the target bound read nothing: when
                # no ray can (the object is far from the hand), nothing else
                # is computed.
                frame_id, radius_m = self._bound
                live = _ball_entry(rays, X_WF[frame_id].translation()[None],
                                   radius_m * radius_m) < self._ranges
                if not live.any():
                    return np.full(len(self._ranges_m), float(self._levels))
                if self._cast:
                    distances[live] = self._cast_distances(X_WF, rays[:, live])
        if self._target_ids:
            distances = np.minimum(distances, self._trace_distances(query_object))
        return self._quantize(distances)

    def _cast_distances(self, X_WF, rays):
        """Closed-form distances along the rays (origins and directions,
        2×N×3, in the world) to the first cast target (inf: none), for the
        target frames' poses X_WF."""
        distances = []
        for frame_id, targets in self._cast:
            rays_F = rays.copy()
            rays_F[0] -= X_WF[frame_id].translation()
            # Row vectors: p_F = R_FW (p_W - p_WF) is (p_W - p_WF) R_WF.
            distances.append(targets.entry(
                rays_F @ X_WF[frame_id].rotation().matrix()))
        return np.minimum.reduce(distances)

    def _quantize(self, distances_m: np.ndarray) -> np.ndarray:
        """`quantize` of every sensor's distance (m, >= 0) at its range: the
        floor lies in [0, levels], for a distance below the range."""
        return np.where(distances_m < self._ranges,  # False for inf and nan
                        np.floor(distances_m / self._ranges * self._levels),
                        float(self._levels))

    def _rays(self, query_object) -> np.ndarray:
        """Every sensor's ray in the world: origins p_WS and unit directions
        z_W, 2×N×3."""
        rays = []
        for frame_id, rays_B in self._ray_groups:
            X_WB = query_object.GetPoseInWorld(frame_id)
            rays_W = rays_B @ X_WB.rotation().matrix().T
            rays_W[0] += X_WB.translation()
            rays.append(rays_W)
        if len(rays) == 1:
            return rays[0]
        return np.concatenate(rays, axis=1)[:, self._order]

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
        for i in range(contact_results.num_point_pair_contacts()):
            pair = contact_results.point_pair_contact_info(i).point_pair()
            if self._pairs_bumper(pair.id_A, pair.id_B):
                return True
        for i in range(contact_results.num_hydroelastic_contacts()):
            surface = contact_results.hydroelastic_contact_info(i).contact_surface()
            if self._pairs_bumper(surface.id_M(), surface.id_N()):
                return True
        return False

    def _pairs_bumper(self, id_A: GeometryId, id_B: GeometryId) -> bool:
        """Whether one of the two geometries is the bumper's, the other a
        target."""
        return (id_A in self._bumper_ids and id_B in self._target_ids) or (
            id_B in self._bumper_ids and id_A in self._target_ids)

    def _sample(self, context, discrete_state):
        touching = self.is_touching(self._contact_port.Eval(context))
        discrete_state.set_value(0, [1.0 if touching else 0.0])
