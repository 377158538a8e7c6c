"""Watch a throw, plan the catch under it, and catch: the station's main job.

Watching throw: the arm throws and parks out of the way; the object's flight is
logged. The offline stage finds the catch point and the palm's pose there.
Catching throw: the same throw (identical initial conditions), then the catch
state machine with (h_catch, h_down). At its release it compares the object's
state with the watched one and, when release noise made them differ, moves
the palm by what that difference changes in the plan (`release_correction`).
"""

import dataclasses as dc

import numpy as np
import torch
from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import Cylinder, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix

from regrasp_drake.episode.diagram import build_episode_diagram
from regrasp_drake.episode.episode import release_time, run_episode
from regrasp_drake.episode.replay import draw_path, framing_view, save_html
from regrasp_drake.episode.result import EpisodeResult, start_grasp
from regrasp_drake.errors import InputError
from regrasp_drake.parameter_space import H_CATCH_RANGE
from regrasp_drake.planning import grasp
from regrasp_drake.planning.catch_plan import (
    CatchPoint,
    catch_moments,
    move_torque_ratio,
    palm_poses_for,
)
from regrasp_drake.planning.follow import plan_follow
from regrasp_drake.planning.free_flight import (
    WatchedFlight,
    as_watched,
    flight_from_release,
)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import Phase, lowered_pose
from regrasp_drake.station.scenario import Scenario, target_of
from regrasp_drake.world.objects import ObjectSpec

# A flight's catch moments are at least this far apart in time (s): the
# object falls some 10 cm and turns some 0.2 rad between them, so the hand
# meets it at another speed and attitude.
CATCH_POINT_SEPARATION_S = 0.03


@dc.dataclass
class CatchPlan:
    catch_point: CatchPoint
    X_WG: RigidTransform   # the palm's grasp pose
    q_grasp: list          # the arm's joint angles there, [rad]
    side: str              # "paper": the θ construction's side; or "mirrored"
    # The watched object's state (13, as logged) at the release time, when
    # the plan is from a simulated throw's flight (`with_release`): what a
    # catching throw compares its own release with (`release_correction`).
    release_state: np.ndarray | None = None
    # The plan's rank among its flight's catch moments (`plan_catches`, at
    # least CATCH_POINT_SEPARATION_S apart): 1, the best; a catching throw
    # corrects its palm at its own release at the same moment.
    moment: int = 1

    def as_dict(self) -> dict:
        return {"catch_point": self.catch_point.as_dict(),
                "p_WG": [round(float(c), 5) for c in self.X_WG.translation()],
                "q_grasp": [round(float(c), 5) for c in self.q_grasp],
                "side": self.side}


def watch(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
          meshcat=None) -> EpisodeResult:
    """The watching throw: no catch attempt."""
    return run_episode(scenario, obj, ik=ik, X_WG=None, meshcat=meshcat)


# How far a logged sample's centre-of-mass velocity may stray from free
# fall's (v + g·Δt over the sample) before the flight counts as disturbed,
# [m/s]. In free flight Drake's step keeps it within 2e-7 (measured on
# table1-row1's watched flight); a touch of the hand changes it by far more.
FLIGHT_DISTURBANCE_M_PER_S = 0.01


def seen_flight(scenario: Scenario, obj: ObjectSpec,
                result: EpisodeResult) -> WatchedFlight:
    """What watching a catch throw shows of the flight: the object's logged
    states up to the last sample of undisturbed free flight after the throw
    ends, i.e. before the hand (or anything) first touches the object again.

    Throws repeat exactly, and until that touch the object flies as in the
    watching throw, so `plan_catch` reads the result as a watched flight that
    ends early (first-throw mode replans from it when its catch fails)."""
    logs = result.logs
    t, states = logs.t, logs.object_state
    t_free = throw.free_time_s(scenario)
    g = np.array([0.0, 0.0, -scenario.gravity_m_per_s2])
    v_cm = []
    for k in range(states.shape[1]):
        q = states[:4, k] / np.linalg.norm(states[:4, k])
        R = RotationMatrix(Quaternion(q)).matrix()
        v_cm.append(states[10:13, k] + np.cross(states[7:10, k],
                                                R @ obj.p_OCm))
    v_cm = np.array(v_cm)
    end = len(t)
    for k in range(int(np.searchsorted(t, t_free)), len(t) - 1):
        expected = v_cm[k] + g * (t[k + 1] - t[k])
        if np.linalg.norm(v_cm[k + 1] - expected) > FLIGHT_DISTURBANCE_M_PER_S:
            end = k + 1
            break
    return as_watched(t[:end].copy(), states[:, :end].copy())


def plan_catch(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
               watched: EpisodeResult) -> CatchPlan:
    """The offline stage: the catch point and the arm's pose under it.

    The hand can catch only where it can be in time: the arm leaves the
    throw's last knot when the throw ends and reaches the grasp pose
    `catch.move_to_grasp_s` later, if the move stays within the servos'
    torque limits. Among the moments after that, `catch_moments` ranks where
    to catch (axis near horizontal, the object landing flat, every h_catch of
    the parameter space able to trigger after the hand is in place, near the
    preferred height); the first the arm reaches in time is the plan."""
    return plan_catches(scenario, obj, ik, watched, count=1)[0]


def catch_palm_poses(scenario: Scenario, point, obj: ObjectSpec):
    """The palm's poses under a catch point (`palm_poses_for`, preferred
    side first) with the scenario's catch settings, the palm slid along the
    object's axis by the target's offset. Under a grasp target the palm
    waits for the grasp the object is to rest in: no shift toward the
    landing end (catch.target_palm_toward_landing_end_m), the offsets kept
    along the tilted palm (catch.target_palm_com_along_normal)."""
    c = scenario.catch
    held_at_all = target_of(scenario).kind == "any"
    return palm_poses_for(
        point, obj.grasp_radius, obj=obj, com_margin_m=c.palm_com_margin_m,
        max_palm_tilt_rad=palm_max_tilt_rad(c),
        across_com_fraction=c.palm_across_com_fraction,
        toward_landing_end_m=(c.palm_toward_landing_end_m if held_at_all
                              else c.target_palm_toward_landing_end_m),
        toward_fingers_m=c.palm_toward_fingers_m,
        along_axis_m=1e-3 * scenario.regrasp.offset_mm,
        com_along_normal=(not held_at_all
                          and c.target_palm_com_along_normal))


def palm_max_tilt_rad(catch) -> float:
    """How far the palm turns toward the object's axis at most, [rad]: the
    scenario's catch.palm_max_tilt_rad, or arcsin(catch.tilt_tolerance)."""
    if catch.palm_max_tilt_rad is not None:
        return float(catch.palm_max_tilt_rad)
    return float(np.arcsin(catch.tilt_tolerance))


def planned_grasp(scenario: Scenario, obj: ObjectSpec, point: CatchPoint,
                  X_WG: RigidTransform) -> grasp.Grasp:
    """The grasp a palm at X_WG would hold the object in as it is at the
    catch point, were it to land without turning further."""
    X_WO = RigidTransform(RotationMatrix(point.R_WO), point.p_WO)
    X_PO = X_WG.inverse() @ X_WO
    return grasp.measure(obj, X_PO.rotation().matrix(), X_PO.translation(),
                         np.asarray(start_grasp(scenario, obj).R_PO))


def gives_target(scenario: Scenario, obj: ObjectSpec, point: CatchPoint,
                 X_WG: RigidTransform) -> bool:
    """Whether a palm at X_WG under `point` catches the object in the
    orientation the scenario's target asks for (the axis the right way
    round, the side where the object has one); `any`: always."""
    target = target_of(scenario)
    if target.kind == "any" or point.R_WO is None:
        return True
    verdict = grasp.judge(target, obj, start_grasp(scenario, obj),
                          planned_grasp(scenario, obj, point, X_WG), True)
    return verdict.axis_error_deg < 90.0 and verdict.side_ok is not False


def hand_ready_s(scenario: Scenario) -> float:
    """When the hand can be at a catch point: the throw's end and the move
    there (catch.move_to_grasp_s), [s]."""
    return throw.free_time_s(scenario) + scenario.catch.move_to_grasp_s


def watched_catch_moments(scenario: Scenario, obj: ObjectSpec,
                          watched: EpisodeResult) -> list[CatchPoint]:
    """The watched flight's catch moments, best first, under the scenario's
    catch fields (`catch_plan.catch_moments`): after `hand_ready_s`, with
    room below for every h_catch of the grid."""
    c = scenario.catch
    return catch_moments(watched.logs.t, watched.logs.object_state, obj,
                         height_m=c.catch_height_m, band_m=c.height_band_m,
                         ready_s=hand_ready_s(scenario),
                         fall_m=H_CATCH_RANGE[1],
                         tilt_tolerance=c.tilt_tolerance,
                         gravity_m_per_s2=scenario.gravity_m_per_s2,
                         exact_crossings=throw.is_toss(scenario.throw))


def plan_catches(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                 watched: EpisodeResult, *, count: int,
                 min_separation_s: float = 0.0) -> list[CatchPlan]:
    """Up to `count` plans, best first (see `plan_catch`), at moments at
    least `min_separation_s` apart. Raises InputError when none is
    reachable."""
    c = scenario.catch
    target = target_of(scenario)
    grasp.check_reachable(target, obj)
    toss = throw.is_toss(scenario.throw)
    q_start, v_start, a_start = throw.end_state(scenario.throw, ik)
    q_seed = throw.grasp_ik_seed(scenario, ik)
    # A flight that ends before the release (a watching throw stopped with
    # the object near the ground) says why there is no catch point.
    t_release = throw.let_go_time_s(scenario)
    if (getattr(watched, "outcome", None) == "landed"
            and watched.logs.t[-1] < t_release):
        raise InputError(
            f"object {obj.name}: no catch point: the watching throw ended at "
            f"t = {watched.logs.t[-1]:.3f} s, before the release at "
            f"{t_release:.3f} s, with the object near the ground (within "
            "monitor.ground_clearance_m of it, counting the object's size), "
            "expected an object the hand holds up until it lets it go")
    points = watched_catch_moments(scenario, obj, watched)
    if not points:
        raise InputError(
            f"object {obj.name}: no catch point (the watched flight never "
            f"descends within {c.height_band_m} m of catch.catch_height_m = "
            f"{c.catch_height_m} m after the hand can be there, "
            f"{hand_ready_s(scenario):.3f} s)")
    reasons, plans = [], []
    for point in points:
        if any(abs(point.t_s - p.catch_point.t_s) < max(min_separation_s, 1e-9)
               for p in plans):
            continue
        for side, X_WG in zip(("paper", "mirrored"),
                              catch_palm_poses(scenario, point, obj)):
            where = f"at t = {point.t_s:.3f} s, {side} side"
            if not gives_target(scenario, obj, point, X_WG):
                reasons.append(f"{where}: not the target grasp "
                               f"({target.label()})")
                continue
            result = ik.solve(X_WG, q_seed)
            if not result.success:
                reasons.append(f"{where}: {result.reason()}")
                continue
            ratio = move_torque_ratio(ik, q_start, result.q, c.move_to_grasp_s,
                                      v_start=v_start, a_start=a_start,
                                      gravity=toss)
            if ratio > c.max_move_torque_fraction:
                reasons.append(
                    f"{where}: the move there needs {ratio:.2f} of a servo's "
                    f"torque limit (> catch.max_move_torque_fraction = "
                    f"{c.max_move_torque_fraction})")
                continue
            plans.append(CatchPlan(catch_point=point, X_WG=X_WG,
                                   q_grasp=list(result.q), side=side,
                                   moment=len(plans) + 1))
            break
        if len(plans) == count:
            break
    if plans:
        return plans
    shown = "; ".join(reasons[:4]) + (
        f"; and {len(reasons) - 4} more" if len(reasons) > 4 else "")
    raise InputError(f"object {obj.name}: no reachable catch point among "
                     f"{len(points)} moments ({shown})")


def plan_at_moment(scenario: Scenario, obj: ObjectSpec, ik: ArmIk, flight,
                   moment: int, *, field: str = "catch point") -> CatchPlan:
    """The plan at the flight's `moment`-th catch moment (plan_catches'
    ranking, moments at least CATCH_POINT_SEPARATION_S apart; 1: the
    `plan_catch` plan). Raises InputError when the flight has fewer (naming
    `field` as the one asking for the moment)."""
    plans = plan_catches(scenario, obj, ik, flight, count=moment,
                         min_separation_s=CATCH_POINT_SEPARATION_S)
    if len(plans) < moment:
        raise InputError(
            f"{field}: got {moment}, expected at most {len(plans)}: "
            f"object {obj.name} has {len(plans)} reachable catch point(s) "
            f"at least {CATCH_POINT_SEPARATION_S} s apart")
    return plans[moment - 1]


def shifted_along_axis(plan: CatchPlan, shift_m: float,
                       ik: ArmIk) -> CatchPlan | None:
    """`plan` with the palm moved `shift_m` [m] toward the object's +y end
    (its axis at the catch point, horizontal), the arm's joint angles
    solved again; None when the moved pose is out of reach."""
    y = np.array(plan.catch_point.y_W, float)
    y[2] = 0.0
    y /= np.linalg.norm(y)
    X_WG = RigidTransform(plan.X_WG.rotation(),
                          plan.X_WG.translation() + shift_m * y)
    result = ik.solve(X_WG, plan.q_grasp)
    if not result.success:
        return None
    return dc.replace(plan, X_WG=X_WG, q_grasp=list(result.q))


def reachable_h_down(ik: ArmIk, plan: CatchPlan, h_downs, *,
                     along_normal: bool = False) -> list[bool]:
    """For each h_down (m), whether the arm reaches the lowered pose the
    catch state machine commands under this plan (the same inverse
    kinematics, from the grasp pose's joint angles): where it does not, the
    episode fails with "lowered pose unreachable" whatever the object
    does. `along_normal`: the lowering along the palm's normal (a catch
    that follows the object along the palm, `follow.follows`)."""
    return [ik.solve(lowered_pose(plan.X_WG, h, along_normal),
                     plan.q_grasp).success
            for h in h_downs]


def with_release(plan: CatchPlan, scenario: Scenario, watched) -> CatchPlan:
    """`plan` (from `watched`, a simulated throw's flight: a watching throw
    or `seen_flight`) with the object's state at the release time as that
    throw logged it; `plan` unchanged when the log has no sample then."""
    t = watched.logs.t
    k = np.flatnonzero(np.abs(np.asarray(t) - release_time(scenario)) < 1e-9)
    if not len(k):
        return plan
    return dc.replace(plan, release_state=np.array(
        watched.logs.object_state[:, k[0]], float))


def plan_watched(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                 watched) -> CatchPlan:
    """`plan_catch` from a simulated throw's flight (a watching throw or
    `seen_flight`), with that throw's release kept for the catching
    throw's correction (`with_release`)."""
    return with_release(plan_catch(scenario, obj, ik, watched), scenario,
                        watched)


@dc.dataclass
class ReleaseCorrection:
    """What `release_correction` did in a catching throw: `shift_m`, the
    palm's move [m] (0 when the release repeated the watched one bit for
    bit), `turn_rad`, its turn, and `how`: "same release", "no watched
    release" (the plan has no release state to compare with: unchanged),
    "shifted" (the plan's pose moved by the difference of the two
    releases' plans), "replanned" (the plans' palms on different sides or
    the shifted pose out of reach: the plan from this release), or "kept"
    (no reachable catch point from this release: the plan's pose)."""
    how: str = "none"
    shift_m: float = 0.0
    turn_rad: float = 0.0

    def as_dict(self) -> dict:
        return {"how": self.how, "shift_mm": round(1e3 * self.shift_m, 2),
                "turn_deg": round(float(np.degrees(self.turn_rad)), 3)}


def release_correction(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                       plan: CatchPlan, parameters, record=None):
    """The catching throw's correction of a watched or predicted plan at its
    own release (run_episode's `at_release`): with release noise a catching
    throw does not repeat the watched flight, a predicted flight is not the
    actual one, and the hand, already under way, can still move. At the
    release time the object's state seen then and the one the plan was made
    from (`plan.release_state`: the watching throw's, or the flight
    predictor's) are each propagated in free flight
    (`free_flight.flight_from_release`, no simulation) and planned at the
    plan's catch moment (`plan_at_moment`); the watched palm moves by the
    difference of the two plans' palms (position and turn), so the
    closed-form flight's own error cancels, and follows the object as this
    release's plan has it (`follow.plan_follow`). A release equal to the
    watched one bit for bit (every throw without noise) leaves the plan
    untouched. `parameters` (h_catch, h_down) stay (None: the MLP system's,
    which stay too); `record`, a ReleaseCorrection, is filled in."""
    record = ReleaseCorrection() if record is None else record
    nominal = []  # computed once, on the first release that differs

    def at_release(state, t):
        if plan.release_state is None:  # nothing to compare with
            record.how = "no watched release"
            return None
        if np.array_equal(state, plan.release_state):
            record.how = "same release"
            return None
        try:
            seen = plan_at_moment(scenario, obj, ik,
                                  flight_from_release(state, t, obj, scenario),
                                  plan.moment)
        except InputError:
            record.how = "kept"
            return None
        if not nominal:
            nominal.append(plan_at_moment(
                scenario, obj, ik,
                flight_from_release(plan.release_state, t, obj, scenario),
                plan.moment))
        X_WG = seen.X_WG
        record.how = "replanned"
        if seen.side == nominal[0].side:
            R = (seen.X_WG.rotation() @ nominal[0].X_WG.rotation().inverse()
                 @ plan.X_WG.rotation())
            p = (plan.X_WG.translation() + seen.X_WG.translation()
                 - nominal[0].X_WG.translation())
            shifted = RigidTransform(R, p)
            if ik.solve(shifted, plan.q_grasp).success:
                X_WG, record.how = shifted, "shifted"
        record.shift_m = float(np.linalg.norm(
            X_WG.translation() - plan.X_WG.translation()))
        record.turn_rad = float(abs(
            (X_WG.rotation() @ plan.X_WG.rotation().inverse())
            .ToAngleAxis().angle()))
        return X_WG, parameters, plan_follow(scenario, obj,
                                             seen.catch_point, X_WG)

    return at_release


def catch_planned(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                  plan: CatchPlan, parameters, *, network=None,
                  features=None, meshcat=None, throw_number: int = 1,
                  record=None) -> EpisodeResult:
    """A catching throw under a watched or predicted plan with `parameters`
    (h_catch, h_down), [m] (None: the grid cell the MLP system in the
    episode's diagram predicts from the network `network` and its
    `features`), corrected at its own release (`release_correction`, which
    fills in `record`, a ReleaseCorrection); `meshcat`: where it is drawn;
    throw_number seeds the release noise."""
    return run_episode(
        scenario, obj, ik=ik, X_WG=plan.X_WG, catch_parameters=parameters,
        mlp_features=features, model=network,
        meshcat=meshcat, throw_number=throw_number,
        follow=plan_follow(scenario, obj, plan.catch_point, plan.X_WG),
        at_release=release_correction(scenario, obj, ik, plan, parameters,
                                      record))


def catch_once(scenario: Scenario, obj: ObjectSpec, *, h_catch: float,
               h_down: float, meshcat=None) -> tuple[EpisodeResult, CatchPlan]:
    """`regrasp-drake catch`: watch, plan, and one catch attempt with
    (h_catch, h_down), [m]; `meshcat`: where the catching throw is drawn."""
    torch.set_num_threads(1)
    ik = ArmIk(scenario.directives)
    plan = plan_watched(scenario, obj, ik, watch(scenario, obj, ik))
    return catch_planned(scenario, obj, ik, plan, (h_catch, h_down),
                         meshcat=meshcat), plan


def episode_graphviz(scenario: Scenario, obj: ObjectSpec, *,
                     max_depth: int = 2) -> str:
    """The catching episode's Diagram as a learning phase's first
    catching throw builds it for `obj`, in Graphviz's language (Drake's
    Diagram.GetGraphvizString, `max_depth` levels of subsystems: the
    episode's, then the station's): the throw watched and the catch planned
    first, so that the grasp pose is the planned one and the MLP system
    (the scenario's catch.weights) is fed the planned features (v_catch
    and the object's)."""
    ik = ArmIk(scenario.directives)
    watched = watch(scenario, obj, ik)
    plan = plan_watched(scenario, obj, ik, watched)
    features = [plan.catch_point.v_catch, *obj.features().values()]
    episode = build_episode_diagram(scenario, obj, ik=ik, X_WG=plan.X_WG,
                                    mlp_features=features)
    return episode.diagram.GetGraphvizString(max_depth=max_depth)


# The replay's camera looks at the throw from this direction (from the target
# toward the camera): near the palm toss's spin axis (+Wx: the object turns
# about it at 5.5 rad/s in table1-row2's flight), so that the flip is seen
# face on, turned 30 deg toward +Wy so that the arm, which reaches from the
# origin toward +Wx -Wy, is seen from its side, and 15 deg above.
REPLAY_DIRECTION_W = (0.84, 0.48, 0.26)
# The catch view frames a cube of this half side around the catch, [m].
CATCH_VIEW_HALF_SIDE_M = 0.15
# The slow-motion button plays from this long before the planned catch, [s].
SLOW_MOTION_LEAD_S = 0.3
# The palm's centre in the palm frame, [m] (both hands' palm boxes span
# 0-0.09 m along its x, sdf/hand*.sdf), where the wait pose's marker, a disc
# in the palm's mid-plane of this radius and thickness, [m], is drawn: wider
# than the palm, so that its rim shows around the palm waiting there.
PALM_CENTRE_P_PC = (0.045, 0.0, 0.0)
WAIT_MARKER_SIZE_M = (0.075, 0.002)


def episode_caption(result: EpisodeResult) -> str:
    """What a catching throw's replay says of itself: the object, the
    outcome and, if caught, when the grasp was recognized; then the regrasp
    (the target and the grasp achieved, `EpisodeResult.regrasp_line`)."""
    caption = f"{result.object}: {result.outcome}"
    if result.catch_time_s is not None:
        caption += f" at {result.catch_time_s:.2f} s"
    if result.target is not None:
        caption += f"; {result.regrasp_line()}"
    return caption


def save_replay(meshcat, path, result: EpisodeResult, plan: CatchPlan,
                ik: ArmIk, caption: str | None = None) -> str:
    """Writes the replay of a catching throw recorded on `meshcat`
    (`run_episode`) to path (replay.save_html): the object's logged path,
    the planned catch point (a magenta sphere) and the palm's pose while it
    waited (a translucent green disc around the palm, from the logged arm state
    at the end of WAIT), opening on the whole throw ("flight" view) with a
    second view on the hand at the catch ("catch"), a slow-motion button
    from SLOW_MOTION_LEAD_S before the planned catch, and `caption` shown
    over the scene. Returns path."""
    p_WO = result.logs.object_state[4:7]
    draw_path(meshcat, "/replay/object_path", p_WO)
    p_WO_catch = plan.catch_point.p_WO
    meshcat.SetObject("/replay/catch_point", Sphere(0.015),
                      Rgba(0.9, 0.0, 0.6, 1.0))
    meshcat.SetTransform("/replay/catch_point", RigidTransform(p_WO_catch))
    waited = np.flatnonzero(result.logs.phase == int(Phase.WAIT))
    framed = [p_WO]
    if waited.size:
        X_WP = ik.palm_pose(result.logs.arm_state[:6, waited[-1]])
        meshcat.SetObject("/replay/wait_pose", Cylinder(*WAIT_MARKER_SIZE_M),
                          Rgba(0.1, 0.8, 0.3, 0.5))
        meshcat.SetTransform("/replay/wait_pose",
                             X_WP @ RigidTransform(PALM_CENTRE_P_PC))
        framed.append(X_WP.translation()[:, None])
    corners = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1)
    views = [
        framing_view("flight", np.hstack(framed), REPLAY_DIRECTION_W),
        framing_view("catch", p_WO_catch[:, None]
                     + CATCH_VIEW_HALF_SIDE_M * corners, REPLAY_DIRECTION_W)]
    return save_html(meshcat, path, views=views, caption=caption,
                     slow_motion_from_s=plan.catch_point.t_s
                     - SLOW_MOTION_LEAD_S)
