"""Issue 42, lever 3: what a coarser step from the release does to the flight.

    .venv/bin/python studies/physics_levers/coarse_flight.py [OBJECT]

One catch of OBJECT (default table1-row2; h_catch 0.3, h_down -0.07) with
the plant stepping at 1, 2 and 4 ms from the release time on
(catch_time_step_s); the throw at the shipped 0.25 ms. Printed: each run's
outcome; against the 1 ms run, up to several moments of the flight, the
largest difference of the object's position and of the palm's (palm_surface
frame, from the logged arm angles); and, along the 1 ms flight, the
distance from the palm to the object's bounding sphere and the approach
sensors' nearest reading (1000: nothing in range).
"""

import regrasp_drake  # noqa: F401, I001 (first: pins NumPy's kernels)
import sys

import numpy as np
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.episode.episode import run_episode
from regrasp_drake.episode.episode import THROWS, release_time
from regrasp_drake.station.scenario import load_scenario, with_catch_time_step
from regrasp_drake.station.plant import add_world
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world import robot
from regrasp_drake.world.objects import resolve_object


def main() -> None:
    scenario = load_scenario()
    ik = ArmIk(scenario.directives)
    obj = resolve_object(name=sys.argv[1] if len(sys.argv) > 1
                         else "table1-row2")
    THROWS.enabled = False
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    plant, _, instances, _, _ = add_world(DiagramBuilder(), scenario, obj)
    context = plant.CreateDefaultContext()

    def palm(q):
        plant.SetPositions(context, instances.arm, q)
        plant.SetPositions(context, instances.hand, robot.HAND_OPEN)
        return plant.GetFrameByName("palm_surface", instances.hand
                                    ).CalcPoseInWorld(context).translation()

    logs = {}
    for step in (0.001, 0.002, 0.004):
        result = run_episode(with_catch_time_step(scenario, step), obj, ik=ik,
                             X_WG=plan.X_WG, catch_parameters=(0.3, -0.07))
        logs[step] = result.logs
        print(f"{1e3 * step:g} ms from the release: {result.outcome}, "
              f"grasp recognized at {result.catch_time_s}")
    fine, t_release = logs[0.001], release_time(scenario)
    for step in (0.002, 0.004):
        coarse = logs[step]
        for t_end in (1.0, 1.1, 1.2, 1.27):
            ts = fine.t[(fine.t > t_release + 1e-9) & (fine.t <= t_end + 1e-9)]
            i = [int(np.argmin(np.abs(fine.t - t))) for t in ts]
            j = [int(np.argmin(np.abs(coarse.t - t))) for t in ts]
            d_object = max(np.linalg.norm(fine.object_state[4:7, a]
                                          - coarse.object_state[4:7, b])
                           for a, b in zip(i, j))
            d_palm = max(np.linalg.norm(palm(fine.arm_state[:6, a])
                                        - palm(coarse.arm_state[:6, b]))
                         for a, b in zip(i, j))
            print(f"{1e3 * step:g} ms, to t = {t_end} s: object "
                  f"{1e3 * d_object:.2f} mm, palm {1e3 * d_palm:.2f} mm "
                  "from the 1 ms run's")
    for k in range(0, len(fine.t), 10):
        if t_release < fine.t[k] < 1.3:
            gap = (np.linalg.norm(fine.object_state[4:7, k]
                                  - palm(fine.arm_state[:6, k]))
                   - obj.bounding_radius)
            print(f"t {fine.t[k]:.3f} s: palm to the object's bounding "
                  f"sphere {gap:.3f} m, nearest approach reading "
                  f"{fine.ir[3:, k].min():.0f}")


if __name__ == "__main__":
    main()
