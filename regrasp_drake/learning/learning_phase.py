"""The learning phase (paper Fig. 1) and the applying phase (paper §II).

Learning: throw 1 watches the object's flight (no catch attempt); the offline
stage finds the catch point and plans the hand's pose there
(`throw_catch.plan_catch`); the MLP predicts (h_catch, h_down) from
(v_catch, h_cm, r_cm, d_obj, v_conv); throw 2 catches with that prediction;
when it fails, the search goes on from the prediction's cell, one throw per
cell, until a catch or the grid is exhausted. The search is an object
(`search.Search`): `learn` throws at the cell it proposes and tells it the
outcome. It is the paper's wavefront search (`search="wavefront"`, the
default; `search.wavefront_order`), or the map-prior search
(`search="map-prior"`; `search.MapPrior`), which after each failed cell
tries the cell most likely to catch according to the training success maps
(models/dataset/maps.npz) that agree with the failures so far. Every throw
recreates the same initial conditions, so the flight repeats exactly and
only the catch differs.

A catching throw corrects its plan at its own release
(`throw_catch.release_correction`): the object's state then is compared
with the one the plan was made from, the one the watching throw logged or,
in first-throw mode, the flight predictor's; when they are equal bit for
bit (a watched plan, no release noise) nothing changes, otherwise the palm
moves by the difference between the plans made from the two releases in
closed-form free flight, before the arm leaves for the grasp pose (the
correction is reported with the throw's attempt). The cell is not changed.

Throw 2 uses the parameters of the grid cell nearest the clamped prediction,
not the prediction itself: the network's output is quantized to the paper's
tolerances (0.04 m in h_catch, 0.01 m in h_down), which makes throw 2 the
first cell of one grid search (as the paper's Fig. 8 does: its start point
is a cell of the parameter space). The raw and clamped predictions are
reported beside the cell.

Where the arm cannot lower the hand as far as a cell's h_down under the
plan (`throw_catch.reachable_h_down`: the lowered pose the state machine
would command is out of reach, and the episode would fail whatever the
object does), no throw is spent on that cell: the search skips it, and a
start cell there moves to the nearest h_down the arm reaches
(`feasible_start`). None of the Table 1 or held-out objects has such cells;
adze-d300-3 (lowering to 0.03 m at most) is caught in 5 throws instead of 82.

First-throw mode (the paper's future work, §VII): with a flight predictor,
there is no watching throw; the offline stage plans from the predicted
flight, and throw 1 already tries to catch. A throw that fails is still
seen: until the hand first touches the object, its flight is the watching
throw's (throws repeat exactly), so the catch is planned again from what was
seen of it (`throw_catch.seen_flight`) and the network and the search start
again from that plan. If the seen flight ends before any reachable catch
point, the next throw watches. So first-throw mode costs at most one throw
more than watching first, and none when the seen flight holds the plan.

Planning at release (`at_release`, also a first-throw mode): no watching
throw and no predicted flight; each catching throw plans its own catch when
the throw ends and the object flies free, from the object's state seen then,
propagated in free flight (`free_flight.flight_from_release`): what a
robot that tracks the object leaving its hand can do. The network and the
search start from throw 1's plan; a later throw keeps the search's cell and
plans its pose from its own release (the same pose without release noise).

Applying: one throw with the stored grasp pose and parameters.

Over 500 lines because the learning phase is one procedure (`_Phase`: watch,
plan, predict, catch, correct, replan, search) whose steps share its state;
what it reports is in learning_result.py, the observation throw in
observation.py.
"""

import sys
import time

import numpy as np
import torch
from pydrake.math import RigidTransform

from regrasp_drake import __version__
from regrasp_drake.episode.episode import release_time, run_episode
from regrasp_drake.episode.result import EpisodeResult, start_grasp
from regrasp_drake.episode.static_hold import static_hold
from regrasp_drake.errors import InputError, field_error
from regrasp_drake.grid import ending
from regrasp_drake.learning import library as lib
from regrasp_drake.learning.learning_result import (
    Attempt,
    LearningResult,
    NoCatchPoint,
    Unholdable,
)
from regrasp_drake.learning.planner import Planner, load_planner
from regrasp_drake.learning.rehearsal import (
    MARGIN_DRAWS,
    MODES,
    PALM_SHIFTS_M,
    Rehearsal,
    later_moments,
    mode_scenario,
    rehearse,
)
from regrasp_drake.learning.search import (
    SEARCHES,
    Search,
    load_prior_maps,
    object_prior,
)
from regrasp_drake.parameter_space import (
    H_DOWN_VALUES,
    cell_parameters,
    nearest_cell,
)
from regrasp_drake.planning import grasp
from regrasp_drake.planning.catch_plan import (
    CatchPoint,
)
from regrasp_drake.planning.follow import follows, plan_follow
from regrasp_drake.planning.free_flight import flight_from_release
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.progress import say
from regrasp_drake.station.mlp_system import FEATURE_NAMES, CatchMlp, ParameterSpace
from regrasp_drake.station.scenario import Scenario, scenario_digest, target_of
from regrasp_drake.throw_catch import (
    CatchPlan,
    ReleaseCorrection,
    catch_planned,
    plan_catch,
    plan_watched,
    reachable_h_down,
    seen_flight,
    shifted_along_axis,
    watch,
)
from regrasp_drake.world.objects import ObjectSpec


# ---- the network's prediction -------------------------------------------
def network_features(obj: ObjectSpec, catch_point: CatchPoint) -> list[float]:
    """The MLP's inputs in its order (mlp_system.FEATURE_NAMES): v_catch (m/s)
    at the catch point, then the object's h_cm, r_cm (m), d_obj (kg/m³) and
    v_conv."""
    values = {"v_catch": catch_point.v_catch} | obj.features()
    return [float(values[name]) for name in FEATURE_NAMES]


def predict(model: CatchMlp, features) -> tuple[list[float], tuple]:
    """The network's raw output and the output clamped to the parameter space,
    (h_catch, h_down) in m."""
    with torch.no_grad():
        raw = model(torch.as_tensor(np.asarray(features, np.float64))).tolist()
    return raw, ParameterSpace().clamp(*raw)


def feasible_start(cell, ik: ArmIk, plan: CatchPlan, *,
                   along_normal: bool = False):
    """(start cell, reach): `cell` (the network's) moved, if the arm cannot
    lower the hand that far under `plan`, to the nearest h_down it can
    (`throw_catch.reachable_h_down`), and that reach per h_down column."""
    reach = reachable_h_down(ik, plan, H_DOWN_VALUES,
                             along_normal=along_normal)
    i, j = cell
    if not reach[j]:
        j = min((k for k in range(len(reach)) if reach[k]),
                key=lambda k: (abs(k - j), k))
    return (i, j), reach


# ---- the learning phase -------------------------------------------------
# How often a learning phase moves the palm along the axis after a throw held
# at another offset than the target's (_Phase.correct_offset).
MAX_OFFSET_CORRECTIONS = 3
# Under a grasp target, a learning phase stops after this many throws in a
# row missed the target for the same reason (grasp.miss_reason: dropped,
# the wrong way round, tilted, off the offset), rather than trying all 150
# cells: a miss every cell makes is the object's, not the cell's.
MAX_SAME_MISSES = 10


def learn(scenario: Scenario, obj: ObjectSpec, model: CatchMlp, *,
          ik: ArmIk | None = None, library_path=None,
          scenario_label: str = "defaults",
          object_source: str = "catalogue", max_throws: int | None = None,
          meshcat=None, on_episode=None, progress=sys.stderr,
          flight_predictor=None, at_release: bool = False,
          search: str = "wavefront", prior_maps=None,
          prior_features=None, offset_prior=None,
          planner: Planner | None = None,
          rehearse: bool = False,
          rehearsed: dict | None = None) -> LearningResult:
    """The learning phase on one object (see the module's docstring).

    planner: who picks the search's first cell (learning/planner.py): None,
    the shipped planner of the scenario's target (`load_planner`: the
    chooser that won its judging by geometry; the paper's network for `any`
    and where no planner is shipped); `planner.PAPER_NETWORK`, the paper's
    network. Every attempt says who chose its cell (`chosen_by`).

    search: the order of the cells after the network's, "wavefront" (the
    paper's) or "map-prior" (see learning/search.py). prior_maps: the map
    prior's success maps, (entries, 10, 15), and prior_features, their
    entries' network features (entries, 5) for the prior's feature kernel
    (None: all maps weigh alike); both None: the shipped training maps and
    features, `search.load_prior_maps`. Only with "map-prior".

    offset_prior: a learning.offset_prior.OffsetPrior: the palm waits, from
    the first catching throw on, the other way from the slide along the
    axis it predicts for the object under the scenario's target (None: at
    the target's offset; later throws correct it from what they show
    either way, `_Phase.correct_offset`).

    flight_predictor: a learning.flight_predictor.FlightPredictor for the
    first-throw mode (no watching throw), or None. rehearse: with it, the
    first catch (planned from the watched or the predicted flight; not
    `at_release`) is rehearsed in simulation before the throw at a lattice of
    cells in each catch mode (rehearsal.MODES), at the palm's places where
    none lands, and starts from the cell with the most margin in the
    target grasp, in that cell's mode (learning/rehearsal.py; a chooser of its own,
    `chosen_by` "rehearsal"). rehearsed: with rehearse, a rehearsal of this
    same first catch recorded before (a LearningResult's `rehearsal`, made
    under this scenario without its release noise), replayed instead of
    rehearsing again: the rehearsal simulates the throw without release
    noise, so runs that differ only in their noise share it
    (benchmarks/regrasp_targets.py --rehearsal-from). at_release: the
    first-throw mode that plans each throw's catch at its release (no
    flight predictor then).

    library_path: where the learned entry is stored when a throw catches
    (None: not stored). max_throws: stop after this many throws, the watch
    included (None: until a catch or the 150 cells are exhausted).
    meshcat: recorded by every throw; on_episode(result) is called after each
    (e.g. RunReplay.add_episode). progress: a stream that gets one line per
    throw (None: quiet)."""
    prior = _check_learn_arguments(
        flight_predictor=flight_predictor, at_release=at_release,
        search=search, prior_maps=prior_maps, prior_features=prior_features,
        max_throws=max_throws, library_path=library_path)
    if rehearsed is not None and not rehearse:
        raise InputError("rehearsed: got a recorded rehearsal with "
                         "rehearse=False, expected rehearse=True")
    phase = _Phase(scenario, obj, model, ik or ArmIk(scenario.directives), prior=prior,
                   at_release=at_release, meshcat=meshcat,
                   on_episode=on_episode, progress=progress,
                   offset_prior=offset_prior,
                   planner=planner or load_planner(target_of(scenario)),
                   rehearse=rehearse and not at_release,
                   rehearsed=rehearsed)
    # Throw 1 watches (or the flight is predicted); the offline stage plans
    # the catch and the network's cell starts the search. At release, throw
    # 1 plans its own catch, and starts the search, when it lets go.
    phase.plan_first(flight_predictor)
    # One throw per cell the search proposes, until one catches.
    while True:
        if phase.search is not None and phase.search.next_cell is None:
            stopped = "exhausted"
            break
        if max_throws is not None and phase.throws >= max_throws:
            stopped = "max_throws"
            break
        result = phase.catch()  # at the search's next cell
        if result is None:  # at release: nothing to catch
            stopped = "no_catch_point"
            break
        if not result.success and phase.correct_offset(result):
            continue  # the same cell again, the palm moved along the axis
        phase.search.tell(result.outcome)
        if result.success:
            stopped = "caught"
            break
        if phase.same_miss(result):
            stopped = "same_miss"
            break
        if phase.predicted:  # the predicted flight's plan failed
            stopped = phase.replan(result, max_throws)
            if stopped is not None:
                break
    return phase.result(stopped, library_path=library_path,
                        scenario_label=scenario_label,
                        object_source=object_source,
                        first_throw=flight_predictor is not None or at_release)


def _check_learn_arguments(*, flight_predictor, at_release, search,
                           prior_maps, prior_features, max_throws,
                           library_path):
    """Refuses learn's bad arguments before any throw; returns the map
    prior's (maps, features) for search "map-prior" (the shipped ones when
    none are given), None for the wavefront."""
    if at_release and flight_predictor is not None:
        raise field_error("flight_predictor", "given",
                          "none when planning at release")
    if search not in SEARCHES:
        raise field_error("search", search,
                          f"one of {', '.join(map(repr, SEARCHES))}")
    for name, value in (("prior_maps", prior_maps),
                        ("prior_features", prior_features)):
        if value is not None and search != "map-prior":
            raise field_error(name, "given", "none unless search is "
                                             "'map-prior'")
    if prior_features is not None and prior_maps is None:
        raise field_error("prior_features", "given without prior_maps",
                          "the features of the prior_maps' entries")
    if search == "map-prior" and prior_maps is None:
        # A bad file: refused before a throw.
        _, prior_maps, prior_features = load_prior_maps(with_features=True)
    first_throw = flight_predictor is not None or at_release
    if max_throws is not None and not (
            isinstance(max_throws, int) and max_throws >= 2 - first_throw):
        raise field_error("max_throws", max_throws,
                          "an integer >= 1 (one catch attempt)" if first_throw
                          else "an integer >= 2 (the watch and one catch "
                               "attempt)")
    if library_path is not None:
        lib.load_library(library_path)  # a malformed file: refused now
    return None if search != "map-prior" else (prior_maps, prior_features)


class _Phase:
    """One learning phase between its throws: the throws made, the plan the
    catches use, the search over the cells from the network's cell for that
    plan, and the attempts so far (see `learn`, which runs its loop)."""

    def __init__(self, scenario: Scenario, obj: ObjectSpec, model: CatchMlp,
                 ik: ArmIk, *, prior, at_release: bool, meshcat, on_episode,
                 progress, planner: Planner, offset_prior=None,
                 rehearse: bool = False, rehearsed: dict | None = None):
        self.scenario, self.obj, self.model, self.ik = scenario, obj, model, ik
        self.planner = planner
        # Whether the first catch is rehearsed (learning/rehearsal.py), a
        # recorded rehearsal to replay (or None), and the rehearsal once
        # made; who chose the search's first cell.
        self.rehearse, self.rehearsed = rehearse, rehearsed
        self.rehearsal = None
        # The scenario of the catching throws: the phase's, in the catch
        # mode the rehearsal picked (learning/rehearsal.py).
        self.catch_scenario = scenario
        self.start_chooser = planner.name
        self.prior = prior  # (maps, features) of the map prior, or None
        self.at_release = at_release
        self.meshcat, self.on_episode, self.progress = (meshcat, on_episode,
                                                        progress)
        self.t0 = time.perf_counter()
        self.throws = 0
        self.watched: EpisodeResult | None = None
        self.plan: CatchPlan | None = None
        self.first_plan: CatchPlan | None = None
        # The flight the first plan is from (predicted or watched): its
        # later catch moments are the rehearsal's too.
        self.flight = None
        self.search: Search | None = None
        self.features = self.raw = self.prediction = None
        self.network_cell = None  # the network's cell for the plan
        self.attempts: list[Attempt] = []
        self.predicted = False  # the plan is the predicted flight's
        self.replanned: dict | None = None
        self.unplanned_sim_s = 0.0  # throws with nothing to catch at release
        # The palm's shift along the object's axis learned from throws held
        # at another offset than the target's (`correct_offset`), [m].
        self.palm_shift_m = 0.0
        self.offset_corrections = 0
        self.offset_prior = offset_prior
        # The last throws' miss reason and how many in a row (`same_miss`).
        self.misses = (None, 0)

    def report(self, line: str) -> None:
        if self.progress is not None:
            say(f"{self.obj.name}: {line}", self.progress)

    def watch(self) -> EpisodeResult:
        """A watching throw (no catch attempt)."""
        self.watched = watch(self.scenario, self.obj, self.ik,
                             meshcat=self.meshcat)
        self.throws += 1
        if self.on_episode is not None:
            self.on_episode(self.watched)
        w = self.watched
        self.report(f"throw {self.throws} (watch): {w.outcome}, "
                    f"{w.sim_time_s:.2f} s simulated, {w.wall_s:.1f} s wall")
        return w

    def plan_first(self, flight_predictor) -> None:
        """The plan of the first catch, from the predicted flight or else a
        watching throw (NoCatchPoint when it shows none), and its search;
        at release, nothing yet."""
        plan = None
        if flight_predictor is not None:
            # (a predictor fitted for another throw is refused here, not
            # taken for a flight without a catch point)
            flight_predictor.check_scenario(self.scenario)
            try:
                plan = flight_predictor.plan(self.obj, self.scenario, self.ik)
                self.flight = flight_predictor.as_watched(self.obj,
                                                          self.scenario)
                self.report("no watching throw: the catch is planned from "
                            "the predicted flight")
                self.predicted = True
            except InputError as e:
                self.report(f"the predicted flight has no reachable catch "
                            f"point ({e}); throw 1 watches")
                self.replanned = {"after_throw": 0, "from": "watching throw"}
        if plan is None and not self.at_release:
            watched = self.watch()
            try:
                plan = plan_watched(self.scenario, self.obj, self.ik, watched)
                self.flight = watched
            except InputError as e:
                raise NoCatchPoint(str(e), throws=1,
                                   sim_time_s=watched.sim_time_s,
                                   wall_s=time.perf_counter() - self.t0
                                   ) from None
        if plan is not None:
            self.start_search(plan)
        self.first_plan = plan

    def start_search(self, plan: CatchPlan) -> None:
        """The network's cell for `plan` (moved to an h_down the arm reaches,
        `feasible_start`) and a new search from it; the catches use `plan`,
        the palm moved along the axis by what the offset prior predicts (the
        first time) or the throws so far showed."""
        first = self.features is None
        self.features = network_features(self.obj, plan.catch_point)
        if first and self.offset_prior is not None:
            slide_mm = self.offset_prior.predict(target_of(self.scenario),
                                                 self.features)
            self.palm_shift_m = -1e-3 * slide_mm
            self.report(f"offset prior: the catch slides {slide_mm:+.1f} mm "
                        "along the axis; the palm waits the other way")
        if self.palm_shift_m:
            plan = shifted_along_axis(plan, self.palm_shift_m, self.ik) or plan
        self.plan = plan
        self.raw, self.prediction = predict(self.model, self.features)
        self.network_cell = nearest_cell(*self.prediction)
        first = self.planner.first_cell(self.obj, plan, self.network_cell)
        self.start_chooser = self.planner.name
        if self.rehearse and self.rehearsal is None:
            later = later_moments(self.scenario, self.obj, self.ik,
                                  self.flight, self.palm_shift_m)
            self.rehearsal = (
                Rehearsal.from_dict(self.rehearsed, plan, self.ik, later)
                if self.rehearsed is not None
                else rehearse(self.scenario, self.obj, self.ik, plan,
                              modes=MODES, shifts=PALM_SHIFTS_M, margin=True,
                              later=later))
            rehearsed = [(f"palm {mm:+g} mm along the axis", by_mode)
                         for mm, by_mode in self.rehearsal.places.items()]
            rehearsed += [(f"catch point {k}", by_mode)
                          for k, by_mode in self.rehearsal.moments.items()]
            for where, by_mode in rehearsed:
                counts = ", ".join(f"{mode} {n}"
                                   for mode, n in by_mode.items())
                self.report(f"rehearsed ({where}): lattice cells in the "
                            f"target grasp of "
                            f"{self.rehearsal.in_target.size}: {counts}")
            for c in self.rehearsal.margin:
                moment = c.get("catch_point", 1)
                at = f", catch point {moment}" if moment > 1 else ""
                self.report(f"margin: {c['mode']} at {c['palm_shift_mm']:+g}"
                            f" mm{at}, cell {tuple(c['cell'])}: lands in "
                            f"{len(c['landed_in'])} of {len(MARGIN_DRAWS)} "
                            f"draws ({', '.join(c['landed_in']) or 'none'})")
            if self.rehearsal.fragile():
                landed = self.rehearsal.picked_draws()
                self.report(f"warning: the rehearsed catch is fragile: it "
                            f"lands in the target grasp in {len(landed)} of "
                            f"{len(MARGIN_DRAWS)} draws "
                            f"({', '.join(landed) or 'none'}; it needs half "
                            "the steps and 2 draws)")
            if self.rehearsal.cell is None:
                self.refuse_or_warn()
            else:
                first, self.start_chooser = self.rehearsal.cell, "rehearsal"
                self.catch_scenario = mode_scenario(self.scenario,
                                                    self.rehearsal.mode)
            if self.rehearsal.plan is not None:  # the palm moved
                plan = self.plan = self.rehearsal.plan
                self.palm_shift_m += self.rehearsal.shift_m
        start, reach = feasible_start(
            first, self.ik, plan,
            along_normal=follows(self.catch_scenario)[0])
        self.report(f"catch point at t = {plan.catch_point.t_s:.3f} s, "
                    f"v_catch {plan.catch_point.v_catch:.3f} m/s; network: "
                    f"h_catch {self.raw[0]:.3f} m, h_down {self.raw[1]:.3f} m;"
                    f" {self.start_chooser} -> start cell {start}")
        if not all(reach):
            self.report(f"the arm lowers the hand to h_down "
                        f"{H_DOWN_VALUES[reach.index(True)]:.2f} m at most "
                        f"here: the {10 * reach.count(False)} cells below "
                        "are skipped")
        prior = (None if self.prior is None
                 else object_prior(*self.prior, self.features))
        self.search = Search(start, prior, reach=reach)

    def refuse_or_warn(self) -> None:
        """Where the rehearsal lands no cell in the target grasp in any
        catch mode, palm place or catch moment: the static test
        (episode/static_hold.py, every closing in turn). When no closing
        holds the object at rest either, the target is refused before the
        catching throw (Unholdable: one line naming the object, the target,
        what the static test saw and what the rehearsal tried); else the
        throw goes on from the planner's cell, with a warning."""
        r = self.rehearsal
        tried = (f"the rehearsal lands none of its {r.in_target.size} "
                 f"lattice cells in the target grasp in {len(MODES)} catch "
                 f"modes at {len(r.places)} palm place(s) and "
                 f"{1 + len(r.moments)} catch moment(s)")
        test = static_hold(self.scenario, self.obj)
        if not test.success:
            raise Unholdable(f"{test.line()}; and {tried}: refused before "
                             "the throw, expected a target the hand can hold",
                             throws=self.throws)
        self.report(f"warning: {tried}; the static test holds it at rest "
                    f"({test.closing}): the throw goes on from "
                    f"{self.planner.name}'s cell")

    def catch(self) -> EpisodeResult | None:
        """A throw caught at the search's next cell with the plan's pose,
        recorded as an attempt. At release, the throw plans its catch when
        it lets the object go (throw 1's plan starts the search); when there
        is nothing to catch then, the throw counts and None is returned
        (NoCatchPoint when no throw had a plan yet)."""
        def plan_at_release(state, t):
            """The plan of this throw from its release (see run_episode)."""
            self.plan = plan_catch(self.scenario, self.obj, self.ik,
                                   flight_from_release(state, t, self.obj,
                                                       self.scenario))
            if self.palm_shift_m:
                self.plan = shifted_along_axis(self.plan, self.palm_shift_m,
                                               self.ik) or self.plan
            if self.search is None:
                self.report(f"planned at the release (t = {t:.3f} s)")
                self.start_search(self.plan)
            return (self.plan.X_WG, cell_parameters(self.search.next_cell),
                    plan_follow(self.scenario, self.obj,
                                self.plan.catch_point, self.plan.X_WG))

        correction = ReleaseCorrection()
        if not self.at_release:  # a watched or predicted plan
            cell = self.search.next_cell
            # The search's first cell, when it is the network's: the MLP
            # system in the episode's diagram predicts it, with this phase's
            # network; the later cells are given.
            from_network = cell == self.search.start == self.network_cell
            result = catch_planned(
                self.catch_scenario, self.obj, self.ik, self.plan,
                None if from_network else cell_parameters(cell),
                network=self.model if from_network else None,
                features=self.features if from_network else None,
                meshcat=self.meshcat, throw_number=self.throws + 1,
                record=correction)
            if (result.h_catch is not None and
                    (result.h_catch, result.h_down) != cell_parameters(cell)):
                raise RuntimeError(
                    f"the episode ran with (h_catch, h_down) = "
                    f"({result.h_catch}, {result.h_down}), expected cell "
                    f"{cell}'s {cell_parameters(cell)}")
            return self.attempted(result, correction)
        cell = None if self.search is None else self.search.next_cell
        try:
            result = run_episode(
                self.scenario, self.obj, ik=self.ik, X_WG=RigidTransform(),
                catch_parameters=(cell_parameters(cell) if cell is not None
                                  else (0.0, 0.0)),
                meshcat=self.meshcat, throw_number=self.throws + 1,
                at_release=plan_at_release)
        except InputError as e:
            self.throws += 1  # nothing to catch at the release: it counts
            self.unplanned_sim_s += release_time(self.scenario)
            self.report(f"throw {self.throws}: no reachable catch point at "
                        f"the release ({e})")
            if self.plan is None:  # nothing planned: no search to report
                raise NoCatchPoint(str(e), throws=self.throws,
                                   sim_time_s=self.unplanned_sim_s,
                                   wall_s=time.perf_counter() - self.t0
                                   ) from None
            return None
        return self.attempted(result, correction)

    def attempted(self, result: EpisodeResult,
                  correction: ReleaseCorrection) -> EpisodeResult:
        """Counts a catching throw at the search's next cell (at release,
        throw 1's search's first) and records it as an attempt."""
        self.throws += 1
        cell = self.search.next_cell
        h_catch, h_down = cell_parameters(cell)
        if self.on_episode is not None:
            self.on_episode(result)
        self.attempts.append(Attempt(
            throw=self.throws, cell=cell, h_catch=h_catch, h_down=h_down,
            outcome=result.outcome, sim_time_s=result.sim_time_s,
            wall_s=result.wall_s, message=result.message,
            ending=None if result.success else ending(result.summary()),
            release_correction=(
                correction.as_dict()
                if correction.how in ("shifted", "replanned", "kept")
                else None),
            achieved_grasp=result.achieved_grasp,
            grasp_error=result.grasp_error, plan=self.plan,
            chosen_by=(self.start_chooser if cell == self.search.start
                       else "search")))
        how = "" if result.success else f" ({self.attempts[-1].ending})"
        self.report(f"throw {self.throws}: cell {cell} (h_catch {h_catch:.2f}"
                    f" m, h_down {h_down:.2f} m): {result.outcome}{how}, "
                    f"{result.sim_time_s:.2f} s simulated, "
                    f"{result.wall_s:.1f} s wall")
        return result

    def same_miss(self, result: EpisodeResult) -> bool:
        """Under a grasp target, after a throw that missed it: whether the
        last MAX_SAME_MISSES throws all missed it for the same reason
        (reported in one line naming the object, the target and the
        reason)."""
        target = target_of(self.scenario)
        if target.kind == "any":
            return False
        reason = grasp.miss_reason(result.caught, result.grasp_error)
        last, count = self.misses
        self.misses = (reason, count + 1 if reason == last else 1)
        if reason is None or self.misses[1] < MAX_SAME_MISSES:
            return False
        self.report(f"target {target.label()}: stopped: the last "
                    f"{MAX_SAME_MISSES} throws all missed it the same way "
                    f"({reason.replace('_', ' ')}): no cell seems to reach it")
        return True

    def correct_offset(self, result: EpisodeResult) -> bool:
        """After a throw held in the target's orientation but at another
        offset along the axis: the palm waits that much the other way from
        the next throw on, at the same cell (the offset is where the palm
        waits, not the cell's doing). At most MAX_OFFSET_CORRECTIONS times
        in a run; False (nothing changed) otherwise, or when the moved
        palm is out of the arm's reach."""
        error = result.grasp_error or {}
        if (result.outcome != "wrong_grasp"
                or self.offset_corrections >= MAX_OFFSET_CORRECTIONS
                or error.get("offset_error_mm") is None
                or error.get("axis_error_deg") is None
                or error["axis_error_deg"] > grasp.AXIS_TOLERANCE_DEG
                or error.get("side_ok") is False):
            return False
        shift_m = -1e-3 * error["offset_error_mm"]
        plan = shifted_along_axis(self.plan, shift_m, self.ik)
        if plan is None:
            return False
        self.plan, self.palm_shift_m = plan, self.palm_shift_m + shift_m
        self.offset_corrections += 1
        self.report(f"held {error['offset_error_mm']:+.1f} mm from the "
                    f"target's offset: the palm waits {1e3 * shift_m:+.1f} mm "
                    "along the axis from the next throw on")
        return True

    def replan(self, result: EpisodeResult, max_throws) -> str | None:
        """First-throw mode, after the predicted flight's plan failed: the
        throw was still watched until the hand touched the object, so the
        catch is planned again from what was seen of its flight
        (`throw_catch.seen_flight`) or, if that shows no reachable catch
        point, from a watching throw; a new plan starts a new search.
        Returns why the phase stops ("max_throws", "no_catch_point"), or
        None when it goes on."""
        self.predicted = False
        try:
            seen = seen_flight(self.scenario, self.obj, result)
            plan = plan_watched(self.scenario, self.obj, self.ik, seen)
            self.replanned = {"after_throw": self.throws,
                              "from": "seen flight",
                              "seen_until_s": round(float(seen.logs.t[-1]), 4)}
            self.report(f"replanned from the flight seen until t = "
                        f"{seen.logs.t[-1]:.3f} s")
        except InputError as e:
            if max_throws is not None and self.throws >= max_throws:
                return "max_throws"
            self.report(f"the flight seen in throw {self.throws} shows no "
                        f"reachable catch point ({e}); throw "
                        f"{self.throws + 1} watches")
            self.replanned = {"after_throw": self.throws,
                              "from": "watching throw"}
            watched = self.watch()
            try:
                plan = plan_watched(self.scenario, self.obj, self.ik, watched)
            except InputError as e:  # the throws made are still counted
                self.report(str(e))
                self.replanned["error"] = str(e)
                return "no_catch_point"
        if not _same_pose(plan, self.plan):  # else the search goes on
            self.start_search(plan)
        return None

    def result(self, stopped: str, *, library_path, scenario_label: str,
               object_source: str, first_throw: bool) -> LearningResult:
        """The phase's result; after a catch, the learned entry, stored in
        the library at library_path (None: not stored)."""
        learned = None
        if stopped == "caught":
            last, plan = self.attempts[-1], self.plan
            learned = lib.LearnedEntry(
                object_source=object_source,
                object_features=dict(self.obj.features()),
                scenario=scenario_label,
                scenario_digest=scenario_digest(self.scenario),
                code_version=__version__,
                catch_point=plan.catch_point.as_dict(),
                p_WG=[float(x) for x in plan.X_WG.translation()],
                R_WG=plan.X_WG.rotation().matrix().tolist(),
                q_grasp=[float(x) for x in plan.q_grasp], side=plan.side,
                h_catch=last.h_catch, h_down=last.h_down,
                cell=list(last.cell), throws=self.throws,
                chosen_by=last.chosen_by,
                search="wavefront" if self.prior is None else "map-prior",
                mode=("at-release" if self.at_release else
                      "first-throw" if first_throw else "watch"))
            if library_path is not None:
                lib.store(library_path, self.obj.name, learned)
        return LearningResult(
            object=self.obj.name, success=learned is not None,
            stopped=stopped,
            throws=self.throws,
            sim_time_s=(0.0 if self.watched is None
                        else self.watched.sim_time_s)
            + sum(a.sim_time_s for a in self.attempts) + self.unplanned_sim_s,
            wall_s=time.perf_counter() - self.t0, watched=self.watched,
            plan=self.plan, features=self.features,
            raw_prediction=self.raw, prediction=self.prediction,
            start_cell=None if self.search is None else self.search.start,
            attempts=self.attempts, learned=learned,
            first_throw=first_throw, replanned=self.replanned,
            first_plan=(None if self.first_plan is self.plan
                        else self.first_plan),
            at_release=self.at_release,
            search="wavefront" if self.prior is None else "map-prior",
            planner=self.planner.name,
            rehearsal=(None if self.rehearsal is None
                       else self.rehearsal.as_dict()),
            target=target_of(self.scenario).as_dict(),
            start_grasp=start_grasp(self.scenario, self.obj).as_dict())


def _same_pose(a: CatchPlan, b: CatchPlan) -> bool:
    """Whether two plans put the palm in the same place (within 1 mm and
    1 mrad) at the same moment."""
    return (abs(a.catch_point.t_s - b.catch_point.t_s) < 1e-9
            and a.X_WG.IsNearlyEqualTo(b.X_WG, 1e-3))


# ---- the applying phase -------------------------------------------------
def check_entry(scenario: Scenario, obj: ObjectSpec,
                entry: lib.LearnedEntry) -> None:
    """Refuses an entry learned under another scenario or for an object with
    other features: its parameters hold for the throw they were learned
    with."""
    digest = scenario_digest(scenario)
    if entry.scenario_digest != digest:
        raise InputError(
            f"object {obj.name}: learned with scenario {entry.scenario} "
            f"(digest {entry.scenario_digest}), the current scenario differs "
            f"(digest {digest}); run `regrasp-drake learn` with this scenario")
    if entry.object_features != obj.features():
        raise InputError(
            f"object {obj.name}: learned with features "
            f"{entry.object_features}, the object now has {obj.features()}; "
            f"run `regrasp-drake learn` on it again")


def apply_learned(scenario: Scenario, obj: ObjectSpec,
                  entry: lib.LearnedEntry, *, ik: ArmIk | None = None,
                  meshcat=None) -> EpisodeResult:
    """The applying phase: one throw, caught with the learned grasp pose and
    (h_catch, h_down)."""
    check_entry(scenario, obj, entry)
    return run_episode(scenario, obj, ik=ik or ArmIk(scenario.directives),
                       X_WG=entry.X_WG,
                       catch_parameters=(entry.h_catch, entry.h_down),
                       meshcat=meshcat)
