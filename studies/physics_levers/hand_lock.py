"""Issue 42, lever 2: the hand's joints locked through the palm toss, or not.

    .venv/bin/python studies/physics_levers/hand_lock.py [OBJECT ...] [--pairs 5]

Per object (default table1-row2 hammer-d200-2 can-d300-3), with and without
the lock (diagram.hand_idle_until_handover turned off for "free"): the
watching throw's object state at the release time, the planned catch point,
and one catch (h_catch 0.3, h_down -0.07): outcome, final position, grasp.
Then the wall time of the episode from the start (no throw cache), locked
and free in turn, `--pairs` times, in this one process: the ratio pair by
pair and its median.
"""

import regrasp_drake  # noqa: F401, I001 (first: pins NumPy's kernels)
import argparse
import json
import statistics

import numpy as np

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.episode import diagram
from regrasp_drake.episode.episode import run_episode
from regrasp_drake.episode.episode import THROWS, release_time
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

LOCKING = diagram.hand_idle_until_handover
PARAMETERS = (0.3, -0.07)


def set_lock(on: bool) -> None:
    diagram.hand_idle_until_handover = LOCKING if on else (lambda s: False)


def episode(scenario, obj, ik, on: bool) -> dict:
    set_lock(on)
    THROWS.clear()
    watched = watch(scenario, obj, ik)
    k = int(np.argmin(np.abs(watched.logs.t - release_time(scenario))))
    plan = plan_catch(scenario, obj, ik, watched)
    caught = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                         catch_parameters=PARAMETERS)
    return {"release": watched.logs.object_state[:, k],
            "p_WG": np.array(plan.as_dict()["p_WG"]),
            "catch_point": plan.catch_point.as_dict(),
            "outcome": caught.outcome, "p_WO_final": np.array(caught.p_WO_final),
            "grasp": caught.achieved_grasp}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("objects", nargs="*",
                        default=["table1-row2", "hammer-d200-2", "can-d300-3"])
    parser.add_argument("--pairs", type=int, default=5)
    args = parser.parse_args()
    scenario = load_scenario()
    ik = ArmIk(scenario.directives)
    for name in args.objects:
        obj = resolve_object(name=name)
        a, b = (episode(scenario, obj, ik, on) for on in (True, False))
        print(name, json.dumps({
            "release_state_max_diff": float(np.abs(a["release"]
                                                   - b["release"]).max()),
            "p_WG_diff_mm": 1e3 * float(np.abs(a["p_WG"] - b["p_WG"]).max()),
            "catch_points_equal": a["catch_point"] == b["catch_point"],
            "outcomes": [a["outcome"], b["outcome"]],
            "p_WO_final_diff_mm": 1e3 * float(np.abs(
                a["p_WO_final"] - b["p_WO_final"]).max()),
            "grasps": [a["grasp"], b["grasp"]]}))
    THROWS.enabled = False
    obj = resolve_object(name=args.objects[0])
    set_lock(False)
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    ratios = []
    for _ in range(args.pairs):
        wall = {}
        for on in (True, False):
            set_lock(on)
            wall[on] = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                                   catch_parameters=PARAMETERS).wall_s
        ratios.append(wall[True] / wall[False])
    print(f"{obj.name}, the episode from the start: wall time locked / free, "
          f"median of {args.pairs} pairs {statistics.median(ratios):.3f} "
          f"({', '.join(f'{r:.3f}' for r in ratios)})")


if __name__ == "__main__":
    main()
