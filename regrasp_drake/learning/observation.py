"""The observation throw and its offline stage (`regrasp-drake throw`): the
watching throw, every catch moment with the sides the arm reaches there,
and the plan; and how episodes and plans are reported in JSON."""

import dataclasses as dc

from regrasp_drake.episode.result import EpisodeResult
from regrasp_drake.errors import InputError
from regrasp_drake.parameter_space import H_DOWN_VALUES
from regrasp_drake.planning.catch_plan import CatchPoint
from regrasp_drake.planning.follow import follows
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.scenario import Scenario
from regrasp_drake.throw_catch import (
    CatchPlan,
    catch_palm_poses,
    plan_catch,
    reachable_h_down,
    watch,
    watched_catch_moments,
)
from regrasp_drake.world.objects import ObjectSpec


@dc.dataclass
class Observation:
    watched: EpisodeResult
    points: list[CatchPoint]  # every catch point, best first
    reach: list[list[dict]]   # per point, per side: reachable, reason
    plan: CatchPlan | None    # None when no point is reachable
    plan_error: str           # why there is no plan ("" when there is one)
    # Per h_down of the grid, whether the arm reaches the lowered pose under
    # the plan (`throw_catch.reachable_h_down`); None without a plan.
    lowering_reach: list[bool] | None = None

    def as_dict(self) -> dict:
        used = self.plan.catch_point.t_s if self.plan else None
        return {
            "object": self.watched.object,
            "watch": episode_dict(self.watched),
            "catch_points": [p.as_dict() | {"used": p.t_s == used, "sides": r}
                             for p, r in zip(self.points, self.reach)],
            "plan": None if self.plan is None else plan_dict(self.plan) | {
                "deepest_reachable_h_down": float(
                    H_DOWN_VALUES[self.lowering_reach.index(True)])},
            "plan_error": self.plan_error,
        }


def observe(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
            meshcat=None, shown: int = 10) -> Observation:
    """The watching throw and the offline stage, with the best catch moments.

    The catch point used by default is the first moment, in the order of
    `catch_plan.catch_moments`, that the arm reaches in time within its
    torque limits (the same choice as `plan_catch`): only moments after the
    hand can be in place; first those where the object's axis is within
    `catch.tilt_tolerance` of horizontal (the paper catches "where the object
    is horizontal, otherwise the probability of catching is reduced"; the
    palm tilts to lie parallel to the axis), then those where it lands flat,
    then those leaving at least 0.40 m of fall after the hand is ready (so
    that every h_catch of the grid can trigger), then the nearest to the
    preferred height `catch.catch_height_m`. The first `shown` moments are
    listed with, per side, whether the arm reaches them and why not."""
    watched = watch(scenario, obj, ik, meshcat=meshcat)
    try:
        plan, error = plan_catch(scenario, obj, ik, watched), ""
    except InputError as e:
        plan, error = None, str(e)
    q_end = throw.grasp_ik_seed(scenario, ik)
    points = watched_catch_moments(scenario, obj, watched)[:shown]
    if plan is not None and all(p.t_s != plan.catch_point.t_s for p in points):
        points.append(plan.catch_point)  # chosen further down the order
    reach = []
    for point in points:
        sides = []
        for side, X_WG in zip(("paper", "mirrored"),
                              catch_palm_poses(scenario, point, obj)):
            result = ik.solve(X_WG, q_end)
            sides.append({"side": side, "reachable": result.success,
                          "reason": result.reason()})
        reach.append(sides)
    return Observation(watched, points, reach, plan, error, None if plan is None
                       else reachable_h_down(
                           ik, plan, H_DOWN_VALUES,
                           along_normal=follows(scenario)[0]))


def episode_dict(result: EpisodeResult) -> dict:
    """An episode as the JSON outputs report it."""
    return {"outcome": result.outcome,
            "sim_time_s": round(result.sim_time_s, 4),
            "wall_s": round(result.wall_s, 3), "message": result.message}


def plan_dict(plan: CatchPlan) -> dict:
    """A catch plan as the JSON outputs report it, the palm's rotation
    included."""
    return plan.as_dict() | {
        "R_WG": plan.X_WG.rotation().matrix().round(6).tolist()}
