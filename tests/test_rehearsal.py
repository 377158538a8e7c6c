"""The first throw's rehearsal: what it simulates, and that it predicts
the throw it rehearses when nothing differs."""

import copy
import dataclasses as dc
import io
import unittest
from types import SimpleNamespace
from unittest import mock

import numpy as np
import torch

from regrasp_drake.episode.static_hold import StaticHold
from regrasp_drake.errors import InputError
from regrasp_drake.learning import learning_phase
from regrasp_drake.learning import rehearsal as rehearsal_module
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import Unholdable, learn
from regrasp_drake.learning.rehearsal import (
    LATTICE,
    LATTICE_COLUMNS,
    LATTICE_ROWS,
    MARGIN_CANDIDATES,
    MARGIN_DRAWS,
    MARGIN_NOISE_SEEDS,
    MODES,
    PALM_SHIFTS_M,
    Rehearsal,
    mode_scenario,
    rehearsal_scenario,
    rehearse,
)
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import Scenario, load_scenario, with_target
from regrasp_drake.world.objects import resolve_object


class RehearsalScenarioTest(unittest.TestCase):
    def test_no_noise_and_the_shipped_steps(self):
        judged = load_scenario(text="{landing_time_step_s: 0.0000625, "
                                    "target_catch_time_step_s: 0.00025, "
                                    "throw: "
                                    "{noise: {release_time_std_s: 0.002, "
                                    "seed: 3}}}")
        rehearsed = rehearsal_scenario(judged)
        shipped = Scenario()
        self.assertTrue(rehearsed.throw.noise.is_zero())
        self.assertEqual(
            (rehearsed.catch_time_step_s, rehearsed.target_catch_time_step_s,
             rehearsed.landing_time_step_s, rehearsed.plant_config.time_step),
            (shipped.catch_time_step_s, shipped.target_catch_time_step_s,
             shipped.landing_time_step_s, shipped.plant_config.time_step))
        # The judged scenario itself is left as it was.
        self.assertEqual(judged.throw.noise.release_time_std_s, 0.002)
        self.assertEqual(len(LATTICE), len(LATTICE_ROWS) * len(LATTICE_COLUMNS))

    def test_the_modes(self):
        scenario = load_scenario()
        for mode in MODES:
            catch = mode_scenario(scenario, mode).catch
            self.assertEqual((catch.follow_pitch, catch.follow_along),
                             (mode == "pitch", mode == "along"), mode)
        with self.assertRaisesRegex(ValueError, "mode: got 'spin'"):
            mode_scenario(scenario, "spin")


class PalmPlaceTest(unittest.TestCase):
    """Which of the palm's places a rehearsal picks (the lattices given: the
    simulation behind them is RehearsedFirstThrowTest's)."""

    @staticmethod
    def lattice(cells):
        in_target = np.zeros((len(LATTICE_ROWS), len(LATTICE_COLUMNS)), bool)
        for i, j in cells:
            in_target[i, j] = True
        return in_target

    def run_with(self, by_place, unreachable=()):
        """rehearse() with each place's lattice from `by_place` (shift in mm
        -> lattice cells in the target), moves in `unreachable` [mm]
        refused as out of the arm's reach; the plan is the shift itself."""
        def rehearse_modes(scenario, obj, ik, plan, modes):
            in_target = self.lattice(by_place[round(1e3 * plan, 3)])
            best = rehearsal_module.label_cell(in_target)
            return Rehearsal(in_target=in_target,
                             cell=None if best is None else (
                                 LATTICE_ROWS[best[0]],
                                 LATTICE_COLUMNS[best[1]]),
                             counts={"plain": int(in_target.sum())})

        def shifted(plan, shift_m, ik):
            moved = plan + shift_m
            return None if round(1e3 * shift_m, 3) in unreachable else moved

        with mock.patch.object(rehearsal_module, "_rehearse_modes",
                               rehearse_modes), \
                mock.patch.object(rehearsal_module, "shifted_along_axis",
                                  shifted):
            return rehearse(None, None, None, 0.0, modes=MODES,
                            shifts=PALM_SHIFTS_M)

    def test_the_plan_place_when_it_lands(self):
        picked = self.run_with({0.0: [(1, 1)], 4.0: [(2, 2), (2, 3)]})
        self.assertEqual((picked.shift_m, picked.plan), (0.0, None))
        self.assertEqual(list(picked.places), [0.0])  # nothing else tried
        self.assertEqual(picked.as_dict()["palm_shift_mm"], 0.0)

    def test_the_nearest_ring_that_lands_and_its_best_place(self):
        none = []
        block = [(i, j) for i in range(3) for j in range(3)]
        picked = self.run_with({0.0: none, 4.0: none, -4.0: none,
                                8.0: [(4, 4)], -8.0: block})
        self.assertEqual(picked.shift_m, -0.008)  # the more robust lattice
        self.assertEqual(picked.plan, -0.008)
        # (the lattice's edge is no miss: its corner is the farthest)
        self.assertEqual(picked.cell, (LATTICE_ROWS[0], LATTICE_COLUMNS[0]))
        self.assertEqual(list(picked.places), [0.0, 4.0, -4.0, 8.0, -8.0])
        self.assertEqual(picked.as_dict()["places"]["-8"], {"plain": 9})
        # A ring with a landing place ends the search.
        picked = self.run_with({0.0: none, 4.0: [(0, 0)], -4.0: none})
        self.assertEqual(picked.shift_m, 0.004)
        self.assertEqual(list(picked.places), [0.0, 4.0, -4.0])

    def test_no_place_lands_and_unreachable_moves(self):
        picked = self.run_with({0.0: [], -4.0: [], -8.0: []},
                               unreachable=(4.0, 8.0))
        self.assertIsNone(picked.cell)
        self.assertEqual((picked.shift_m, picked.plan), (0.0, None))
        self.assertEqual(list(picked.places), [0.0, -4.0, -8.0])


    def test_a_recorded_pick_read_back(self):
        picked = self.run_with({0.0: [], 4.0: [], -4.0: [(1, 1), (1, 2)]})
        with mock.patch.object(rehearsal_module, "shifted_along_axis",
                               lambda plan, shift_m, ik: plan + shift_m):
            read = Rehearsal.from_dict(picked.as_dict(), 0.0, None)
        self.assertEqual(read.as_dict(), picked.as_dict())
        self.assertEqual((read.cell, read.mode, read.plan),
                         (picked.cell, picked.mode, -0.004))
        with mock.patch.object(rehearsal_module, "shifted_along_axis",
                               lambda plan, shift_m, ik: None):
            with self.assertRaisesRegex(ValueError, "palm_shift_mm: got -4"):
                Rehearsal.from_dict(picked.as_dict(), 0.0, None)


class MarginTest(unittest.TestCase):
    """The margin's candidates and draws (the landings given: the simulation
    behind them is RehearsedFirstThrowTest's)."""

    def setUp(self):
        lattice = PalmPlaceTest.lattice
        block = [(i, j) for i in range(3) for j in range(3)]
        self.plain = Rehearsal(in_target=lattice(block), cell=(1, 1),
                               mode="plain")
        self.pitch = Rehearsal(in_target=lattice([(4, 4)]), cell=(9, 13),
                               mode="pitch")
        self.place = dc.replace(self.plain, lattices=(self.plain, self.pitch),
                                counts={"plain": 9, "pitch": 1})
        self.draws = []

    def landings(self, lands):
        """A stand-in for rehearsal._landings: `lands(mode, draw, cell,
        plan)`."""
        def run(scenario, obj, ik, plan, cells):
            noise = scenario.throw.noise
            if noise.is_zero():
                # the half draw: the shipped steps halved, no noise
                self.assertEqual((scenario.target_catch_time_step_s,
                                  scenario.landing_time_step_s),
                                 (0.00025, 0.0000625))
                draw = "half"
            else:
                self.assertEqual((noise.release_time_std_s,
                                  noise.joint_velocity_std_rad_per_s),
                                 (0.002, 0.03))
                draw = f"noise {noise.seed}"
            mode = ("pitch" if scenario.catch.follow_pitch else
                    "along" if scenario.catch.follow_along else "plain")
            self.draws.append((mode, draw, tuple(cells)))
            return [lands(mode, draw, cell, plan) for cell in cells]
        return mock.patch.object(rehearsal_module, "_landings", run)

    def margin_pick(self) -> Rehearsal:
        """_with_margin at the one place and mode of `self.place`."""
        return rehearsal_module._with_margin(
            Scenario(), None, None, None,
            dc.replace(self.place, places={0.0: self.place.counts}),
            [self.place])

    def test_candidates(self):
        candidates = rehearsal_module._candidates(self.place, [self.place])
        self.assertEqual(len(candidates), MARGIN_CANDIDATES)
        # the pick first, then the block's most robust cells: its corner
        # (3 from a miss), then the cells 2 from one (row-major)
        self.assertEqual([(c.mode, c.cell) for c in candidates],
                         [("plain", (1, 1)), ("plain", (1, 4)),
                          ("plain", (3, 1)), ("plain", (3, 4))])

    def test_the_candidate_landing_in_most_draws(self):
        def lands(mode, draw, cell, plan):
            return cell == (3, 4) or (cell == (1, 1) and draw == "half")
        with self.landings(lands):
            picked = self.margin_pick()
        self.assertEqual((picked.mode, picked.cell), ("plain", (3, 4)))
        self.assertEqual(picked.picked_draws(), list(MARGIN_DRAWS))
        self.assertIsNone(self.plain.picked_draws())  # no margin rehearsed
        self.assertEqual(picked.counts, {"plain": 9, "pitch": 1})
        self.assertEqual([m["landed_in"] for m in picked.margin],
                         [["half"], [], [], list(MARGIN_DRAWS)])
        # one throw per draw for the four candidates of one place and mode
        self.assertEqual([d[1] for d in self.draws],
                         ["half"] + [f"noise {s}" for s in MARGIN_NOISE_SEEDS])
        self.assertNotIn(0, MARGIN_NOISE_SEEDS)  # the judged runs' seeds
        self.assertNotIn(1, MARGIN_NOISE_SEEDS)
        self.assertNotIn(2, MARGIN_NOISE_SEEDS)

    def test_a_tie_keeps_the_pick(self):
        with self.landings(lambda mode, draw, cell, plan: True):
            picked = self.margin_pick()
        self.assertEqual((picked.mode, picked.cell), ("plain", (1, 1)))

    def test_a_tie_goes_to_the_least_tilted(self):
        # Every candidate lands in every draw: the one whose rehearsed
        # landings rest least tilted (their mean), recorded with each.
        tilt = {(1, 1): 12.0, (1, 4): 3.0, (3, 1): 3.0, (3, 4): 9.0}

        def lands(mode, draw, cell, plan):
            return rehearsal_module.Landing(
                True, tilt[cell] + (1.0 if draw == "half" else 0.0))
        with self.landings(lands):
            picked = self.margin_pick()
        # (1, 4) and (3, 1) tie at 3.3°: the earlier
        self.assertEqual((picked.mode, picked.cell), ("plain", (1, 4)))
        self.assertEqual([m["tilt_deg"] for m in picked.margin],
                         [12.3, 3.3, 3.3, 9.3])
        self.assertEqual(picked.picked_draws(), list(MARGIN_DRAWS))

    def test_half_the_steps_first(self):
        # The pick lands in both noise draws, a rival at half the steps and
        # in one noise draw: the rival (the half step predicts a quarter
        # step's verdict, FINDINGS §14).
        def lands(mode, draw, cell, plan):
            return (draw != "half" if cell == (1, 1) else
                    draw in ("half", "noise 1001") if cell == (3, 4) else
                    False)
        with self.landings(lands):
            picked = self.margin_pick()
        self.assertEqual(picked.cell, (3, 4))
        self.assertFalse(picked.fragile())

    def widened(self, lands_at_4mm, elsewhere=("noise 1001",)):
        """_with_margin with PALM_SHIFTS_M where everything lands in the
        draws `elsewhere` only; the +4 mm place's lattice has the block and
        its (1, 1) lands everywhere if `lands_at_4mm`. The plan is the
        place's shift [m]."""
        def rehearse_modes(scenario, obj, ik, plan, modes):
            self.rehearsed_places.append(round(1e3 * plan, 3))
            return dc.replace(self.place if plan == 0.004 else
                              dc.replace(self.pitch, lattices=()),
                              counts={"plain": 1})

        def lands(mode, draw, cell, plan):
            return (lands_at_4mm and plan == 0.004 and cell == (1, 1)
                    or draw in elsewhere)

        self.rehearsed_places = []
        with self.landings(lands), \
                mock.patch.object(rehearsal_module, "_rehearse_modes",
                                  rehearse_modes), \
                mock.patch.object(rehearsal_module, "shifted_along_axis",
                                  lambda plan, shift_m, ik: plan + shift_m):
            return rehearsal_module._with_margin(
                Scenario(), None, None, 0.0,
                dc.replace(self.place, places={0.0: self.place.counts}),
                [self.place], shifts=PALM_SHIFTS_M, modes=MODES)

    def test_widened_where_nothing_holds(self):
        picked = self.widened(lands_at_4mm=True)
        # every other place rehearsed, the next candidates judged
        self.assertEqual(self.rehearsed_places, [4.0, -4.0, 8.0, -8.0])
        self.assertEqual(list(picked.places), [0.0, 4.0, -4.0, 8.0, -8.0])
        self.assertEqual([m["widened"] for m in picked.margin],
                         [False] * MARGIN_CANDIDATES
                         + [True] * MARGIN_CANDIDATES)
        self.assertEqual((picked.shift_m, picked.plan, picked.cell),
                         (0.004, 0.004, (1, 1)))
        self.assertEqual(picked.picked_draws(), list(MARGIN_DRAWS))
        self.assertFalse(picked.fragile())
        # Nothing lands at half the steps anywhere: the first pick, fragile.
        picked = self.widened(lands_at_4mm=False)
        self.assertEqual((picked.shift_m, picked.cell), (0.0, (1, 1)))
        self.assertEqual(picked.picked_draws(), ["noise 1001"])
        self.assertTrue(picked.fragile())
        # Two draws without half the steps: fragile, widened.
        picked = self.widened(lands_at_4mm=True,
                              elsewhere=("noise 1001", "noise 1002"))
        self.assertEqual(len(picked.margin), 2 * MARGIN_CANDIDATES)
        self.assertEqual((picked.shift_m, picked.cell), (0.004, (1, 1)))
        # Half the steps and a noise draw: it holds, nothing more rehearsed.
        picked = self.widened(lands_at_4mm=True,
                              elsewhere=("half", "noise 1002"))
        self.assertEqual(len(picked.margin), MARGIN_CANDIDATES)
        self.assertEqual(self.rehearsed_places, [])


class LaterMomentTest(unittest.TestCase):
    """Where no place has a candidate that holds, the flight's later catch
    moment (the lattices and landings given, as in MarginTest)."""

    LATER = SimpleNamespace(moment=2)  # the plan at the second moment

    def run_with(self, lattices, lands):
        """rehearse() with margin, PALM_SHIFTS_M and the later moment:
        `lattices` maps a place (its shift in mm, the plan being the shift
        itself) or "later" to its cells in the target in every mode;
        lands(place, draw, cell) says where the margin's draws land."""
        def place(plan):
            return "later" if plan is self.LATER else round(1e3 * plan, 3)

        def rehearse_modes(scenario, obj, ik, plan, modes):
            self.rehearsed.append(place(plan))
            in_target = PalmPlaceTest.lattice(lattices.get(place(plan), []))
            best = rehearsal_module.label_cell(in_target)
            only = Rehearsal(in_target=in_target, mode="plain",
                             cell=None if best is None else (
                                 LATTICE_ROWS[best[0]],
                                 LATTICE_COLUMNS[best[1]]))
            return dc.replace(only, counts={"plain": int(in_target.sum())},
                              lattices=(only,))

        def landings(scenario, obj, ik, plan, cells):
            noise = scenario.throw.noise
            draw = "half" if noise.is_zero() else f"noise {noise.seed}"
            return [lands(place(plan), draw, cell) for cell in cells]

        self.rehearsed = []
        with mock.patch.object(rehearsal_module, "_rehearse_modes",
                               rehearse_modes), \
                mock.patch.object(rehearsal_module, "_landings", landings), \
                mock.patch.object(rehearsal_module, "shifted_along_axis",
                                  lambda plan, shift_m, ik: plan + shift_m):
            return rehearse(Scenario(), None, None, 0.0, modes=MODES,
                            shifts=PALM_SHIFTS_M, margin=True,
                            later=[self.LATER])

    BLOCK = [(i, j) for i in range(3) for j in range(3)]

    def test_no_cell_at_any_place(self):
        picked = self.run_with({"later": self.BLOCK},
                               lambda place, draw, cell: place == "later")
        self.assertEqual(self.rehearsed,
                         [0.0, 4.0, -4.0, 8.0, -8.0, "later"])
        self.assertEqual((picked.moment, picked.plan, picked.shift_m),
                         (2, self.LATER, 0.0))
        self.assertEqual(picked.picked_draws(), list(MARGIN_DRAWS))
        d = picked.as_dict()
        self.assertEqual((d["catch_point"], d["catch_points"], d["by_mode"]),
                         (2, {"2": {"plain": 9}}, {"plain": 9}))
        self.assertEqual({m["catch_point"] for m in d["margin"]}, {2})
        # Read back: the later moment's plan, from the plans given.
        read = Rehearsal.from_dict(d, 0.0, None, later=[self.LATER])
        self.assertEqual((read.plan, read.moment, read.cell),
                         (self.LATER, 2, picked.cell))
        self.assertEqual(read.as_dict(), d)
        with self.assertRaisesRegex(ValueError, "catch_point: got 2"):
            Rehearsal.from_dict(d, 0.0, None)

    def test_after_the_places(self):
        # A cell at the plan's place that lands in one noise draw only:
        # every place, then the later moment, whose block holds.
        picked = self.run_with(
            {0.0: [(1, 1)], "later": self.BLOCK},
            lambda place, draw, cell: (place == "later"
                                       or draw == "noise 1001"))
        self.assertEqual(self.rehearsed,
                         [0.0, 4.0, -4.0, 8.0, -8.0, "later"])
        self.assertEqual(picked.moment, 2)
        self.assertFalse(picked.fragile())
        self.assertEqual([m.get("catch_point", 1) for m in picked.margin],
                         [1, 2, 2, 2, 2])
        # A candidate at the plan's place that holds: no later moment.
        picked = self.run_with(
            {0.0: [(1, 1)], "later": self.BLOCK},
            lambda place, draw, cell: True)
        self.assertEqual(self.rehearsed, [0.0])
        self.assertEqual((picked.moment, picked.as_dict()["catch_points"]),
                         (1, {}))


# A smaller lattice and fewer margin candidates under test, around the
# cells where table1-row2 lands in the flip (studies/landing_step rows):
# the same code, a third of the catches.
SMALL_LATTICE = dict(LATTICE_ROWS=(5, 7, 9), LATTICE_COLUMNS=(4, 7, 10),
                     LATTICE=[(i, j) for i in (5, 7, 9) for j in (4, 7, 10)],
                     MARGIN_CANDIDATES=2)


class RehearsedFirstThrowTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.scenario = with_target(load_scenario(), Target("flip"))
        cls.obj = resolve_object(name="table1-row2")
        cls.model = load_weights(MODELS_DIR / cls.scenario.catch.weights)[0]
        cls.predictor = FlightPredictor.load(
            MODELS_DIR / "flight_predictor.json")
        with mock.patch.multiple(rehearsal_module, **SMALL_LATTICE):
            cls.result = cls.learn(rehearse=True)

    @classmethod
    def learn(cls, progress=None, **kwargs):
        return learn(cls.scenario, cls.obj, cls.model, ik=ArmIk(),
                     max_throws=1, progress=progress,
                     flight_predictor=cls.predictor, **kwargs)

    def test_the_rehearsal_predicts_the_throw_it_rehearses(self):
        # Without noise at the shipped steps the throw is what the
        # rehearsal simulated: its cell lands in the target grasp.
        rehearsal = self.result.rehearsal
        self.assertIsNotNone(rehearsal["cell"])
        # Every catch mode rehearsed; the lattice is the picked mode's.
        self.assertEqual(set(rehearsal["by_mode"]), set(MODES))
        self.assertEqual(rehearsal["in_target"],
                         rehearsal["by_mode"][rehearsal["mode"]])
        i, j = rehearsal["cell"]
        rows, columns = (SMALL_LATTICE["LATTICE_ROWS"],
                         SMALL_LATTICE["LATTICE_COLUMNS"])
        self.assertEqual(rehearsal["lattice"][rows.index(i)]
                         [columns.index(j)], 1)
        # The pick and its rival judged in every draw.
        self.assertEqual(len(rehearsal["margin"]), 2)
        first = self.result.attempts[0]
        self.assertEqual((first.chosen_by, tuple(first.cell)),
                         ("rehearsal", (i, j)))
        self.assertTrue(self.result.success, first.grasp_error)

    def test_a_recorded_rehearsal_replays_the_same_throw(self):
        # (benchmarks/regrasp_targets.py --rehearsal-from) Nothing is
        # rehearsed again: the recorded pick alone gives the same catch.
        with mock.patch.object(rehearsal_module, "_rehearse",
                               side_effect=AssertionError("rehearsed")):
            replayed = self.learn(rehearse=True,
                                  rehearsed=self.result.rehearsal)
        self.assertEqual(replayed.rehearsal, self.result.rehearsal)
        a, b = replayed.attempts[0], self.result.attempts[0]
        self.assertEqual((a.chosen_by, a.cell, a.outcome, a.grasp_error),
                         (b.chosen_by, b.cell, b.outcome, b.grasp_error))

    def test_refused_where_neither_the_rehearsal_nor_a_closing_holds(self):
        # A recorded rehearsal that landed no cell anywhere: the static test
        # decides, before any throw (the catching throws stubbed to fail).
        d = copy.deepcopy(self.result.rehearsal)
        d |= {"cell": None, "margin": [], "palm_shift_mm": 0.0,
              "places": {"+0": {}, "+4": {}, "-4": {}}, "catch_points": {
                  "2": {}}}

        class Thrown(Exception):
            pass

        def test(success):
            return StaticHold(object=self.obj.name, target=Target("flip"),
                              rest={"offset_mm": 0.4, "tilt_deg": 3.0},
                              closed=None, held=success, success=success,
                              reason=None if success else "dropped",
                              grasp_error=None, closing="open, centred",
                              tried=10)
        with mock.patch.object(learning_phase, "catch_planned",
                               side_effect=Thrown), \
                mock.patch.object(learning_phase, "static_hold",
                                  return_value=test(False)):
            with self.assertRaises(Unholdable) as e:
                self.learn(rehearse=True, rehearsed=d)
        self.assertEqual(e.exception.throws, 0)
        self.assertRegex(str(e.exception), (
            r"^object table1-row2, target flip.*: no closing of the hand "
            r"holds it at rest \(10 tried; .*\); and the rehearsal lands "
            r"none of its 9 lattice cells in the target grasp in 3 catch "
            r"modes at 3 palm place\(s\) and 2 catch moment\(s\): refused "
            r"before the throw"))
        # Held at rest: a warning, and the throw goes on.
        progress = io.StringIO()
        with mock.patch.object(learning_phase, "catch_planned",
                               side_effect=Thrown), \
                mock.patch.object(learning_phase, "static_hold",
                                  return_value=test(True)):
            with self.assertRaises(Thrown):
                self.learn(rehearse=True, rehearsed=d, progress=progress)
        self.assertIn("warning: the rehearsal lands none of its 9 lattice "
                      "cells", progress.getvalue())
        self.assertIn("the static test holds it at rest (open, centred)",
                      progress.getvalue())

    def test_a_recorded_rehearsal_needs_rehearse(self):
        with self.assertRaisesRegex(InputError, "rehearsed: .*rehearse=True"):
            self.learn(rehearsed=self.result.rehearsal)


if __name__ == "__main__":
    unittest.main()
