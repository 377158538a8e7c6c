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
_MINUS_PLUS = np.array([-1.0, 1.0])[:, None, None, None]


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
    """Closed-form ray casting of a fixed set of rays, fixed in a frame B,
    against boxes, spheres, cylinders and capsules fixed in a frame F: every
    ray against every shape in one batch of array operations, for any pose
    X_FB.

    Each shape is made of parts, each part, in its own frame G, the points
    within four quadrics Σ_k w_k x_k² <= r²: three slabs |x_k| <= half_k
    (w a unit vector) and a ball about G's origin (w = 1, 1, 1) or an
    infinite cylinder about G's z axis (w = 1, 1, 0). A box is its slabs in a
    ball of infinite radius, a sphere its ball between infinite slabs, a
    cylinder its cylinder between z slabs, and a capsule a cylinder and two
    balls at its ends. An unbounded quadric holds a ray over its whole
    length, so it changes no entry distance.

    The rays are cast in every part's frame at once: a ray enters a part
    where it has entered all four quadrics, and hits it if it has not yet
    left any there."""

    def __init__(self, shapes, rays_B):
        """`shapes`: (X_FG, shape) pairs, every shape a Drake Box, Sphere,
        Cylinder or Capsule. `rays_B`: the rays' origins and unit directions
        in B, 2×N×3."""
        ball, cylinder, no_slabs = (1.0, 1.0, 1.0), (1.0, 1.0, 0.0), (np.inf,) * 3
        parts = []  # (X_FG, half sizes, w, r) of each part
        for X_FG, shape in shapes:
            if isinstance(shape, Sphere):
                parts.append((X_FG, no_slabs, ball, shape.radius()))
            elif isinstance(shape, Box):
                parts.append((X_FG, shape.size() / 2.0, ball, np.inf))
            else:
                half = shape.length() / 2.0
                parts.append((X_FG, (np.inf, np.inf, half), cylinder,
                              shape.radius()))
                if isinstance(shape, Capsule):
                    parts += [(X_FG @ RigidTransform([0.0, 0.0, z]), no_slabs,
                               ball, shape.radius()) for z in (-half, half)]
        X_FG, half, w, r = zip(*parts)
        m, n = len(parts), rays_B.shape[1]
        # The rays in each part's frame G are X_GF·X_FB·H_B, H_B the rays in
        # homogeneous coordinates (origins and directions, 2×4×N), linear in
        # the 16 entries of X_FB: the rays are this matrix times them.
        X_GF = np.array([X.inverse().GetAsMatrix34() for X in X_FG])  # M×3×4
        H_B = np.concatenate((rays_B.transpose(0, 2, 1),
                              [[[1.0] * n], [[0.0] * n]]), axis=1)
        self._rays_G = np.einsum("mcj,ikn->imcnkj", X_GF, H_B).reshape(-1, 16)
        self._shape = (2, m, 3, n)
        # Each part's four quadrics: weights M×4×3, squared radii M×4×1.
        self._w = np.concatenate((np.broadcast_to(np.eye(3), (m, 3, 3)),
                                  np.array(w)[:, None]), axis=1)
        self._r2 = np.square(np.concatenate((half, np.array(r)[:, None]),
                                            axis=1))[:, :, None]

    @staticmethod
    def supports(shape) -> bool:
        return isinstance(shape, (Box, Sphere, Cylinder, Capsule))

    def entry(self, X_FB: np.ndarray) -> np.ndarray:
        """The distance along each ray to where it enters the first shape,
        for the pose X_FB (a 4×4 matrix): 0 for an origin inside one, inf for
        a miss, N."""
        rays = (self._rays_G @ X_FB.ravel(order="F")).reshape(self._shape)
        # Σ_k w_k (o_k + s·d_k)² = r² is a·s² + 2b·s + c = 0, for origins o
        # and directions d, for every part's four quadrics (M×4×N each).
        (oo, b), (_, a) = self._w @ (rays[:, None] * rays[None])
        c = oo - self._r2  # -inf for an unbounded quadric
        # A ray parallel to a slab, or along a cylinder's axis, has a = 0:
        # 1e-300 leaves every a above 1e-284 as it is, and puts such a ray
        # in the quadric over its whole length (bounds ∓√-c·1e150 m) where
        # it starts inside (c < 0), nowhere where it starts outside (c > 0),
        # and at its origin only where it runs on the surface (c = 0).
        a = a + 1e-300
        disc = b * b - a * c
        # A negative discriminant, a line that misses the quadric, gives an
        # empty interval (enter > leave).
        root = np.copysign(np.sqrt(np.abs(disc)), disc)
        # Where the ray enters each quadric, and minus where it leaves.
        bounds = (_MINUS_PLUS * b - root) / a
        # Where it has entered all of a part's quadrics (and is not behind
        # its origin), and minus where it first leaves one.
        enter, minus_leave = bounds.max(axis=2)
        enter = np.maximum(enter, 0.0)
        return np.where(enter <= -minus_leave, enter, np.inf).min(axis=0)


def ray_entry(shape, o, d) -> np.ndarray:
    """The distance along each ray (origins o, unit directions d: N×3, in the
    shape's frame G) to where it enters a Drake Box, Sphere, Cylinder or
    Capsule: 0 for an origin inside it, inf for a miss. Exact (closed form).
    Returns None for other shapes."""
    if not _CastTargets.supports(shape):
        return None
    return _CastTargets([(RigidTransform(), shape)],
                        np.array([o, d], float)).entry(np.eye(4))


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
        body's frame origin that holds every target geometry. While it lies
        beyond the reach of all the rays of a body (their ranges from the
        body's origin), they read nothing without casting; traced rays that
        miss it read nothing without tracing, and the others start tracing
        where they enter it (the same readings, far fewer distance
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
        self._ranges = np.array(self._ranges_m)
        self._target_ids = frozenset(target_geometry_ids)
        self._bound = None
        if target_bound is not None:
            body, radius_m = target_bound
            self._bound = (plant.GetBodyFrameIdOrThrow(body.index()), float(radius_m))
        # The rays grouped by the geometry frame B of their body (usually
        # all on the palm), as origins p_BS and directions z_BS (2×k×3), so
        # that one pose places them all; `_order` puts the groups' rays back
        # in sensor order.
        body_frames = [plant.GetBodyFrameIdOrThrow(frame.body().index())
                       for frame in sensor_frames]
        groups, grouped = [], []
        for body_id in dict.fromkeys(body_frames):
            index = [i for i, f in enumerate(body_frames) if f == body_id]
            grouped += index
            X_BS = [sensor_frames[i].GetFixedPoseInBodyFrame() for i in index]
            groups.append((body_id, index, np.array([
                [X.translation() for X in X_BS],
                [X.rotation().col(2) for X in X_BS]])))
        self._ray_groups = [(body_id, rays_B) for body_id, _, rays_B in groups]
        self._order = np.argsort(grouped)
        # Closed-form targets, grouped by their geometry frame F.
        by_frame = {}
        if inspector is not None:
            traced = []
            for geometry_id in target_geometry_ids:
                shape = inspector.GetShape(geometry_id)
                if not _CastTargets.supports(shape):
                    traced.append(geometry_id)
                    continue
                by_frame.setdefault(inspector.GetFrameId(geometry_id), []).append(
                    (inspector.GetPoseInFrame(geometry_id), shape))
            self._target_ids = frozenset(traced)
        # Per ray group: its body frame B, and per frame F of cast targets
        # (F's id, the targets with the group's rays, and the squared
        # distance from B's origin to F's beyond which no ray reaches the
        # target bound, if it is about F; else inf).
        self._casts = []
        for body_id, index, rays_B in groups:
            reach = np.max(np.linalg.norm(rays_B[0], axis=1) + self._ranges[index])
            casts = []
            for frame_id, shapes in by_frame.items():
                beyond2 = math.inf
                if self._bound is not None and self._bound[0] == frame_id:
                    beyond2 = (reach + self._bound[1]) ** 2
                casts.append((frame_id, _CastTargets(shapes, rays_B), beyond2))
            self._casts.append((body_id, casts, np.full(len(index), np.inf)))
        # The geometry frames whose poses a sample reads, each once.
        self._frames = list(dict.fromkeys(
            [body_id for body_id, _ in self._ray_groups] + list(by_frame)))

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
        X_W = {frame_id: query_object.GetPoseInWorld(frame_id)
               for frame_id in self._frames}
        distances = []  # per ray group
        for body_id, casts, nothing in self._casts:
            nearest = nothing
            for frame_id, targets, beyond2 in casts:
                X_FB = X_W[frame_id].InvertAndCompose(X_W[body_id]).GetAsMatrix4()
                x, y, z = X_FB[:3, 3].tolist()  # p_FB
                if x * x + y * y + z * z >= beyond2:
                    continue  # no ray reaches the target bound
                entry = targets.entry(X_FB)
                nearest = entry if nearest is nothing else np.minimum(nearest, entry)
            distances.append(nearest)
        if len(distances) == 1:
            distances = distances[0]
        else:
            distances = np.concatenate(distances)[self._order]
        if self._target_ids:
            distances = np.minimum(distances, self._trace_distances(query_object))
        return self._quantize(distances)

    def _quantize(self, distances_m: np.ndarray) -> np.ndarray:
        """`quantize` of every sensor's distance (m, >= 0; inf or nan for
        nothing) at its range: the floor, capped at `levels`."""
        return np.fmin(np.floor(distances_m / self._ranges * self._levels),
                       self._levels)

    def _rays(self, query_object) -> np.ndarray:
        """Every sensor's ray in the world: origins p_WS and unit directions
        z_W, 2×N×3."""
        rays = []
        for frame_id, rays_B in self._ray_groups:
            X_WB = query_object.GetPoseInWorld(frame_id)
            rays_W = rays_B @ X_WB.rotation().matrix().T
            rays_W[0] += X_WB.translation()
            rays.append(rays_W)
        return np.concatenate(rays, axis=1)[:, self._order]

    def _trace_distances(self, query_object):
        """Sphere-traced distances to the first traced target (inf: none)."""
        readings = np.full(len(self._ranges_m), np.inf)
        if self._bound is not None:
            p_WC = query_object.GetPoseInWorld(self._bound[0]).translation()
        for i, (p_WS, z_W, range_m) in enumerate(
                zip(*self._rays(query_object), self._ranges_m)):
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
