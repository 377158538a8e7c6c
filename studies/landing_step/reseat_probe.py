"""Probe of a re-seat after the catch (FINDINGS §18): once the hand is back at
the grasp pose (the end of RETURN), the fingers open a fraction FRAC of the
way from closed to the catch's pre-shape at their speed, wait DWELL s, and
close again; HOLD, and the monitor's hold_s, start after that. Patched into
the catch state machine for this probe only (not a scenario option); each
pair's first throw replays X's rehearsal (X_eighth.jsonl) at the finer
judge's steps through benchmarks/regrasp_targets.py.

    .venv/bin/python studies/landing_step/reseat_probe.py OUT DWELL FRAC \\
        OBJECT:KIND:MM ...
"""
import regrasp_drake  # noqa: F401, I001 (first: it pins NumPy's kernels)
import argparse
import sys
from pathlib import Path

import numpy as np
from pydrake.systems.framework import EventStatus

from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station import catch_state_machine as csm

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import regrasp_targets  # noqa: E402

FINER = ("{plant_config: {time_step: 0.000125}, landing_time_step_s: "
         "0.00003125, target_catch_time_step_s: 0.000125}")


def patch(dwell_s: float, fraction: float) -> None:
    """The re-seat, patched into csm.CatchStateMachine."""
    transition = csm.CatchStateMachine._transition
    hand = csm.CatchStateMachine._hand_reference

    def ramps(self):
        if not hasattr(self, "_reseat"):
            speed = self._preshape_to_closed.speed
            relaxed = self._closed + fraction * (self._preshape - self._closed)
            opening = csm.FingerRamp(self._closed, relaxed, speed)
            closing = csm.FingerRamp(relaxed, self._closed, speed)
            self._reseat = (opening, closing, opening.duration + dwell_s
                            + closing.duration)
        return self._reseat

    def reseat_transition(self, context, x, t):
        if int(x[csm._PHASE]) == csm._RETURN:
            end = x[csm._T0] + x[csm._T]
            if end <= t < end + ramps(self)[2]:
                return EventStatus.Succeeded()  # still re-seating
        return transition(self, context, x, t)

    def reseat_hand(self, x, t):
        q, v = hand(self, x, t)
        if int(x[csm._PHASE]) != csm._RETURN:
            return q, v
        opening, closing, _ = ramps(self)
        e = np.asarray(t, float) - (x[csm._T0] + x[csm._T])
        q1, v1 = opening.at(e)
        q2, v2 = closing.at(e - opening.duration - dwell_s)
        second = e >= opening.duration + dwell_s
        started = e >= 0
        return (np.where(started, np.where(second, q2, q1), q),
                np.where(started, np.where(second, v2, v1), v))

    csm.CatchStateMachine._transition = reseat_transition
    csm.CatchStateMachine._hand_reference = reseat_hand


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("dwell_s", type=float)
    parser.add_argument("fraction", type=float)
    parser.add_argument("pairs", nargs="+", metavar="OBJECT:KIND:MM")
    args = parser.parse_args()
    if args.dwell_s < 0 or not 0 < args.fraction <= 1:
        parser.error(f"DWELL, FRAC: got {args.dwell_s}, {args.fraction}, "
                     "expected DWELL >= 0 and 0 < FRAC <= 1")
    for pair in args.pairs:
        if pair.count(":") != 2:
            parser.error(f"pair: got {pair!r}, expected OBJECT:KIND:MM")
    patch(args.dwell_s, args.fraction)
    for pair in args.pairs:
        name, kind, mm = pair.split(":")
        regrasp_targets.main([
            "--objects", name, "--targets", f"{kind}:{mm}",
            "--modes", "first-throw", "--max-throws", "1", "--rehearse",
            "--rehearsal-from",
            str(MODELS_DIR / "results" / "landing_step" / "X_eighth.jsonl"),
            "--scenario-text", FINER, "--out", args.out])


if __name__ == "__main__":
    main()
