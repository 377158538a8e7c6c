"""Watch a throw, plan the catch under it, and catch: the station's main job.

Watching throw: the arm throws and parks out of the way; the object's flight is
logged. The offline stage finds the catch point and the palm's pose there.
Catching throw: the same throw (identical initial conditions), then the catch
state machine with (h_catch, h_down).
"""

import dataclasses as dc
from pathlib import Path

import torch
from pydrake.math import RigidTransform

from regrasp_drake.errors import InputError
from regrasp_drake.planning.catch_plan import (CatchPoint, find_catch_points,
                                               palm_poses_for)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.episode import EpisodeResult, run_episode
from regrasp_drake.station.scenario import Scenario, load_scenario
from regrasp_drake.world.objects import ObjectSpec, resolve_object


@dc.dataclass
class CatchPlan:
    catch_point: CatchPoint
    X_WG: RigidTransform   # the palm's grasp pose
    q_grasp: list          # the arm's joint angles there, [rad]
    side: str              # "paper": the θ construction's side; or "mirrored"

    def as_dict(self) -> dict:
        return {"catch_point": self.catch_point.as_dict(),
                "p_WG": [round(float(c), 5) for c in self.X_WG.translation()],
                "q_grasp": [round(float(c), 5) for c in self.q_grasp],
                "side": self.side}


def watch(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
          meshcat=None) -> EpisodeResult:
    """The watching throw: no catch attempt."""
    return run_episode(scenario, obj, ik=ik, X_WG=None, meshcat=meshcat)


def plan_catch(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
               watched: EpisodeResult) -> CatchPlan:
    """The offline stage: the catch point and the arm's pose under it."""
    logs = watched.logs
    points = find_catch_points(logs.t, logs.object_state,
                               height_m=scenario.catch.catch_height_m,
                               tilt_tolerance=scenario.catch.tilt_tolerance,
                               band_m=scenario.catch.height_band_m,
                               most_horizontal=True)
    if not points:
        raise InputError(
            f"object {obj.name}: no catch point (the watched flight never "
            f"descends within {scenario.catch.height_band_m} m of "
            f"catch.catch_height_m = {scenario.catch.catch_height_m} m)")
    reasons = []
    for point in points:
        for side, X_WG in zip(("paper", "mirrored"),
                              palm_poses_for(point, obj.grasp_radius)):
            result = ik.solve(X_WG, scenario.catch.ik_seed_q_rad)
            if result.success:
                return CatchPlan(catch_point=point, X_WG=X_WG,
                                 q_grasp=list(result.q), side=side)
            reasons.append(f"at {point.p_WO.round(3).tolist()}, {side} side: "
                           f"{result.reason()}")
    raise InputError(f"object {obj.name}: no reachable catch point ("
                     + "; ".join(reasons) + ")")


def catch_once(*, scenario_path=None, object_name=None, object_file=None,
               h_catch: float, h_down: float, html: Path | None = None,
               plot: Path | None = None) -> tuple[EpisodeResult, CatchPlan]:
    """`regrasp-drake catch`: watch, plan, and one catch attempt."""
    torch.set_num_threads(1)
    scenario = load_scenario(scenario_path)
    obj = resolve_object(name=object_name, file=object_file)
    ik = ArmIk()
    meshcat = None
    if html is not None:
        from regrasp_drake.station.replay import make_meshcat
        meshcat = make_meshcat()
    watched = watch(scenario, obj, ik)
    plan = plan_catch(scenario, obj, ik, watched)
    result = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                         catch_parameters=(h_catch, h_down), meshcat=meshcat)
    if html is not None:
        from regrasp_drake.station.replay import save_html
        save_html(meshcat, html)
    if plot is not None:
        from regrasp_drake.plots import plot_episode
        plot_episode(result, plot)
    return result, plan
