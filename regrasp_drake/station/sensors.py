"""The hand's sensors: infrared range sensors and a tactile bumper (paper §V.B).

Both are sampled systems: each holds its readings as discrete state, refreshed
by a periodic discrete update (and once at initialization), and exposes that
state through a state output port, so that reading an output costs no Python
between samples.
"""

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import GeometryId, QueryObject
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
    ):
        """`target_bound`, optional: (body, radius_m), a sphere about the
        body's frame origin that holds every target geometry. Rays that miss
        it read nothing without tracing, and the others start tracing where
        they enter it (the same readings, far fewer distance queries)."""
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
        readings = np.empty(len(self._ranges_m))
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
                    readings[i] = self._levels
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
            readings[i] = quantize(distance_m, range_m, self._levels)
        return readings

    def _sample(self, context, discrete_state):
        query_object = self._query_port.Eval(context)
        discrete_state.set_value(0, self.read_levels(query_object))


class TactileBumper(LeafSystem):
    """A tactile bumper: reads 1.0 while the bumper geometry touches any target
    geometry (a point pair or a hydroelastic contact surface), else 0.0.

    Input port `contact_results`: the plant's contact results output port.
    Output port `bumper`: a 1-vector, sampled every `period_s` seconds and at
    initialization.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        bumper_geometry_id: GeometryId,
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
        self._bumper_id = bumper_geometry_id
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
            if (id_A == self._bumper_id and id_B in self._target_ids) or (
                id_B == self._bumper_id and id_A in self._target_ids
            ):
                return True
        return False

    def _sample(self, context, discrete_state):
        touching = self.is_touching(self._contact_port.Eval(context))
        discrete_state.set_value(0, [1.0 if touching else 0.0])
