"""Issue 42, lever 4: how long the object needs to settle before the toss.

    .venv/bin/python studies/physics_levers/settle_length.py [OBJECT ...]
        [--settle-s 0.3 0.1 0.05]

Per object (default table1-row2 hammer-d200-2) and settle time
(throw.settle_s; the shipped 0.3 s first): the watching throw at the
shipped steps; over the settle, the object's largest displacement from the
solved rest pose (station.rest_pose, relaxed at 1 ms) and its speed;
against the first settle time, the largest difference of the object's
state at the release time (13 components) and of the planned catch point
and palm pose, the catch moment counted from the settle's end.
"""

import regrasp_drake  # noqa: F401, I001 (first: pins NumPy's kernels)
import argparse

import numpy as np

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.episode.episode import THROWS, release_time
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("objects", nargs="*",
                        default=["table1-row2", "hammer-d200-2"])
    parser.add_argument("--settle-s", type=float, nargs="+",
                        default=[0.3, 0.1, 0.05])
    args = parser.parse_args()
    THROWS.enabled = False
    ik = ArmIk(load_scenario().directives)
    for name in args.objects:
        obj = resolve_object(name=name)
        first = None
        for settle in args.settle_s:
            scenario = load_scenario(text="{throw: {settle_s: %r}}" % settle)
            watched = watch(scenario, obj, ik)
            logs = watched.logs
            during = logs.t <= settle + 1e-9
            p = logs.object_state[4:7, during]
            speed = np.linalg.norm(logs.object_state[10:13, during], axis=0)
            fast = logs.t[during][speed > 1e-3]
            k = int(np.argmin(np.abs(logs.t - release_time(scenario))))
            plan = plan_catch(scenario, obj, ik, watched)
            now = (logs.object_state[:, k], plan, settle)
            first = first or now
            point, point0 = plan.catch_point, first[1].catch_point
            moved = np.linalg.norm(p - p[:, :1], axis=0).max()
            d_point = np.linalg.norm(np.subtract(point.p_WO, point0.p_WO))
            d_palm = np.linalg.norm(plan.X_WG.translation()
                                    - first[1].X_WG.translation())
            d_moment = (point.t_s - settle) - (point0.t_s - first[2])
            print(f"{name}, settle {settle:g} s: largest displacement "
                  f"{1e3 * moved:.3f} mm, speed up to "
                  f"{1e3 * speed.max():.2f} mm/s, {1e3 * speed[-1]:.3f} "
                  "mm/s at its end, above 1 mm/s until "
                  f"{fast[-1] if len(fast) else 0.0:.3f} s; against the "
                  f"{first[2]:g} s settle: release state "
                  f"{np.abs(now[0] - first[0]).max():.2e}, catch point "
                  f"{1e3 * d_point:.2f} mm, palm {1e3 * d_palm:.2f} mm, "
                  f"catch moment {1e3 * d_moment:+.1f} ms")

if __name__ == "__main__":
    main()
