"""Rehearsing a first throw's catch in simulation before the throw: a plan
judged by its margin, not by one guess.

Before the first catching throw (the flight predicted, no watching throw),
the catch planned from the predicted flight is simulated at a lattice of
the parameter space's cells (`LATTICE`, 25 of the 150: every other h_catch,
every third h_down), all forked from one simulated throw
(episode/branching.py), under what the planner knows: the throw without
release noise, at the shipped plant steps (`rehearsal_scenario`), the palm
corrected at the rehearsed release as the throw corrects it. The cell
the throw then uses is the lattice's most robust one in the target grasp
(labels.label_cell on the lattice: the farthest from a miss, so that a
release off by the noise, or a landing another step resolves otherwise,
stays inside the cells that land in the target); with none, the planner's.

With `modes`, the lattice is rehearsed once per catch mode (`MODES`:
"plain", the palm waiting; "pitch", the palm turning with the object's
pitch; "along", the palm moving with the object along the palm and
lowered along its normal; planning/follow.py), and the throw takes the
mode whose lattice has the most robust cell in the target grasp
(labels.robustness; a tie goes to the one with more such cells, then to
"plain", then to the first in MODES): the follow lands some pairs the
waiting palm tilts and tips others off the palm's edge
(studies/landing_step/FINDINGS.md §7), which the rehearsal tells apart
before the throw.

With `shifts` (PALM_SHIFTS_M), where no mode's lattice has a cell in the
target grasp at the plan's place, the palm's place is rehearsed again,
moved along the object's axis (throw_catch.shifted_along_axis), the
nearest places first: the first ring of places where some lattice has a
cell in the target gives the place, mode and cell, scored as above (a tie
goes to the place listed first). A moved palm moves where the object
comes to rest in the hand, so the moves stay within the target's offset
window (planning/grasp.OFFSET_TOLERANCE_MM) and the rehearsal judges them
against it like any catch.

With `margin`, the pick is then judged as a probability (issue 60 item
3): the MARGIN_CANDIDATES best cells over every lattice rehearsed (the
pick above first, then by each cell's robustness, its lattice's count of
cells in the target and the waiting palm) are rehearsed again in
MARGIN_DRAWS: at half the shipped catch and landing steps, and under
release noise at the shipped level (ThrowNoise.at_level(1)) with the
rehearsal's own seeds. The throw takes the candidate that lands in the
target grasp at half the steps and, among those, in the most draws (a tie:
the one whose rehearsed landings rest least tilted, their mean to 0.1°,
then the earlier candidate: over 60 pairs it changed 24 picks, kept every
hit and took the median tilt at a finer step from 9.7° to 9.05°,
studies/landing_step/FINDINGS.md §18). Judged at a step twice finer than
the half draw, 47 of the 48 picks that landed at half the steps landed, 3
of the 8 that did not (studies/landing_step/FINDINGS.md §14).

With `shifts` too, where no candidate holds (lands at half the steps and in
2 draws or more), the search widens: every place of `shifts` not rehearsed
yet is rehearsed, and the MARGIN_CANDIDATES best cells not judged yet, over
every lattice, are judged in the same draws (§15: it found a candidate that
holds in 6 of the 8 pairs with none; widening also where none lands in all
3 draws found none in 5 pairs tried, at 7-13 minutes each). With `later`
too, where no place has a cell in the target, or none of their candidates
holds, the flight's later catch moments (`later_moments`) are rehearsed in
every mode at their own place, and their best cells judged: the throw may
then catch the object at another moment of its fall.

The rehearsal never sees what judges it: a run judged under release noise
has its own seeds (benchmarks/regrasp_targets.py --noise-level: the trial
numbers, never MARGIN_NOISE_SEEDS), and one judged at a finer step
(--scenario-text) a step finer than the rehearsal's half: the half draw
runs at 0.0625 ms landing and 0.25 ms target catch, so a judge finer than
that needs plant_config.time_step 0.125 ms (FINDINGS §14).
"""

import copy
import dataclasses as dc
import math
import statistics

import numpy as np

from regrasp_drake.episode.branching import run_cells
from regrasp_drake.episode.episode import Episode, ThrowCache
from regrasp_drake.errors import InputError
from regrasp_drake.learning.labels import label_cell, robustness
from regrasp_drake.parameter_space import (
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    cell_parameters,
)
from regrasp_drake.planning.follow import plan_follow
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import Scenario, ThrowNoise
from regrasp_drake.throw_catch import (
    CatchPlan,
    plan_at_moment,
    release_correction,
    shifted_along_axis,
    with_release,
)
from regrasp_drake.world.object_model import ObjectSpec

# The lattice's rows (h_catch indices) and columns (h_down indices).
LATTICE_ROWS = tuple(range(1, len(H_CATCH_VALUES), 2))   # 0.08 ... 0.40 m
LATTICE_COLUMNS = tuple(range(1, len(H_DOWN_VALUES), 3))  # -0.13 ... -0.01 m
LATTICE = [(i, j) for i in LATTICE_ROWS for j in LATTICE_COLUMNS]
# The catch modes a rehearsal may compare: the palm waiting, turning with
# the object's pitch (catch.follow_pitch), or moving with it along the palm
# (catch.follow_along).
MODES = ("plain", "pitch", "along")
# The palm's places rehearsed when no mode lands at the plan's: moved along
# the object's axis by these [m], ring by ring (the nearest ring first):
# of the 14 pairs of 60 without a cell at the plan's place, 10 have one
# 4 mm from it; the 8 mm ring found none for the other 4
# (studies/landing_step/FINDINGS.md §12).
PALM_SHIFTS_M = ((0.004, -0.004), (0.008, -0.008))
# The margin's candidates, and the draws each is rehearsed again in besides
# the rehearsal's own: "half" (the shipped catch and landing steps halved)
# and one release-noise draw per seed at the shipped level. The judged
# runs' noise seeds are their trial numbers (0, 1, 2, ...): these are not.
MARGIN_CANDIDATES = 4
MARGIN_NOISE_SEEDS = (1001, 1002)
MARGIN_DRAWS = ("half",) + tuple(f"noise {seed}" for seed in MARGIN_NOISE_SEEDS)
# The later catch moments rehearsed where no place holds (`later_moments`):
# at the second moment the watched flight's 150-cell grid lands 30 and 66
# cells of the mallets' flip +30, none at the first; rehearsed there, both
# land in the target at a finer step (studies/landing_step/FINDINGS.md
# §§16-17).
LATER_MOMENTS = 1


@dc.dataclass(frozen=True)
class Landing:
    """A rehearsed catch: whether it lands in the target grasp (its truth
    value) and the tilt it rests at, [°] (None: not held)."""
    in_target: bool
    tilt_deg: float | None = None

    def __bool__(self) -> bool:
        return self.in_target


@dc.dataclass(frozen=True)
class Rehearsal:
    """A rehearsal's lattice map (rows × columns, True: in the target
    grasp) in the catch mode it picks, the cell it picks (None: no lattice
    cell lands in the target grasp), and each mode's count of lattice cells
    in the target."""
    in_target: np.ndarray
    cell: tuple[int, int] | None
    mode: str = "plain"
    counts: dict = dc.field(default_factory=dict)
    # The palm's move along the object's axis from the plan's place [m],
    # the plan so moved (None: not moved), and each place rehearsed
    # (shift in mm -> each mode's count of lattice cells in the target).
    shift_m: float = 0.0
    plan: CatchPlan | None = None
    places: dict = dc.field(default_factory=dict)
    # Every mode's lattice at this place (Rehearsals), and the margin's
    # candidates with the draws each landed in (dicts; see `rehearse`).
    lattices: tuple = ()
    margin: list = dc.field(default_factory=list)
    # The catch moment rehearsed (the plan's `moment`: 1, the plan's own;
    # a later one's plan is `plan`), and each later moment rehearsed
    # (moment -> each mode's count of lattice cells in the target).
    moment: int = 1
    moments: dict = dc.field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"cell": None if self.cell is None else list(self.cell),
                "mode": self.mode,
                "in_target": int(self.in_target.sum()),
                "of": int(self.in_target.size),
                "by_mode": dict(self.counts),
                "lattice": self.in_target.astype(int).tolist(),
                "palm_shift_mm": round(1e3 * self.shift_m, 3),
                "places": {f"{mm:+g}": dict(counts)
                           for mm, counts in self.places.items()},
                "catch_point": self.moment,
                "catch_points": {str(k): dict(counts)
                                 for k, counts in self.moments.items()},
                "margin": list(self.margin)}

    @classmethod
    def from_dict(cls, d: dict, plan: CatchPlan, ik: ArmIk,
                  later=()) -> "Rehearsal":
        """The rehearsal `as_dict` recorded for the catch under `plan`
        (`later`: the plans at the flight's later catch moments, as given
        to `rehearse`), its palm's place moved again (shifted_along_axis)
        from the plan of the moment it picked."""
        moment = int(d.get("catch_point", 1))
        base = plan
        if moment > 1:
            base = next((p for p in later if p.moment == moment), None)
            if base is None:
                raise ValueError(f"catch_point: got {moment}, expected one "
                                 "of the flight's catch moments, 1 to "
                                 f"{1 + len(later)}")
        shift_m = 1e-3 * float(d["palm_shift_mm"])
        moved = None if moment == 1 else base
        if shift_m:
            moved = shifted_along_axis(base, shift_m, ik)
            if moved is None:
                raise ValueError(f"palm_shift_mm: got {d['palm_shift_mm']}, "
                                 "expected a move the arm reaches from "
                                 "this plan")
        return cls(in_target=np.array(d["lattice"], dtype=bool),
                   cell=None if d["cell"] is None else tuple(d["cell"]),
                   mode=d["mode"], counts=dict(d["by_mode"]),
                   shift_m=shift_m, plan=moved,
                   places={float(mm): dict(counts)
                           for mm, counts in d["places"].items()},
                   margin=list(d["margin"]), moment=moment,
                   moments={int(k): dict(counts) for k, counts
                            in d.get("catch_points", {}).items()})

    def fragile(self) -> bool:
        """Whether the pick's margin was rehearsed and it did not land in
        the target grasp at half the steps or in fewer than 2 of
        MARGIN_DRAWS (judged at a step finer than the draws, 3 of 8 such
        picks landed: studies/landing_step/FINDINGS.md §§13-14)."""
        landed = self.picked_draws()
        return landed is not None and not _holds(landed)

    def picked_draws(self) -> list[str] | None:
        """The MARGIN_DRAWS the picked candidate landed in (None: no margin
        rehearsed)."""
        for c in self.margin:
            if (c["mode"], c["palm_shift_mm"], tuple(c["cell"]),
                    c.get("catch_point", 1)) == (
                    self.mode, round(1e3 * self.shift_m, 3), self.cell,
                    self.moment):
                return list(c["landed_in"])
        return None

    def score(self) -> tuple:
        """What a rehearsal's pick is ranked by, highest first: its lattice's
        largest robustness (labels.robustness), its count of cells in the
        target grasp, and whether the palm waits ("plain")."""
        return (int(robustness(self.in_target).max()),
                int(self.in_target.sum()), self.mode == "plain")


def later_moments(scenario: Scenario, obj: ObjectSpec, ik: ArmIk, flight,
                  shift_m: float = 0.0) -> list[CatchPlan]:
    """The plans at `flight`'s catch moments 2 to 1 + LATER_MOMENTS (the
    ones it has; throw_catch.plan_at_moment) with its release kept
    (`with_release`), each palm moved `shift_m` along the object's axis
    where the arm reaches it: what `rehearse` takes as `later`."""
    plans = []
    for moment in range(2, 2 + LATER_MOMENTS):
        try:
            plan = with_release(plan_at_moment(scenario, obj, ik, flight,
                                               moment), scenario, flight)
        except InputError:
            break
        if shift_m:
            plan = shifted_along_axis(plan, shift_m, ik) or plan
        plans.append(plan)
    return plans


def mode_scenario(scenario: Scenario, mode: str) -> Scenario:
    """`scenario` with the catch mode `mode` (one of MODES)."""
    if mode not in MODES:
        raise ValueError(f"mode: got {mode!r}, expected one of {MODES}")
    out = copy.deepcopy(scenario)
    out.catch.follow_pitch = mode == "pitch"
    out.catch.follow_along = mode == "along"
    return out


def rehearsal_scenario(scenario: Scenario) -> Scenario:
    """What the rehearsal simulates: `scenario` without release noise and at
    the shipped plant steps (the throw's, the catch's and the landing's)."""
    shipped = Scenario()
    out = copy.deepcopy(scenario)
    out.throw.noise = ThrowNoise(seed=scenario.throw.noise.seed)
    out.plant_config.time_step = shipped.plant_config.time_step
    for name in ("catch_time_step_s", "target_catch_time_step_s",
                 "landing_time_step_s", "landing_settle_s"):
        setattr(out, name, getattr(shipped, name))
    return out


def rehearse(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
             plan: CatchPlan, modes=None, shifts=(),
             margin: bool = False, later=()) -> Rehearsal:
    """The catch under `plan` rehearsed at every LATTICE cell (see the
    module's docstring), its palm corrected at the rehearsed throw's release
    as the throw will correct it (throw_catch.release_correction); one
    process. `modes`: the catch modes compared (a subset of MODES; None:
    the scenario's own only). `shifts`: rings of the palm's moves along
    the object's axis [m] (PALM_SHIFTS_M) rehearsed when no mode lands in
    the target grasp at the plan's place; a move the arm does not reach is
    skipped. `margin`: the pick judged again with its rivals in
    MARGIN_DRAWS (see the module's docstring). `later`: with `margin`, the
    plans at the flight's later catch moments (throw_catch.plan_at_moment,
    LATER_MOMENTS of them), rehearsed at their own place where no place
    of `shifts` has a candidate that holds."""
    best = _rehearse_modes(scenario, obj, ik, plan, modes)
    places = {0.0: best.counts}
    rehearsed = [best]
    for ring in shifts if best.cell is None else ():
        found = []
        for shift_m in ring:
            moved = shifted_along_axis(plan, shift_m, ik)
            if moved is None:
                continue
            rehearsal = dc.replace(
                _rehearse_modes(scenario, obj, ik, moved, modes),
                shift_m=shift_m, plan=moved)
            places[round(1e3 * shift_m, 3)] = rehearsal.counts
            rehearsed.append(rehearsal)
            if rehearsal.cell is not None:
                found.append(rehearsal)
        if found:
            best = max(found, key=Rehearsal.score)
            break
    best = dc.replace(best, places=places)
    if margin and best.cell is None and later:
        # No cell at any place: the later catch moments, in the same modes.
        moments = _rehearse_moments(scenario, obj, ik, later, modes)
        rehearsed += moments
        found = [m for m in moments if m.cell is not None]
        best = dc.replace(max(found, key=Rehearsal.score) if found else best,
                          places=places, moments={
                              m.moment: m.counts for m in moments})
        later = ()
    if not margin or best.cell is None:
        return best
    return _with_margin(scenario, obj, ik, plan, best, rehearsed,
                        shifts=shifts, modes=modes, later=later)


def _rehearse_moments(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                      later, modes) -> list[Rehearsal]:
    """`_rehearse_modes` at each of the `later` catch moments' plans, at the
    moment's own place."""
    return [dc.replace(_rehearse_modes(scenario, obj, ik, p, modes),
                       plan=p, moment=p.moment) for p in later]


def _holds(landed: list[str]) -> bool:
    """Whether a candidate that landed in `landed` (of MARGIN_DRAWS) is
    not fragile: it landed at half the steps and in 2 draws or more."""
    return "half" in landed and len(landed) >= 2


def _key(c: Rehearsal) -> tuple:
    """A candidate's catch mode, place [mm], cell and catch moment."""
    return (c.mode, round(1e3 * c.shift_m, 3), c.cell, c.moment)


def _candidates(best: Rehearsal, rehearsed, judged=()) -> list[Rehearsal]:
    """Up to MARGIN_CANDIDATES picks (each a Rehearsal of its place and
    mode, with its cell) not among `judged`: `best` first (unless judged
    is given), then the cells in the target of every lattice in
    `rehearsed` (each place's `lattices`, or the place's pick alone),
    ranked by the cell's robustness, its lattice's count of cells in the
    target, the waiting palm, the nearer place and the earlier moment."""
    ranked = []
    for place in rehearsed:
        for lattice in place.lattices or (place,):
            lattice = dc.replace(lattice, shift_m=place.shift_m,
                                 plan=place.plan, moment=place.moment,
                                 lattices=())
            r = robustness(lattice.in_target)
            for i, j in np.argwhere(r > 0):
                cell = (LATTICE_ROWS[i], LATTICE_COLUMNS[j])
                key = (int(r[i, j]), int(lattice.in_target.sum()),
                       lattice.mode == "plain", -abs(place.shift_m),
                       -place.moment)
                ranked.append((key, dc.replace(lattice, cell=cell)))
    ranked.sort(key=lambda entry: entry[0], reverse=True)  # stable
    out = [] if judged else [dc.replace(best, lattices=())]
    seen = {_key(c) for c in list(judged) + out}
    for _, candidate in ranked:
        if len(out) == MARGIN_CANDIDATES:
            break
        if _key(candidate) not in seen:
            seen.add(_key(candidate))
            out.append(candidate)
    return out


def _draw_scenario(scenario: Scenario, mode: str, draw: str) -> Scenario:
    """The rehearsal's scenario in catch mode `mode` ("own": the scenario's
    own) for one of MARGIN_DRAWS."""
    out = rehearsal_scenario(scenario if mode == "own"
                             else mode_scenario(scenario, mode))
    if draw == "half":
        for name in ("catch_time_step_s", "target_catch_time_step_s",
                     "landing_time_step_s"):
            if getattr(out, name) is not None:
                setattr(out, name, 0.5 * getattr(out, name))
    else:
        out.throw.noise = ThrowNoise.at_level(
            1.0, seed=int(draw.removeprefix("noise ")))
    return out


def _with_margin(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                 plan: CatchPlan, best: Rehearsal, rehearsed, shifts=(),
                 modes=None, later=()) -> Rehearsal:
    """`best` or a rival (`_candidates`) with more margin in MARGIN_DRAWS
    (see the module's docstring); where none holds (`_holds`), the places
    of `shifts` not rehearsed yet are rehearsed in `modes` and the next
    candidates judged too; where still none holds, the `later` catch
    moments are, and their candidates judged. Its `margin` lists every
    candidate's draws ("widened": judged after the first round;
    "catch_point": its moment), `places` every place's counts, `moments`
    every later moment's."""
    places, moments = dict(best.places), dict(best.moments)
    candidates = _candidates(best, rehearsed)
    landed = _judge(scenario, obj, ik, plan, candidates)
    first_round = len(candidates)
    if shifts and not any(_holds(draws) for draws in landed):
        for ring in shifts:
            for shift_m in ring:
                mm = round(1e3 * shift_m, 3)
                moved = (None if mm in places
                         else shifted_along_axis(plan, shift_m, ik))
                if moved is None:
                    continue
                place = dc.replace(
                    _rehearse_modes(scenario, obj, ik, moved, modes),
                    shift_m=shift_m, plan=moved)
                places[mm] = place.counts
                rehearsed = list(rehearsed) + [place]
        more = _candidates(best, rehearsed, judged=candidates)
        landed += _judge(scenario, obj, ik, plan, more)
        candidates += more
    if later and not any(_holds(draws) for draws in landed):
        rehearsed = list(rehearsed) + _rehearse_moments(
            scenario, obj, ik, later, modes)
        moments |= {r.moment: r.counts for r in rehearsed if r.moment > 1}
        more = _candidates(best, rehearsed, judged=candidates)
        landed += _judge(scenario, obj, ik, plan, more)
        candidates += more
    tilts = [_mean_tilt(draws) for draws in landed]
    record = [{"mode": c.mode, "palm_shift_mm": round(1e3 * c.shift_m, 3),
               "cell": list(c.cell), "landed_in": list(landed[k]),
               "widened": k >= first_round}
              | ({"tilt_deg": tilts[k]} if math.isfinite(tilts[k]) else {})
              | ({"catch_point": c.moment} if c.moment > 1 else {})
              for k, c in enumerate(candidates)]
    pick = max(range(len(candidates)),
               key=lambda k: ("half" in landed[k], len(landed[k]), -tilts[k],
                              -k))
    picked = candidates[pick]
    return dc.replace(picked, places=places, margin=record, moments=moments,
                      counts=(moments[picked.moment] if picked.moment > 1
                              else places[round(1e3 * picked.shift_m, 3)]))


def _mean_tilt(draws: dict) -> float:
    """A candidate's mean rehearsed tilt over the draws it landed in
    (`_judge`'s draw -> tilt), [°] to 0.1; inf: none landed, or no tilt
    known."""
    tilts = [t for t in draws.values() if t is not None]
    return round(statistics.mean(tilts), 1) if tilts else math.inf


def _judge(scenario: Scenario, obj: ObjectSpec, ik: ArmIk, plan: CatchPlan,
           candidates) -> list[dict]:
    """The MARGIN_DRAWS each of `candidates` lands in the target grasp in,
    each with the tilt it rests at there (draw -> tilt [°], None: not
    known), in MARGIN_DRAWS's order (the candidates at one place and mode
    share each draw's throw)."""
    landed = [{} for _ in candidates]
    for draw in MARGIN_DRAWS:
        groups = {}
        for k, c in enumerate(candidates):
            groups.setdefault((c.mode, c.shift_m, c.moment), []).append(k)
        for (mode, _, _), members in groups.items():
            moved = candidates[members[0]].plan or plan
            hits = _landings(_draw_scenario(scenario, mode, draw), obj, ik,
                             moved, [candidates[k].cell for k in members])
            for k, hit in zip(members, hits):
                if hit:
                    landed[k][draw] = getattr(hit, "tilt_deg", None)
    return landed


def _rehearse_modes(scenario: Scenario, obj: ObjectSpec, ik: ArmIk,
                    plan: CatchPlan, modes) -> Rehearsal:
    """`rehearse` at the plan's place: each of `modes` (None: the
    scenario's own), the one whose pick scores highest (a tie: the first in
    `modes`)."""
    if not modes:
        only = _rehearse(rehearsal_scenario(scenario), obj, ik, plan)
        return dc.replace(only, mode="own",
                          counts={"own": int(only.in_target.sum())})
    rehearsals = {mode: dc.replace(_rehearse(rehearsal_scenario(
        mode_scenario(scenario, mode)), obj, ik, plan), mode=mode)
        for mode in modes}
    best = max(rehearsals.values(), key=Rehearsal.score)
    return dc.replace(best, counts={
        mode: int(r.in_target.sum()) for mode, r in rehearsals.items()},
        lattices=tuple(rehearsals.values()))


def _rehearse(rehearsed: Scenario, obj: ObjectSpec, ik: ArmIk,
              plan: CatchPlan) -> Rehearsal:
    """`rehearse` in the one catch mode of `rehearsed`."""
    in_target = np.array([bool(hit) for hit in _landings(
        rehearsed, obj, ik, plan, LATTICE)]).reshape(
            len(LATTICE_ROWS), len(LATTICE_COLUMNS))
    best = label_cell(in_target)
    cell = (None if best is None
            else (LATTICE_ROWS[best[0]], LATTICE_COLUMNS[best[1]]))
    return Rehearsal(in_target=in_target, cell=cell)


def _landings(rehearsed: Scenario, obj: ObjectSpec, ik: ArmIk,
              plan: CatchPlan, cells) -> list[Landing]:
    """The catch under `plan` at each of `cells` (`catches`): whether it
    lands in the target grasp, and its tilt."""
    return [Landing(bool(r.success), (r.achieved_grasp or {}).get("tilt_deg"))
            for r in catches(rehearsed, obj, ik, plan, cells)]


def catches(rehearsed: Scenario, obj: ObjectSpec, ik: ArmIk,
            plan: CatchPlan, cells) -> list:
    """The catch under `plan` at each of `cells` (EpisodeResults without
    logs), all forked from one throw simulated under `rehearsed`, the palm
    corrected at its release as the throw corrects it."""
    throws = ThrowCache(size=1)
    episode = Episode(rehearsed, obj, ik=ik, X_WG=plan.X_WG,
                      catch_parameters=(0.0, 0.0), throws=throws)
    episode.start()
    release = episode.advance_to_release()
    corrected = release_correction(rehearsed, obj, ik, plan, (0.0, 0.0))(
        release.object_state, release.t)
    if corrected is None:
        X_WG = plan.X_WG
        follow = plan_follow(rehearsed, obj, plan.catch_point, X_WG)
    else:
        X_WG, _, follow = corrected
    return run_cells(rehearsed, obj, ik=ik, X_WG=X_WG,
                     parameters=[cell_parameters(c) for c in cells],
                     workers=1, throws=throws, follow=follow)
