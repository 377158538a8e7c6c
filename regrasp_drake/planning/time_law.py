"""The arm's time laws: quintics in the normalised time τ = t / T, shared by
the catch state machine (station/catch_state_machine.py), which commands
them, and the catch planner (planning/catch_plan.py), which checks their
torques before the catch."""

import numpy as np


def quintic_from(tau, T, q0, v0, a0, q1):
    """The quintic from (q0, v0, a0) at τ = 0 to q1 at rest (zero velocity
    and acceleration) at τ = 1, τ = t / T: its (q, v, v̇) at τ, a number or
    a column (k × 1: rows of k × n), held at q1 after τ = 1."""
    scalar = np.ndim(tau) == 0
    if scalar and tau >= 1.0:
        return q1, np.zeros_like(q1), np.zeros_like(q1)
    done = None if scalar else tau >= 1.0
    tau = max(tau, 0.0) if scalar else np.maximum(tau, 0.0)
    c1, c2 = v0 * T, 0.5 * a0 * T * T
    A = q1 - q0 - c1 - c2
    B = -c1 - 2.0 * c2
    C = -2.0 * c2
    c3 = 10.0 * A - 4.0 * B + 0.5 * C
    c4 = -15.0 * A + 7.0 * B - C
    c5 = 6.0 * A - 3.0 * B + 0.5 * C
    q = q0 + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5))))
    dq = c1 + tau * (2 * c2 + tau * (3 * c3 + tau * (4 * c4 + tau * 5 * c5)))
    ddq = 2 * c2 + tau * (6 * c3 + tau * (12 * c4 + tau * 20 * c5))
    if done is None:
        return q, dq / T, ddq / (T * T)
    return (np.where(done, q1, q), np.where(done, 0.0, dq / T),
            np.where(done, 0.0, ddq / (T * T)))


def quintic(tau):
    """Time law s(τ), s'(τ), s''(τ) with zero end velocity and acceleration
    (τ a number or an array)."""
    tau = np.clip(tau, 0.0, 1.0) if np.ndim(tau) else min(max(tau, 0.0), 1.0)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = 30 * tau**2 * (1 - tau) ** 2
    dds = 60 * tau * (1 - tau) * (1 - 2 * tau)
    return s, ds, dds


def ease_in(tau):
    """Time law s(τ) = 2τ³ - τ⁴, s'(τ), s''(τ): from rest at τ = 0 to s = 1
    at τ = 1 moving at twice the mean speed (s' = 2, s'' = 0), then on at
    that speed (s = 1 + 2(τ - 1)) (τ a number or an array)."""
    tau = np.maximum(tau, 0.0) if np.ndim(tau) else max(tau, 0.0)
    u = np.minimum(tau, 1.0) if np.ndim(tau) else min(tau, 1.0)
    s = u**3 * (2.0 - u) + 2.0 * (tau - u)
    ds = u**2 * (6.0 - 4.0 * u)
    dds = 12.0 * u * (1.0 - u)
    return s, ds, dds
