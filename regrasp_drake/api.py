"""The public face: from an object and a grasp to a regrasp, in a few lines.

    import regrasp_drake as rd
    obj = rd.load_object("table1-row2")
    run = rd.regrasp(obj, rd.Target("flip"), watch=False, max_throws=1)
    print(run.regrasp_line())   # the verdict first, then why
    run.save_replay("replay.html"); run.plot("sensors.png")

`regrasp`, `learn`, `catch` and `apply` are the command line's commands of
those names with their defaults (docs/commands.md); the commands, the
examples and the notebook call them. The main job (watch, plan, predict the
cell, catch, search) is the learning phase's (learning/learning_phase.py);
one catch attempt with given parameters is throw_catch.catch_once's.

Each returns a `Run`. Its episodes are drawn on `meshcat` (Drake's
StartMeshcat() in a notebook, or any Meshcat; default: a private one on
loopback, for the replay) unless replay=False, and recorded, so that
`Run.save_replay` writes them as one self-contained HTML file.

No call changes the process's state: torch's thread count is set to one
for a call that runs the network and restored after it, and what a call
writes without a path given (`learn`'s library) goes to ./out of the
working directory.

`Episode` is one throw (and its catch) held between its stages, for a
caller who drives an episode itself: start, advance to the release, set
the task, advance to the outcome, read the result.
"""

import contextlib
import dataclasses as dc
import difflib
import inspect
import sys
import warnings
from pathlib import Path

import torch

# rd.Episode: one throw held between its stages (episode/episode.py).
from regrasp_drake.episode.episode import Episode as Episode
from regrasp_drake.episode.result import EpisodeResult
from regrasp_drake.episode.static_hold import check_holdable
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import apply_learned
from regrasp_drake.learning.learning_phase import learn as learning_phase
from regrasp_drake.learning.library import DEFAULT_LIBRARY, lookup
from regrasp_drake.learning.offset_prior import OffsetPrior
from regrasp_drake.learning.planner import PAPER_NETWORK
from regrasp_drake.learning.run_replay import RunReplay
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import TARGET_KINDS, Target, check_reachable
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.plots import plot_episode
from regrasp_drake.station import scenario as scenarios
from regrasp_drake.station.mlp_system import CatchMlp, load_weights
from regrasp_drake.station.scenario import Scenario, target_of, with_target
from regrasp_drake.station.scenario_checks import check_catch_parameters
from regrasp_drake.throw_catch import catch_once, episode_caption, save_replay
from regrasp_drake.world.objects import ObjectSpec, resolve_object

# Where `learn` stores what it learned and `apply` looks it up by default:
# out/ of the working directory at the call (the command line's --library
# defaults to paths.OUT_DIR's instead).
DEFAULT_LIBRARY_PATH = Path("out") / DEFAULT_LIBRARY
# learn's planner: the target's shipped one, or the paper's network.
PLANNER_CHOICES = ("shipped", "paper")


def load_object(name: str | None = None, *, file=None) -> ObjectSpec:
    """A catalogue object by name (`regrasp-drake objects` lists them), or
    an object of a YAML file in the catalogue's format (examples/
    my_object.yaml): its first, or the one called `name`."""
    return resolve_object(name=name, file=None if file is None else Path(file))


def load_scenario(name: str | None = None, *, file=None,
                  text: str | None = None,
                  target: Target | str | None = None) -> Scenario:
    """A scenario: `name` of the shipped named scenarios (default "Default";
    "Fast" runs at a 1 ms step throughout), or of `file`'s, or `file` itself
    when it holds one scenario; `text`: YAML fields that replace its own
    (as --scenario-text); `target`: the grasp to aim for (a Target or its
    kind), which picks the target's throw."""
    scenario = scenarios.load_scenario(file, name=name, text=text,
                                       names=("file", "name", "text"))
    return scenario if target is None else with_target(scenario,
                                                       _target(target))


@dc.dataclass
class Run:
    """What `regrasp`, `learn`, `catch` and `apply` return: how the run
    ended, its last episode and, for a learning phase, all it reports."""
    object: str
    success: bool       # held in the target grasp (any grasp for `any`)
    throws: int         # throws made, a watching throw included
    episode: EpisodeResult  # the last throw (its logs: `plot`)
    plan: object = None     # the catch plan (throw_catch.CatchPlan), if any
    learning: object = None  # learning_result.LearningResult, for a phase
    replay: RunReplay | None = None  # every throw's recording, if recorded
    scenario: Scenario | None = None  # the scenario it ran under
    entry: object = None  # the library entry `apply` caught with

    @property
    def achieved_grasp(self) -> dict | None:
        """The grasp the last throw ends in (planning/grasp.py: kind,
        offset_mm along the axis, tilt_deg…), None when not held."""
        return self.episode.achieved_grasp

    @property
    def miss_reason(self) -> str | None:
        """Why the last throw is not in the target grasp: "dropped" (not
        held), "wrong_way_round" (the axis reversed), "wrong_side" (a
        lopsided object's side another), "tilted" (more than 20° off the
        palm's axis), "off_offset" (more than 10 mm from the target's
        offset); None on a success (planning/grasp.py miss_reason)."""
        return None if self.success else self.episode.miss_reason

    def regrasp_line(self) -> str:
        """The last throw's verdict first, then why: "flip, +0 mm: in the
        target grasp (held flip, +3 mm, tilt 12°)", "keep, +0 mm: missed,
        tilted 29° > 20° (held keep, +2 mm, tilt 29°)"."""
        return self.episode.regrasp_line()

    def summary(self) -> dict:
        """The learning phase's report, or the one throw's summary; JSON."""
        if self.learning is not None:
            return self.learning.as_dict()
        # Who chose the cell: the caller (`catch`), or, for `apply`, who
        # chose it when it was learned (None: a library from before that
        # was recorded).
        chosen_by = "given" if self.entry is None else self.entry.chosen_by
        return self.episode.summary() | {"chosen_by": chosen_by} | (
            {} if self.plan is None else {"plan": self.plan.as_dict()})

    def save_replay(self, path) -> str:
        """Writes the run's Meshcat replay to path, one self-contained HTML
        file: a run of one catching throw with its plan drawn (its path, the
        planned catch point, the palm's wait pose; views on the flight and
        the catch), else every throw one after the other. Returns path."""
        if self.replay is None:
            raise InputError("save_replay: the run was not recorded "
                             "(replay=False), expected a recorded run")
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        if self.replay.episodes == 1 and self.plan is not None:
            return save_replay(self.replay.meshcat, path, self.episode,
                               self.plan, ArmIk(self.scenario.directives),
                               caption=episode_caption(self.episode))
        return self.replay.save(path)

    def plot(self, path) -> Path:
        """Writes a PNG of the last throw's sensors over time (the paper's
        Fig. 11) and the object's height and tilt. Returns path."""
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        return plot_episode(self.episode, Path(path))


def catch(obj: ObjectSpec, h_catch: float, h_down: float, *,
          scenario: Scenario | None = None, meshcat=None,
          replay: bool = True) -> Run:
    """`regrasp-drake catch`: a watching throw, the catch planned under its
    flight, and one catch attempt with (h_catch, h_down), [m] (the paper's
    parameter space: 0 … 0.40, -0.14 … 0)."""
    check_catch_parameters(h_catch, h_down, names=("h_catch", "h_down"))
    scenario = _checked(scenario, obj)
    recording = _recording(meshcat, replay)
    episode, plan = catch_once(
        scenario, obj, h_catch=h_catch, h_down=h_down,
        meshcat=None if recording is None else recording.meshcat)
    if recording is not None:
        recording.add_episode(episode.sim_time_s)
    return _run(scenario, obj.name, episode, plan=plan, replay=recording,
                throws=2)


def learn(obj: ObjectSpec, *, scenario: Scenario | None = None,
          target: Target | str | None = None, watch: bool = True,
          at_release: bool = False, max_throws: int | None = None,
          search: str = "wavefront", weights=None, flight_model=None,
          offset_prior=None, library=DEFAULT_LIBRARY_PATH,
          meshcat=None, replay: bool = True, progress=sys.stderr,
          scenario_label: str = "defaults",
          object_source: str = "catalogue", planner: str = "shipped",
          rehearse: bool = False, first_throw: bool | None = None) -> Run:
    """`regrasp-drake learn`: the learning phase on `obj` (paper Fig. 1):
    watch, plan, the planner's cell, catch, and search the parameter space
    until a catch (learning/learning_phase.py).

    What it may cost, in throws: with `watch` (the default) one watching
    throw, then one catching throw per cell tried until one catches: up to
    the 150 cells, fewer under a grasp target (it stops after 10 throws in
    a row missed it the same way); without, the catch from throw 1 on.
    `max_throws` bounds it: watch=False, max_throws=1 is one throw.

    target: the grasp to end in (a Target or its kind; default the
    scenario's regrasp.target). watch=False: no watching throw, throw 1
    catches, planned from the flight predictor (`flight_model`, a path or a
    loaded FlightPredictor; default models/flight_predictor.json), or with
    at_release=True planned at each throw's release. max_throws: stop after
    so many throws, the watching throw included (at least 2 with watch;
    default: until a catch or every cell is tried). first_throw: the old
    name of watch=False (deprecated). search:
    "wavefront" (the paper's) or "map-prior". weights: the network (a path
    or a loaded CatchMlp; default the scenario's catch.weights in models/).
    offset_prior: a path or a loaded OffsetPrior (default none). library:
    where a catch is stored (None: not stored). progress: a stream for one
    line per throw (None: quiet). scenario_label, object_source: what the
    library records of where the scenario and the object came from.
    planner: who picks the search's first cell, "shipped" (the target's
    planner, models/planner_<target>.json's winner; the paper's network
    under `any`) or "paper" (the paper's network; docs/planner.md).
    rehearse: the first catch (planned from the watched or the predicted
    flight; not at_release) is rehearsed in simulation at a lattice of 25
    cells in each of three catch modes before the throw (the palm moved
    4-8 mm along the axis where no mode lands) and starts from the cell
    that lands in its margin's draws (half the step first, then release
    noise) among the most robust, the palm's other places searched too
    where no candidate lands at half the step and in 2 draws, then the
    flight's second catch moment (learning/rehearsal.py; one to fifteen
    minutes on two cores). A target that no rehearsed cell lands and no
    closing of the hand holds at rest (the static test) is refused before
    the catching throw: InputError (learning_phase.Unholdable)."""
    if planner not in PLANNER_CHOICES:
        raise field_error("planner", planner, " or ".join(PLANNER_CHOICES))
    watch = _watch(watch, first_throw, "learn")
    if at_release and watch:
        raise InputError("at_release: got True with watch=True, expected "
                         "watch=False (a catch planned at each release makes "
                         "no watching throw)")
    if rehearse and at_release:
        raise InputError("rehearse: got True with at_release=True, expected "
                         "at_release=False (it rehearses a catch planned "
                         "before the throw)")
    _check_max_throws(max_throws, watch)
    scenario = _checked(scenario, obj, target)
    recording = _recording(meshcat, replay)
    episodes = []

    def on_episode(result):
        episodes.append(result)
        if recording is not None:
            recording.add_episode(result.sim_time_s)

    if library is not None and Path(library) == DEFAULT_LIBRARY_PATH:
        Path(library).parent.mkdir(exist_ok=True)
    with _one_torch_thread():
        result = learning_phase(
            scenario, obj, load_network(weights, scenario),
            library_path=library, scenario_label=scenario_label,
            object_source=object_source, max_throws=max_throws,
            flight_predictor=(load_flight_predictor(flight_model)
                              if not watch and not at_release else None),
            at_release=at_release, search=search,
            offset_prior=load_offset_prior(offset_prior, scenario),
            meshcat=None if recording is None else recording.meshcat,
            on_episode=on_episode, progress=progress,
            planner=PAPER_NETWORK if planner == "paper" else None,
            rehearse=rehearse)
    # The plan of the last catching throw (a later one's, after an offset
    # correction, never ran).
    plan = result.attempts[-1].plan if result.attempts else result.plan
    return _run(scenario, obj.name, episodes[-1], plan=plan,
                learning=result, replay=recording, success=result.success,
                throws=result.throws)


def regrasp(obj: ObjectSpec, target: Target | str, *, watch: bool = True,
            **options) -> Run:
    """`regrasp-drake regrasp`: the learning phase aiming for `target` (a
    Target, e.g. Target("flip", offset_mm=0), or its kind: keep, flip, turn,
    any); watch=False: no watching throw, throw 1 catches, planned from
    the flight predictor (with max_throws=1: that one throw, and no search
    after a miss); `options` as `learn`'s, which says what a call may cost
    in throws."""
    _check_options("regrasp", options, learn, taken=("target", "watch"))
    return learn(obj, target=target, watch=watch, **options)


def apply(obj: ObjectSpec, *, library=DEFAULT_LIBRARY_PATH,
          scenario: Scenario | None = None, meshcat=None,
          replay: bool = True) -> Run:
    """`regrasp-drake apply`: one throw, caught with the grasp pose and
    parameters `learn` stored for `obj` in `library` under this
    scenario."""
    scenario = _checked(scenario, obj)
    entry = lookup(library, obj.name)
    recording = _recording(meshcat, replay)
    episode = apply_learned(
        scenario, obj, entry,
        meshcat=None if recording is None else recording.meshcat)
    if recording is not None:
        recording.add_episode(episode.sim_time_s)
    return _run(scenario, obj.name, episode, replay=recording, entry=entry)


def load_network(weights, scenario: Scenario, *, field: str = "weights"):
    """The catch network: `weights` loaded (a path; a CatchMlp as it is;
    None: the scenario's catch.weights in models/). InputError names
    `field` and the file."""
    if isinstance(weights, CatchMlp):
        return weights
    path = weights or MODELS_DIR / scenario.catch.weights
    try:
        return load_weights(path)[0]
    except InputError as e:
        label = field if weights else (f"{field} (default: the scenario's "
                                       "catch.weights)")
        raise InputError(f"{label}: {e}") from None


def load_flight_predictor(flight_model=None, *, field: str = "flight_model"):
    """The first-throw mode's flight predictor: a path loaded (None:
    models/flight_predictor.json), a FlightPredictor as it is."""
    if isinstance(flight_model, FlightPredictor):
        return flight_model
    try:
        return FlightPredictor.load(flight_model
                                    or MODELS_DIR / "flight_predictor.json")
    except InputError as e:
        raise InputError(f"{field}: {e}") from None


def load_offset_prior(offset_prior, scenario: Scenario, *,
                      field: str = "offset_prior"):
    """The offset prior for a scenario aiming for a target: a path loaded,
    an OffsetPrior as it is; None without one, or for target `any`."""
    if scenario.regrasp.target == "any" or offset_prior is None:
        return None
    if isinstance(offset_prior, OffsetPrior):
        return offset_prior
    try:
        return OffsetPrior.load(offset_prior)
    except InputError as e:
        raise InputError(f"{field}: {e}") from None


def _target(target: Target | str) -> Target:
    if isinstance(target, Target):
        return target
    if isinstance(target, str) and target in TARGET_KINDS:
        return Target(target)
    raise field_error("target", target, "a Target or one of its kinds "
                                        "(keep, flip, turn, any)")


def _check_options(function: str, options: dict, inner,
                   taken: tuple = ()) -> None:
    """Refuses a keyword argument of `options` that `inner` does not take
    (or that `function` sets itself, `taken`), as Python does, naming
    `function`, the one the caller called."""
    known = [p for p in inspect.signature(inner).parameters
             if p not in taken and p != "obj"]
    for name in options:
        if name not in known:
            close = difflib.get_close_matches(name, known, n=1)
            hint = f". Did you mean {close[0]!r}?" if close else ""
            raise TypeError(f"{function}() got an unexpected keyword "
                            f"argument {name!r}{hint}")


def _watch(watch: bool, first_throw: bool | None, function: str) -> bool:
    """watch, or the deprecated first_throw's opposite."""
    if first_throw is None:
        return watch
    warnings.warn(f"{function}(first_throw=...) is deprecated: it means no "
                  "watching throw, not one throw; use watch=False (and "
                  "max_throws=1 for one throw)", DeprecationWarning,
                  stacklevel=3)
    return not first_throw


def _check_max_throws(max_throws, watch: bool) -> None:
    """At least the watch, if any, and one catching throw."""
    if max_throws is None:
        return
    least = 2 if watch else 1
    if (not isinstance(max_throws, int) or isinstance(max_throws, bool)
            or max_throws < least):
        raise field_error("max_throws", max_throws, (
            f"an integer >= {least} ("
            + ("the watching throw and one catch; watch=False catches on "
               "throw 1)" if watch else "one catching throw)")))


@contextlib.contextmanager
def _one_torch_thread():
    """torch on one thread (the network's output, and so the cell, is then
    the same bits everywhere), its thread count restored after."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def _checked(scenario: Scenario | None, obj: ObjectSpec,
             target: Target | str | None = None) -> Scenario:
    """The scenario (None: the shipped default) aiming for `target` (None:
    its own), refused when the target is out of the object's reach."""
    if scenario is None:
        scenario = load_scenario()
    elif not isinstance(scenario, Scenario):
        raise field_error("scenario", scenario,
                          "a Scenario (rd.load_scenario) or None")
    if not isinstance(obj, ObjectSpec):
        raise field_error("obj", obj, "an object (rd.load_object)")
    if target is not None:
        scenario = with_target(scenario, _target(target))
    check_reachable(target_of(scenario), obj)
    check_holdable(scenario, obj)
    return scenario


def _recording(meshcat, replay: bool) -> RunReplay | None:
    """Where a run's throws are drawn and recorded: `meshcat` (any Meshcat)
    or, when replay is True, a private one; None: not drawn."""
    if meshcat is None and not replay:
        return None
    return RunReplay(meshcat=meshcat)


def _run(scenario: Scenario, name: str, episode: EpisodeResult, *,
         success: bool | None = None, throws: int = 1, **fields) -> Run:
    return Run(object=name, episode=episode, throws=throws,
               success=episode.success if success is None else success,
               scenario=scenario, **fields)
