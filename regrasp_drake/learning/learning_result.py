"""What a learning phase reports: every attempt (`Attempt`) and the
phase's result (`LearningResult`), and the refusal of an object with no
reachable catch point (`NoCatchPoint`)."""

import dataclasses as dc

from regrasp_drake.episode.result import EpisodeResult
from regrasp_drake.errors import InputError
from regrasp_drake.learning import library as lib
from regrasp_drake.learning.observation import episode_dict, plan_dict
from regrasp_drake.parameter_space import HELD_OUTCOMES, cell_parameters
from regrasp_drake.station.mlp_system import FEATURE_NAMES
from regrasp_drake.throw_catch import CatchPlan


class NoCatchPoint(InputError):
    """The watching throw shows no reachable catch point: the learning phase
    cannot go on. Carries the throws made (the watch) and their time."""

    def __init__(self, message: str, *, throws: int, sim_time_s: float,
                 wall_s: float):
        super().__init__(message)
        self.throws = throws
        self.sim_time_s = sim_time_s
        self.wall_s = wall_s


class Unholdable(InputError):
    """A grasp target refused before the catching throw: no closing of the
    hand holds the object at rest in it (the static test) and the
    rehearsal lands no cell in it in any catch mode, palm place or catch
    moment. Carries the throws made (a watch, if any)."""

    def __init__(self, message: str, *, throws: int):
        super().__init__(message)
        self.throws = throws


@dc.dataclass
class Attempt:
    throw: int          # the throw's number in the run (the watch is 1)
    cell: tuple         # (i_catch, i_down)
    h_catch: float      # [m]
    h_down: float       # [m]
    # caught (in the target grasp) | wrong_grasp | dropped | timeout |
    # landed | failed
    outcome: str
    sim_time_s: float   # simulated time of the throw, [s]
    wall_s: float       # wall time of the throw, [s]
    message: str        # a failed episode's reason
    # How a throw that did not catch ended (grid.ending: in_fingers, on_arm,
    # loose, below_palm, near_ground, failed, other), None when caught.
    ending: str | None = None
    # How the throw corrected its watched plan at its release
    # (throw_catch.ReleaseCorrection.as_dict), when its release differed.
    release_correction: dict | None = None
    # The grasp it ended in (planning/grasp.Grasp.as_dict; None when not
    # held) and its error against the target.
    achieved_grasp: dict | None = None
    grasp_error: dict | None = None
    # The plan the throw waited under (throw_catch.CatchPlan; not reported).
    plan: CatchPlan | None = None
    # Who chose its cell: the search's first cell's chooser
    # (learning/planner.py Planner.name) or "search".
    chosen_by: str | None = None

    @property
    def caught(self) -> bool:
        """Held at the end, in whatever grasp."""
        return self.outcome in HELD_OUTCOMES

    def as_dict(self) -> dict:
        d = {"throw": self.throw, "cell": list(self.cell),
             "h_catch": self.h_catch, "h_down": self.h_down,
             "outcome": self.outcome, "success": self.outcome == "caught",
             "caught": self.caught, "achieved_grasp": self.achieved_grasp,
             "grasp_error": self.grasp_error,
             "sim_time_s": round(self.sim_time_s, 4),
             "wall_s": round(self.wall_s, 3), "message": self.message,
             "ending": self.ending, "chosen_by": self.chosen_by}
        if self.release_correction is not None:
            d["release_correction"] = self.release_correction
        return d


@dc.dataclass
class LearningResult:
    object: str
    success: bool       # held in the target grasp on the last throw
    # caught | exhausted | max_throws | no_catch_point | same_miss (under a
    # grasp target, learning_phase.MAX_SAME_MISSES throws in a row missed it
    # for the same reason)
    stopped: str
    throws: int         # every throw, the watching throw included
    sim_time_s: float   # simulated time of every throw, [s]
    wall_s: float       # wall time of the whole phase, [s]
    watched: EpisodeResult | None  # the watching throw, if one was made
    plan: CatchPlan
    features: list      # the network's inputs (FEATURE_NAMES order)
    raw_prediction: list    # the network's output (h_catch, h_down), [m]
    prediction: tuple       # clamped to the parameter space, [m]
    start_cell: tuple
    attempts: list[Attempt]
    learned: lib.LearnedEntry | None
    first_throw: bool = False  # planned from the predicted flight first
    # First-throw mode: when and from what the catch was planned again
    # (after_throw, from: "seen flight" | "watching throw"), or None.
    replanned: dict | None = None
    first_plan: CatchPlan | None = None  # the predicted flight's, if replaced
    at_release: bool = False  # each throw planned when it released the object
    search: str = "wavefront"  # the search's rule: one of search.SEARCHES
    # Who chose the search's first cell (learning/planner.py Planner.name).
    planner: str = "paper_network"
    # The first catch's rehearsal (learning/rehearsal.py Rehearsal.as_dict),
    # or None when not rehearsed.
    rehearsal: dict | None = None
    target: dict | None = None  # the scenario's (planning/grasp.Target)
    start_grasp: dict | None = None  # how the object lay before the throw

    @property
    def caught(self) -> bool:
        """The last throw held the object, in whatever grasp."""
        return bool(self.attempts) and self.attempts[-1].caught

    @property
    def achieved_grasp(self) -> dict | None:
        """The grasp the last throw ended in (None: not held)."""
        return self.attempts[-1].achieved_grasp if self.attempts else None

    @property
    def search_attempts(self) -> list[Attempt]:
        """The attempts at the final plan (its search from start_cell)."""
        after = (self.replanned or {}).get("after_throw", 0)
        return [a for a in self.attempts if a.throw > after]

    def as_dict(self) -> dict:
        return {
            "object": self.object, "target": self.target,
            "success": self.success, "caught": self.caught,
            "start_grasp": self.start_grasp,
            "achieved_grasp": self.achieved_grasp,
            "grasp_error": (self.attempts[-1].grasp_error if self.attempts
                            else None),
            "stopped": self.stopped, "throws": self.throws,
            "sim_time_s": round(self.sim_time_s, 4),
            "wall_s": round(self.wall_s, 3),
            "watch": (None if self.watched is None
                      else episode_dict(self.watched)),
            "first_throw": self.first_throw,
            "at_release": self.at_release,
            "search": self.search, "planner": self.planner,
            **({"rehearsal": self.rehearsal} if self.rehearsal else {}),
            "replanned": self.replanned,
            "first_plan": (None if self.first_plan is None
                           else plan_dict(self.first_plan)),
            "plan": plan_dict(self.plan),
            "features": dict(zip(FEATURE_NAMES, self.features)),
            "prediction": {"raw": [round(x, 5) for x in self.raw_prediction],
                           "clamped": [round(x, 5) for x in self.prediction],
                           "start_cell": list(self.start_cell),
                           "start_parameters": list(
                               cell_parameters(self.start_cell))},
            "attempts": [a.as_dict() for a in self.attempts],
            "learned": None if self.learned is None else self.learned.as_dict(),
        }
