"""The figures that say whether a simulated result is a property of the
object or of the solver: a success map against the same map at a finer
step, and a throw's release and catch point against the same throw at a
finer step (benchmarks/map_convergence.py, benchmarks/release_convergence.py
and the studies that compare their runs)."""

import numpy as np


def agreement(a, b) -> dict:
    """Cells with the same outcome in boolean maps a and b, and the number
    two independent maps with their catch rates would share by chance."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    p, q = a.mean(), b.mean()
    return {"same": int((a == b).sum()),
            "chance": round(float(a.size * (p * q + (1 - p) * (1 - q))), 1),
            "cells": int(a.size)}


def release_differences(a: dict, b: dict) -> dict:
    """How far apart two throws of one object are (rows of
    benchmarks/release_convergence.py: the object's state at the release,
    w_WO rad/s, v_WO m/s, p_WO m, and the planned catch point, catch_p_WO m
    at catch_t_s s, or None): the spin's, velocity's and position's
    differences and the catch point's and moment's (None unless both
    throws planned one)."""
    d = {"spin_rad_per_s": float(np.linalg.norm(
             np.subtract(a["w_WO"], b["w_WO"]))),
         "velocity_mm_per_s": 1e3 * float(np.linalg.norm(
             np.subtract(a["v_WO"], b["v_WO"]))),
         "position_mm": 1e3 * float(np.linalg.norm(
             np.subtract(a["p_WO"], b["p_WO"]))),
         "catch_point_mm": None, "catch_moment_ms": None}
    if a["catch_p_WO"] is not None and b["catch_p_WO"] is not None:
        d["catch_point_mm"] = 1e3 * float(np.linalg.norm(
            np.subtract(a["catch_p_WO"], b["catch_p_WO"])))
        d["catch_moment_ms"] = 1e3 * abs(a["catch_t_s"] - b["catch_t_s"])
    return d
