"""How soon can the hand wait under a tossed object? A bound from gravity.

For every h_catch of the paper's range (0-0.40 m) to trigger after the hand
is in place, the palm must be at rest 0.40 m (plus the object's height over
the palm, CENTRE_ABOVE_PALM_M) below the object while the object still falls
toward it. Both leave the release with the same vertical velocity V; the
object then falls at g. The fastest the palm can get there is bang-bang: it
accelerates downward at A, then brakes at A to rest. Relative to the object
it gains (A - g) t1²/2 + (A - g) t1 t2 - (A + g) t2²/2, with t2 = t1 - V/A:
this grows without bound only if A > 2g; below 2g it peaks, the higher the
faster the launch (the palm then had longer to fall ahead). This script
prints, for launch speeds V and palm accelerations A, the earliest moment
the palm can wait
0.40 m under the object, where it then is, and the catch moment, spin
(half a turn by then) and impact speed that such a toss would need.

    .venv/bin/python studies/palm_toss/catch_timing_bound.py
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse

import numpy as np

G = 9.81
H_CATCH_MAX_M = 0.40
# The object's centre over the palm at the catch, [m] (about a lying
# object's radius plus the pads).
CENTRE_ABOVE_PALM_M = 0.04


def earliest_wait(V: float, A: float, dt: float = 1e-4):
    """(t, z_palm) of the earliest bang-bang palm at rest H_CATCH_MAX_M +
    CENTRE_ABOVE_PALM_M under the object, from the release (z = 0, both at
    V); None if the palm never gets there (with A < 2g it loses ground
    after a while)."""
    for t1 in np.arange(V / A, 3.0, dt):
        v1 = V - A * t1
        t2 = -v1 / A
        t = t1 + t2
        z_palm = V * t1 - A * t1**2 / 2 + v1 * t2 + A * t2**2 / 2
        z_object = V * t - G * t**2 / 2
        if z_object - z_palm >= H_CATCH_MAX_M + CENTRE_ABOVE_PALM_M:
            return t, z_palm
    return None


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--speeds", type=float, nargs="+",
                        default=[2.2, 2.5, 3.0])
    parser.add_argument("--accelerations", type=float, nargs="+",
                        default=[12.0, 16.0, 20.0, 25.0])
    args = parser.parse_args(argv)
    print("| launch V, m/s | palm A, m/s² | palm waits from, s | palm at, m "
          "| catch at, s | spin for half a turn, rad/s | impact, m/s |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for V in args.speeds:
        for A in args.accelerations:
            found = earliest_wait(V, A)
            if found is None:
                print(f"| {V} | {A} | never | | | | |")
                continue
            t, z_palm = found
            z_catch = z_palm + CENTRE_ABOVE_PALM_M
            T = (V + np.sqrt(V**2 - 2 * G * z_catch)) / G
            print(f"| {V} | {A} | {t:.3f} | {z_palm:+.3f} | {T:.3f} "
                  f"| {np.pi / T:.2f} | {V - G * T:.2f} |")


if __name__ == "__main__":
    main()
