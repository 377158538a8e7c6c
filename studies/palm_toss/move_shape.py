"""Can a better-shaped move bring the hand under the object sooner?

    .venv/bin/python studies/palm_toss/move_shape.py [--object table1-row2]
        [--durations 0.45 0.40 0.36 0.33]

After the palm toss the catch's move (`planning/time_law.quintic_from`)
takes the arm from the toss's moving state to the grasp pose; it needs 0.45
s within 0.9 of the servos' limits, so the hand is in place only ~50 ms
before the catch (FINDINGS.md). This asks how much of that is the quintic's
shape: it adds to the quintic, per joint, the two degree-6 and degree-7
terms τ³(1-τ)³ and τ⁴(1-τ)³ (which keep the start state and the rest at the
end) and minimizes the largest |torque| / limit over the move (inverse
dynamics with gravity, 61 samples) by Nelder-Mead, for each duration. It
prints the quintic's ratio and the best shaped one's.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse

import numpy as np
from pydrake.multibody.tree import MultibodyForces

from regrasp_drake.planning.catch_plan import ARM_EFFORT_LIMITS
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.planning.time_law import quintic_from
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

# The palm toss at 1 ms (this study's palm_toss.yaml, now a named scenario).
_SCENARIO_NAME = "Fast"


def _bump(tau, n):
    """τⁿ(1-τ)³ and its first two derivatives in τ."""
    b = tau**n * (1 - tau) ** 3
    db = n * tau**(n - 1) * (1 - tau) ** 3 - 3 * tau**n * (1 - tau) ** 2
    ddb = (n * (n - 1) * tau**(n - 2) * (1 - tau) ** 3
           - 6 * n * tau**(n - 1) * (1 - tau) ** 2 + 6 * tau**n * (1 - tau))
    return b, db, ddb


def torque_ratio(ik, start, q1, T, c, samples=61) -> float:
    plant = ik.plant
    context = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    c = np.reshape(c, (2, 6))
    worst = 0.0
    for tau in np.linspace(0.0, 1.0, samples):
        q, v, a = quintic_from(min(tau, 1 - 1e-12), T, *start, q1)
        for j, n in enumerate((3, 4)):
            b, db, ddb = _bump(tau, n)
            q, v, a = q + 64 * c[j] * b, v + 64 * c[j] * db / T, \
                a + 64 * c[j] * ddb / T**2
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        forces.SetZero()
        plant.CalcForceElementsContribution(context, forces)
        torque = plant.CalcInverseDynamics(context, a, forces)
        worst = max(worst, float(np.max(np.abs(torque) / ARM_EFFORT_LIMITS)))
    return worst


def nelder_mead(fun, x0, step=0.3, iterations=800):
    n = len(x0)
    points = [x0] + [x0 + step * np.eye(n)[i] for i in range(n)]
    values = [fun(p) for p in points]
    for _ in range(iterations):
        order = np.argsort(values)
        points = [points[i] for i in order]
        values = [values[i] for i in order]
        centre = np.mean(points[:-1], axis=0)
        reflected = centre + (centre - points[-1])
        f_r = fun(reflected)
        if f_r < values[0]:
            expanded = centre + 2 * (centre - points[-1])
            f_e = fun(expanded)
            points[-1], values[-1] = ((expanded, f_e) if f_e < f_r
                                      else (reflected, f_r))
        elif f_r < values[-2]:
            points[-1], values[-1] = reflected, f_r
        else:
            contracted = centre + 0.5 * (points[-1] - centre)
            f_c = fun(contracted)
            if f_c < values[-1]:
                points[-1], values[-1] = contracted, f_c
            else:
                points = [points[0] + 0.5 * (p - points[0]) for p in points]
                values = [fun(p) for p in points]
    best = int(np.argmin(values))
    return points[best], values[best]


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--durations", type=float, nargs="+",
                        default=[0.45, 0.40, 0.36, 0.33])
    args = parser.parse_args()
    scenario = load_scenario(name=_SCENARIO_NAME)
    obj, ik = resolve_object(name=args.object), ArmIk()
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    start = throw.end_state(scenario.throw, ik)
    q1 = np.array(plan.q_grasp)
    print(f"{args.object}: the move from the toss's hand-off (joint "
          f"velocities {np.round(start[1], 2)} rad/s) to the grasp pose "
          f"(Δq {np.round(q1 - start[0], 2)} rad)")
    for T in args.durations:
        quintic = torque_ratio(ik, start, q1, T, np.zeros(12))
        _, shaped = nelder_mead(
            lambda c, T=T: torque_ratio(ik, start, q1, T, c), np.zeros(12))
        print(f"  {T:.2f} s: quintic {quintic:.3f} of a servo's limit, "
              f"shaped {shaped:.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
