"""The searches over the 150 cells: the paper's wavefront order (Figs. 7-8)
and the map-prior search, alone, in the learning phase and on the command
line, and the search object the learning phase loops over, fed outcomes by
hand. One short learning run (three throws)."""

import contextlib
import io
import itertools
import json
import tempfile
import unittest
from pathlib import Path

import numpy as np

from regrasp_drake.cli import make_parser
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset_files import object_of
from regrasp_drake.learning.search import (
    FEATURE_SIGMA,
    MapPrior,
    Search,
    attempts_to_catch,
    feature_weighted_order,
    feature_weights,
    load_prior_maps,
    map_prior_order,
    ring,
    smooth,
    wavefront_order,
)
from regrasp_drake.parameter_space import H_CATCH_VALUES, H_DOWN_VALUES, cells
from regrasp_drake.paths import MODELS_DIR

N_CATCH, N_DOWN = len(H_CATCH_VALUES), len(H_DOWN_VALUES)
CORNERS = [(0, 0), (0, N_DOWN - 1), (N_CATCH - 1, 0), (N_CATCH - 1, N_DOWN - 1)]


class TestWavefrontOrder(unittest.TestCase):
    def test_every_start_cell_covers_the_grid_once(self):
        everything = set(cells())
        for start in cells():
            order = wavefront_order(start)
            with self.subTest(start=start):
                self.assertEqual(order[0], start)
                self.assertEqual(len(order), 150)
                self.assertEqual(len(set(order)), 150)  # never a cell twice
                self.assertEqual(set(order), everything)  # none outside

    def test_rings_in_order_each_complete(self):
        for start in cells():
            rings = [ring(c, start) for c in wavefront_order(start)]
            with self.subTest(start=start):
                self.assertEqual(rings, sorted(rings))
                # Each ring holds every in-grid cell at that distance.
                for r in set(rings):
                    expected = sum(
                        max(abs(i - start[0]), abs(j - start[1])) == r
                        for i in range(N_CATCH) for j in range(N_DOWN))
                    self.assertEqual(rings.count(r), expected)

    def test_each_ring_grows_from_the_previous(self):
        """Fig. 8: a layer is made of neighbours (±1 unit in h_catch and/or
        h_down) of the layer before it."""
        for start in CORNERS + [(4, 7), (9, 3)]:
            order = wavefront_order(start)
            for k, cell in enumerate(order[1:], 1):
                inner = [c for c in order[:k]
                         if ring(c, start) == ring(cell, start) - 1]
                with self.subTest(start=start, cell=cell):
                    self.assertTrue(any(ring(cell, c) == 1 for c in inner))

    def test_documented_order_inside_a_ring(self):
        for start in cells():
            order = wavefront_order(start)
            keys = [(ring(c, start), (c[0] - start[0]) ** 2
                     + (c[1] - start[1]) ** 2, c[0], c[1]) for c in order]
            with self.subTest(start=start):
                self.assertEqual(keys, sorted(keys))

    def test_first_ring_examples(self):
        # An inner cell: the four edge neighbours, then the diagonals.
        self.assertEqual(wavefront_order((4, 7))[:9], [
            (4, 7), (3, 7), (4, 6), (4, 8), (5, 7),
            (3, 6), (3, 8), (5, 6), (5, 8)])
        # Corners: three neighbours, the diagonal last.
        self.assertEqual(wavefront_order((0, 0))[:4],
                         [(0, 0), (0, 1), (1, 0), (1, 1)])
        self.assertEqual(wavefront_order((0, 14))[:4],
                         [(0, 14), (0, 13), (1, 14), (1, 13)])
        self.assertEqual(wavefront_order((9, 14))[:4],
                         [(9, 14), (8, 14), (9, 13), (8, 13)])
        # The last cell from a corner is the opposite corner.
        self.assertEqual(wavefront_order((0, 0))[-1], (9, 14))

    def test_start_outside_the_grid_refused(self):
        for start in ((-1, 0), (0, N_DOWN), (N_CATCH, 3)):
            with self.subTest(start=start), self.assertRaises(InputError) as e:
                wavefront_order(start)
            self.assertIn("start_cell", str(e.exception))



def block(i_range, j_range) -> np.ndarray:
    """A success map that catches in the cells i_range x j_range only."""
    caught = np.zeros((N_CATCH, N_DOWN), bool)
    caught[i_range[0]:i_range[1] + 1, j_range[0]:j_range[1] + 1] = True
    return caught


def proposals(search: Search, outcomes) -> list:
    """The cells `search` proposes while it is told `outcomes` one by one
    (it may stop first: a catch, or no cell left)."""
    proposed = []
    for outcome in outcomes:
        if search.next_cell is None:
            break
        proposed.append(search.next_cell)
        search.tell(outcome)
    return proposed


class TestSearch(unittest.TestCase):
    """The search object alone: it proposes a cell, is told how the throw
    there ended, and proposes the next (no simulation: the outcomes are
    given here)."""

    def test_wavefront_proposes_its_order_until_a_catch(self):
        start = (4, 7)
        search = Search(start)
        outcomes = ["dropped", "timeout", "landed", "failed", "dropped",
                    "caught", "dropped"]
        proposed = proposals(search, outcomes)
        self.assertEqual(proposed, wavefront_order(start)[:6])
        self.assertEqual(search.tried, list(zip(proposed, outcomes)))
        self.assertTrue(search.caught)
        self.assertIsNone(search.next_cell)  # over after the catch
        with self.assertRaises(InputError) as e:
            search.tell("dropped")
        self.assertIn("outcome", str(e.exception))

    def test_every_cell_once_then_exhausted(self):
        search = Search((9, 0))
        proposed = proposals(search, ["dropped"] * 200)
        self.assertEqual(proposed, wavefront_order((9, 0)))
        self.assertIsNone(search.next_cell)
        self.assertFalse(search.caught)
        self.assertEqual(len(search.tried), 150)

    def test_unreachable_cells_are_passed_over_without_a_throw(self):
        """The arm lowers the hand to the fourth h_down at most: the cells
        of the three deepest columns are never proposed, and are recorded
        as unreachable where the wavefront reaches them."""
        reach = [j >= 3 for j in range(N_DOWN)]
        start = (5, 3)
        search = Search(start, reach=reach)
        proposed = proposals(search, ["dropped"] * 200)
        order = wavefront_order(start)
        self.assertEqual(proposed, [c for c in order if reach[c[1]]])
        self.assertEqual([c for c, _ in search.tried], order)
        self.assertEqual([c for c, outcome in search.tried
                          if outcome == Search.UNREACHABLE],
                         [c for c in order if not reach[c[1]]])
        # A start the arm cannot reach is passed over too.
        self.assertEqual(Search((5, 0), reach=reach).next_cell, (5, 3))
        with self.assertRaises(InputError) as e:
            Search(start, reach=reach[:5])
        self.assertIn("reach", str(e.exception))

    def test_map_prior_follows_the_maps_the_failures_leave(self):
        """Two maps catch only at (0, 0), one only at (9, 14): from (0, 0),
        a failure there points to (9, 14); a catch there ends the search."""
        kind_a, kind_b = block((0, 0), (0, 0)), block((9, 9), (14, 14))
        prior = MapPrior([kind_a, kind_a, kind_b], sigma_cells=0)
        search = Search((0, 0), prior)
        self.assertEqual(proposals(search, ["dropped", "caught"]),
                         [(0, 0), (9, 14)])
        self.assertTrue(search.caught)
        # The failure moved the weight to the map that does not catch at
        # (0, 0): each factor EPS for the two that do, 1 - EPS for it.
        np.testing.assert_allclose(prior.w, np.array([0.2, 0.2, 0.8]) / 1.2)

    def test_map_prior_counts_an_unreachable_cell_as_a_failure(self):
        """With columns the arm does not reach, the map prior proposes what
        it would without them, less those cells: each is a failure to it,
        as a throw there would be."""
        maps = np.random.default_rng(1).random((6, N_CATCH, N_DOWN))
        reach = [j >= 4 for j in range(N_DOWN)]
        start = (3, 6)
        everywhere = list(Search(start, MapPrior(maps)))
        search = Search(start, MapPrior(maps), reach=reach)
        self.assertEqual(proposals(search, ["dropped"] * 200),
                         [c for c in everywhere if reach[c[1]]])
        self.assertEqual([c for c, _ in search.tried], everywhere)


class TestMapPriorOrder(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.names, cls.prior = load_prior_maps()  # the shipped training maps

    def test_start_first_every_cell_once(self):
        rng = np.random.default_rng(0)
        priors = {"shipped": self.prior,
                  "random probabilities": rng.random((5, N_CATCH, N_DOWN))}
        for (label, prior), start in itertools.product(
                priors.items(), CORNERS + [(7, 2), (4, 7)]):
            order = list(map_prior_order(start, prior))
            with self.subTest(prior=label, start=start):
                self.assertEqual(order[0], start)
                self.assertEqual(len(order), 150)
                self.assertEqual(set(order), set(cells()))  # none twice

    def test_identical_maps_give_their_catching_cells_in_wavefront_order(self):
        """Unsmoothed, every map the same: a failure changes no map's
        weight relative to another, so the posterior stays that map, and
        the search tries its catching cells first, nearest in the wavefront
        order first, then the others."""
        caught = np.zeros((N_CATCH, N_DOWN), bool)
        for cell in ((3, 3), (3, 4), (8, 12), (0, 14)):
            caught[cell] = True
        start = (7, 2)  # fails
        order = list(map_prior_order(start, [caught] * 3, sigma_cells=0))
        wave = wavefront_order(start)
        self.assertEqual(order[1], next(c for c in wave if caught[c]))
        self.assertEqual(order[1], (3, 3))
        self.assertEqual(order, [start] + [c for c in wave if caught[c]] + [
            c for c in wave[1:] if not caught[c]])

    def test_smoothed_single_cell_map_goes_straight_to_it(self):
        """One catching cell ten rings from the start: the wavefront tries
        dozens of cells first, the map prior (smoothed) goes there second."""
        caught = block((1, 1), (12, 12))
        start = (7, 2)
        self.assertGreater(attempts_to_catch(wavefront_order(start), caught),
                           100)
        order = map_prior_order(start, [caught, caught])
        self.assertEqual(list(itertools.islice(order, 2)), [start, (1, 12)])

    def test_leave_one_object_out_beats_the_wavefront(self):
        """A prior of two kinds of object, two catch points each: six that
        catch around the start cell (7, 2) and three that catch only far
        from it (h_catch low, no lowering). Each object held out with both
        its maps; the far ones need 2 cells with the map prior (the start
        fails, so the far maps take the weight) and over 100 with the
        wavefront."""
        maps, names = [], []
        for k in range(6):
            for point, shift in ((1, 0), (2, 1)):
                maps.append(block((6 + shift, 8), (k % 3, 3 + shift)))
                names.append(f"near-{k}" + ("" if point == 1 else "@2"))
        for k in range(3):
            for point, shift in ((1, 0), (2, 1)):
                maps.append(block((0, 1 + shift), (11 + k, 14)))
                names.append(f"far-{k}" + ("" if point == 1 else "@2"))
        maps = np.array(maps)
        start = (7, 2)
        costs = {"wavefront": {}, "map-prior": {}}
        for name, caught in zip(names, maps):
            prior = maps[[object_of(n) != object_of(name) for n in names]]
            costs["wavefront"][name] = attempts_to_catch(
                wavefront_order(start), caught)
            costs["map-prior"][name] = attempts_to_catch(
                map_prior_order(start, prior), caught)
        for name in names:
            with self.subTest(name=name):
                if name.startswith("near"):
                    self.assertEqual(costs["wavefront"][name], 1)
                    self.assertEqual(costs["map-prior"][name], 1)
                else:
                    self.assertGreater(costs["wavefront"][name], 100)
                    self.assertEqual(costs["map-prior"][name], 2)
        self.assertLess(np.mean(list(costs["map-prior"].values())),
                        np.mean(list(costs["wavefront"].values())) / 5)

    def test_bad_arguments_refused_when_called(self):
        good = np.zeros((2, N_CATCH, N_DOWN))
        for kwargs, field in (
                (dict(start_cell=(N_CATCH, 0), prior_maps=good), "start_cell"),
                (dict(start_cell=(0, 0), prior_maps=good[:, :, :5]),
                 "prior_maps"),
                (dict(start_cell=(0, 0), prior_maps=good[:0]), "prior_maps"),
                (dict(start_cell=(0, 0), prior_maps=good + 2), "prior_maps"),
                (dict(start_cell=(0, 0), prior_maps=good, eps=0), "eps"),
                (dict(start_cell=(0, 0), prior_maps=good, eps=0.6), "eps"),
                (dict(start_cell=(0, 0), prior_maps=good, sigma_cells=-1),
                 "sigma_cells")):
            with self.subTest(field=field, kwargs=list(kwargs)), \
                    self.assertRaises(InputError) as e:
                map_prior_order(**kwargs)  # no next(): refused at once
            self.assertIn(field, str(e.exception))

    def test_feature_weights_favour_the_maps_of_like_objects(self):
        """Two kinds of object that differ in r_cm only: maps of an object
        with the other kind's features weigh e^-2 or less (2 standard
        deviations apart at sigma 1), the nearest entry weighs 1, and no
        sigma is uniform."""
        prior = np.array([[-3.7, 0.0, 0.0, 200.0, 8.0]] * 3
                         + [[-3.7, 0.0, 0.04, 200.0, 8.0]] * 3)
        near = feature_weights(prior[4], prior, sigma=1.0)
        np.testing.assert_allclose(near[3:], 1.0)
        np.testing.assert_allclose(near[:3], np.exp(-2.0))
        # Far beyond every entry: the nearest still weighs 1 (no underflow).
        far = feature_weights([-3.7, 0.0, 5.0, 200.0, 8.0], prior, sigma=0.1)
        np.testing.assert_allclose(far[3:], 1.0)
        self.assertTrue(np.all(far[:3] < 1e-12))
        np.testing.assert_array_equal(feature_weights(prior[0], prior, None),
                                      np.ones(6))
        for args, field in (((prior[0], prior[:, :4]), "prior_features"),
                            (([1.0, 2.0], prior), "features"),
                            (([np.nan] * 5, prior), "features"),
                            ((prior[0], prior, 0.0), "sigma")):
            with self.subTest(field=field), \
                    self.assertRaises(InputError) as e:
                feature_weights(*args)
            self.assertIn(field, str(e.exception))

    def test_weights_pick_the_like_objects_maps(self):
        """Two kinds of map, both failing at the start cell: weighted toward
        one kind, the search's second cell is that kind's catching cell;
        toward the other, the other's."""
        kind_a, kind_b = block((0, 0), (0, 0)), block((9, 9), (14, 14))
        maps = np.array([kind_a, kind_a, kind_b, kind_b])
        start = (5, 7)
        for weights, second in (([1, 1, 1e-3, 1e-3], (0, 0)),
                                ([1e-3, 1e-3, 1, 1], (9, 14))):
            order = map_prior_order(start, maps, sigma_cells=0,
                                    weights=weights)
            with self.subTest(weights=weights):
                self.assertEqual(list(itertools.islice(order, 2)),
                                 [start, second])
        for weights in ([1, 1, 1], [0, 0, 0, 0], [1, -1, 1, 1],
                        [1, np.inf, 1, 1]):
            with self.subTest(weights=weights), \
                    self.assertRaises(InputError) as e:
                map_prior_order(start, maps, weights=weights)
            self.assertIn("weights", str(e.exception))

    def test_feature_weighted_order_follows_the_like_objects(self):
        """The object's features next to kind B's entries: the second cell
        is kind B's catching cell; without prior features, every map counts
        alike and the search is the unweighted one."""
        kind_a, kind_b = block((0, 0), (0, 0)), block((9, 9), (14, 14))
        maps = np.array([kind_a, kind_a, kind_a, kind_b])
        prior_features = np.array([[0.0] * 5, [0.1] * 5, [0.2] * 5,
                                   [3.0] * 5])
        start = (5, 7)
        # A kernel of width 0.75 (the shipped width is None: see below).
        near_b = feature_weighted_order(start, maps, prior_features,
                                        np.full(5, 3.0), sigma=0.75)
        self.assertEqual(list(itertools.islice(near_b, 2)), [start, (9, 14)])
        alike = feature_weighted_order(start, maps, None, np.full(5, 3.0))
        self.assertEqual(list(itertools.islice(alike, 150)),
                         list(itertools.islice(map_prior_order(start, maps),
                                               150)))

    def test_shipped_prior_has_features_and_the_kernel_width_is_chosen(self):
        names, caught, features = load_prior_maps(with_features=True)
        self.assertEqual(features.shape, (len(names), 5))
        # The width is the one studies/search_prior/search_prior.py's rule
        # picks on the shipped maps (None: every map alike).
        chosen = json.loads((Path(__file__).parents[1] / "studies"
                             / "search_prior" / "search_prior.json").read_text())
        self.assertEqual(chosen["feature_sigma"]["chosen"], FEATURE_SIGMA)
        self.assertTrue(chosen["feature_sigma"]["agrees"])
        # The entries' features are those of their plans in the data set.
        plan = json.loads((MODELS_DIR / "dataset" / "plans"
                           / f"{names[0]}.json").read_text())
        np.testing.assert_array_equal(
            features[0], [plan["features"][k] for k in (
                "v_catch", "h_cm", "r_cm", "d_obj", "v_conv")])

    def test_smoothing_keeps_probabilities_and_spreads_a_catch(self):
        caught = block((4, 4), (7, 7))
        p = smooth(caught)
        self.assertAlmostEqual(p.sum(), 1.0, places=12)  # no edge nearby
        self.assertEqual(np.unravel_index(p.argmax(), p.shape), (4, 7))
        self.assertGreater(p[4, 8], p[4, 9])   # falls off with distance
        self.assertEqual(p[4, 10], 0.0)        # beyond the 2-cell radius
        # At an edge, the edge cells repeat outwards: a caught edge row
        # stays caught, and nothing leaves [0, 1].
        edge = smooth(block((0, 0), (0, N_DOWN - 1)))
        np.testing.assert_allclose(edge[0], edge[0, 0])
        self.assertTrue(np.all((edge >= 0) & (edge <= 1)))
        np.testing.assert_array_equal(smooth(caught, 0), caught)
        # A pair smooths each axis by its own width: (s, s) is s, and a 0
        # leaves that axis alone.
        np.testing.assert_array_equal(smooth(caught, (0.7, 0.7)),
                                      smooth(caught, 0.7))
        along_catch = smooth(caught, (0.7, 0.0))
        self.assertTrue(np.all(along_catch[:, [6, 8]] == 0))
        self.assertGreater(along_catch[5, 7], 0.0)
        np.testing.assert_array_equal(smooth(caught, (0, 0)), caught)


class TestPriorMapsFile(unittest.TestCase):
    def test_shipped_prior(self):
        names, caught = load_prior_maps()
        self.assertEqual(caught.shape, (len(names), N_CATCH, N_DOWN))
        self.assertEqual(caught.dtype, bool)
        from regrasp_drake.world.objects import load_catalogue
        catalogue = load_catalogue()
        self.assertTrue(all(catalogue[object_of(n)].set == "train"
                            for n in names))

    def test_missing_and_malformed_files_refused_in_one_line(self):
        with tempfile.TemporaryDirectory() as d:
            d = Path(d)
            (d / "text.npz").write_text("not an archive\n")
            np.savez(d / "no_caught.npz", objects=np.array(["a"]))
            np.savez(d / "wrong_shape.npz", objects=np.array(["a"]),
                     caught=np.zeros((1, N_CATCH, N_DOWN - 1), bool))
            np.savez(d / "counts.npz", objects=np.array(["a"]),
                     caught=np.zeros((1, N_CATCH, N_DOWN), int))
            np.savez(d / "four_features.npz", objects=np.array(["a"]),
                     caught=np.zeros((1, N_CATCH, N_DOWN), bool),
                     features=np.zeros((1, 4)))
            np.savez(d / "nan_feature.npz", objects=np.array(["a"]),
                     caught=np.zeros((1, N_CATCH, N_DOWN), bool),
                     features=np.full((1, 5), np.nan))
            for name in ("missing.npz", "text.npz", "no_caught.npz",
                         "wrong_shape.npz", "counts.npz", "four_features.npz",
                         "nan_feature.npz"):
                with self.subTest(file=name), \
                        self.assertRaises(InputError) as e:
                    load_prior_maps(d / name)
                message = str(e.exception)
                self.assertIn(str(d / name), message)
                self.assertEqual(len(message.splitlines()), 1)


class TestSearchOption(unittest.TestCase):
    """`search` in the learning phase and `--search` on the command line."""

    def test_unknown_search_refused_before_any_throw(self):
        from regrasp_drake.learning.learning_phase import learn
        from regrasp_drake.station.mlp_system import CatchMlp
        from regrasp_drake.station.scenario import load_scenario
        from regrasp_drake.world.objects import load_catalogue
        episodes, progress = [], io.StringIO()
        for kwargs, expected in (
                (dict(search="bogus"),
                 "search: got 'bogus', expected one of 'wavefront', "
                 "'map-prior'"),
                (dict(search="wavefront", prior_maps=np.zeros((1, 10, 15))),
                 "prior_maps: got 'given', expected none unless search is "
                 "'map-prior'"),
                (dict(search="wavefront", prior_features=np.zeros((1, 5))),
                 "prior_features: got 'given', expected none unless search "
                 "is 'map-prior'"),
                (dict(search="map-prior", prior_features=np.zeros((1, 5))),
                 "prior_features: got 'given without prior_maps', expected "
                 "the features of the prior_maps' entries")):
            with self.subTest(kwargs=list(kwargs)), \
                    self.assertRaises(InputError) as e:
                learn(load_scenario(), load_catalogue()["table1-row2"],
                      CatchMlp(), on_episode=episodes.append,
                      progress=progress, **kwargs)
            self.assertEqual(str(e.exception), expected)
        self.assertEqual(episodes, [])  # no throw made
        self.assertEqual(progress.getvalue(), "")

    def test_cli_search_option(self):
        parser = make_parser()
        for command, args in (("learn", ["--object", "table1-row2"]),
                              ("table1", [])):
            with self.subTest(command=command):
                self.assertEqual(
                    parser.parse_args([command, *args]).search, "wavefront")
                self.assertEqual(parser.parse_args(
                    [command, *args, "--search", "map-prior"]).search,
                    "map-prior")
                stderr = io.StringIO()
                with contextlib.redirect_stderr(stderr), \
                        self.assertRaises(SystemExit) as e:
                    parser.parse_args([command, *args, "--search", "rings"])
                self.assertEqual(e.exception.code, 2)
                self.assertIn("--search", stderr.getvalue())
                self.assertIn("map-prior", stderr.getvalue())


class TestMapPriorLearningRun(unittest.TestCase):
    """table1-row2 from the cell (0.04, 0.00) m: the map prior, its maps
    weighted as shipped (FEATURE_SIGMA), tries the prior's cells in order,
    each throw's outcome the one table1-row2's stored map (the same watched
    plan) has in that cell, until one catches; at most three throws."""

    def test_tries_the_prior_order_and_catches_as_the_map_says(self):
        import torch

        from regrasp_drake.learning.learning_phase import learn
        from regrasp_drake.planning.ik import ArmIk
        from regrasp_drake.station.mlp_system import load_weights
        from regrasp_drake.station.scenario import load_scenario
        from regrasp_drake.world.objects import load_catalogue
        from tests.test_learning import constant_weights
        torch.set_num_threads(1)
        with tempfile.TemporaryDirectory() as d:
            model, _ = load_weights(constant_weights(Path(d) / "w.pt",
                                                     0.04, 0.0))
        _, prior, prior_features = load_prior_maps(with_features=True)
        r = learn(load_scenario(), load_catalogue()["table1-row2"], model,
                  ik=ArmIk(), max_throws=3, progress=None, search="map-prior")
        weights = feature_weights(r.features, prior_features)
        # As shipped (FEATURE_SIGMA None), every map weighs alike.
        np.testing.assert_array_equal(weights, np.ones(len(prior)))
        self.assertEqual(r.start_cell, (0, 14))
        stored = {tuple(row["cell"]): row["outcome"] == "caught" for row in map(
            json.loads, (MODELS_DIR / "results" / "maps" / "table1-row2.jsonl")
            .read_text().splitlines())}
        order = list(itertools.islice(
            map_prior_order(r.start_cell, prior, weights=weights), 2))
        first = next((k for k, c in enumerate(order, 1) if stored[c]), None)
        expected = order[:first] if first else order
        self.assertEqual([a.cell for a in r.attempts], expected)
        self.assertEqual([a.outcome == "caught" for a in r.attempts],
                         [stored[c] for c in expected])
        self.assertEqual(r.caught, first is not None)
        self.assertEqual(r.throws, 1 + len(expected))
        self.assertEqual(r.as_dict()["search"], "map-prior")
        if r.caught:
            self.assertEqual((r.learned.mode, r.learned.search),
                             ("watch", "map-prior"))


if __name__ == "__main__":
    unittest.main()
