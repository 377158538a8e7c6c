"""The learned planner (learning/planner.py): its splits, its choice on a
held-out object, its judging, its file, and the planner a target gets."""

import json
import shutil
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import numpy as np
import torch

from regrasp_drake.errors import InputError
from regrasp_drake.learning.labels import SHAPE, label_cell
from regrasp_drake.learning.planner import (
    PAPER_NETWORK,
    PLANNER_FEATURES,
    PlannerData,
    SuccessModel,
    best_constant,
    choose,
    judge,
    load_planner,
    splits,
    winner,
)
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target

REPO = Path(__file__).parents[1]
FLIP = MODELS_DIR / "dataset_flip+0"


def synthetic(n_geometries=4, per_geometry=4, seed=0) -> PlannerData:
    """Maps whose one succeeding band of h_down columns moves with the
    first feature (a heavier object needs more lowering, say), the other
    features alike for all: a rule a model can learn and no constant cell
    obeys."""
    rng = np.random.default_rng(seed)
    n = n_geometries * per_geometry
    features = np.zeros((n, len(PLANNER_FEATURES)))
    features[:, 0] = np.linspace(-1.5, 1.5, n)[rng.permutation(n)]
    caught = np.zeros((n, *SHAPE), bool)
    for k in range(n):
        j = int(np.clip(np.round(7 + 4.5 * features[k, 0]), 1, 13))
        caught[k, :, j - 1:j + 2] = True
    return PlannerData(
        objects=[f"obj{k}" for k in range(n)],
        geometries=[f"geo{k % n_geometries}" for k in range(n)],
        features=features, caught=caught,
        labels=[label_cell(m) for m in caught],
        paper_features=features[:, :5])


class SplitTest(unittest.TestCase):
    def test_no_geometry_on_both_sides(self):
        groups = ["can", "pill", "can", "spool", "pill", "can"]
        folds = splits(groups)
        self.assertEqual(len(folds), 3)
        held = np.concatenate([h for _, h in folds])
        self.assertEqual(sorted(held.tolist()), list(range(len(groups))))
        for train, held_out in folds:
            self.assertFalse({groups[k] for k in train}
                             & {groups[k] for k in held_out})
            self.assertEqual(len(set(train) | set(held_out)), len(groups))

    def test_best_constant_and_choice(self):
        caught = np.zeros((3, *SHAPE), bool)
        caught[:, 4, 6] = [True, True, False]
        caught[0, 1, 1] = True
        self.assertEqual(best_constant(caught), (4, 6))
        scores = np.zeros(SHAPE)
        scores[2, 3], scores[5, 14] = 0.9, 0.95
        self.assertEqual(choose(scores), (5, 14))
        reach = [True] * 14 + [False]  # the arm cannot lower to column 14
        self.assertEqual(choose(scores, reach), (2, 3))


class ChoiceTest(unittest.TestCase):
    """On maps where the succeeding cells move with a feature, the model
    trained without an object (or its geometry) picks a cell that succeeds
    for it, where the best constant cell cannot for most."""

    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.data = synthetic()

    def test_choice_on_a_held_out_object(self):
        data = self.data
        k = int(np.argsort(data.features[:, 0])[3])  # a light one
        train = [m for m in range(len(data.objects)) if m != k]
        model = SuccessModel().fit(data.features[train], data.caught[train])
        cell = choose(model.success_maps(data.features[k])[0])
        self.assertTrue(data.caught[k][cell], cell)
        self.assertFalse(data.caught[k][best_constant(data.caught[train])])

    def test_judging(self):
        choices = {}
        report = judge(self.data, choices=choices)
        for kind, n in (("by_geometry", 4), ("by_object", 16)):
            figures = report[kind]
            # the cells it reports picking give its rates, map by map
            picked = choices[kind]
            self.assertEqual(sorted(picked), sorted(self.data.objects))
            for chooser in ("learned", "paper_network", "best_constant"):
                hits = [self.data.caught[self.data.objects.index(name)][
                    picked[name][chooser]] for name in picked]
                self.assertAlmostEqual(figures[chooser], np.mean(hits), 4)
            for name, cells in picked.items():
                m = self.data.objects.index(name)
                self.assertEqual(cells["ceiling"], self.data.labels[m])
            self.assertEqual(figures["splits"], n)
            self.assertEqual(figures["maps"], 16)
            self.assertEqual(figures["ceiling"], 1.0)
            self.assertLessEqual(figures["best_constant"], 0.5)
            self.assertGreaterEqual(figures["learned"],
                                    figures["best_constant"] + 0.3)

    def test_deterministic(self):
        data = self.data
        maps = [SuccessModel().fit(data.features, data.caught, seed=3,
                                   epochs=50).success_maps(data.features)
                for _ in range(2)]
        np.testing.assert_array_equal(maps[0], maps[1])


class FileTest(unittest.TestCase):
    def test_round_trip_and_refusals(self):
        data = synthetic(2, 3)
        model = SuccessModel(members=2).fit(data.features, data.caught,
                                            epochs=20)
        report = {"by_geometry": {"learned": 0.5, "best_constant": 0.4,
                                  "paper_network": 0.3},
                  "best_constant_cell": [2, 3]}
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "planner_flip+0.json"
            model.save(path, report)
            loaded, metadata = SuccessModel.load(path)
            self.assertEqual(metadata, report)
            np.testing.assert_array_equal(
                loaded.success_maps(data.features),
                model.success_maps(data.features))
            planner = load_planner(Target("flip"), Path(d))
            self.assertEqual(planner.name, "learned")
            self.assertIs(planner.model.__class__, SuccessModel)
            # Where the learned planner does not win, the paper's network.
            model.save(Path(d) / "planner_flip+30.json", report | {
                "by_geometry": {"learned": 0.5, "best_constant": 0.6,
                                "paper_network": 0.3}})
            self.assertIs(load_planner(Target("flip", 30.0), Path(d)),
                          PAPER_NETWORK)
            # No planner file for keep, none ever for `any`.
            self.assertIs(load_planner(Target("keep"), Path(d)), PAPER_NETWORK)
            self.assertIs(load_planner(Target("any"), Path(d)), PAPER_NETWORK)
            raw = json.loads(path.read_text())
            raw["state"]["mean"] = raw["state"]["mean"][:3]
            path.write_text(json.dumps(raw))
            with self.assertRaises(InputError) as e:
                SuccessModel.load(path)
            self.assertIn("state.mean", str(e.exception))
            path.write_text("{not json")
            with self.assertRaises(InputError):
                SuccessModel.load(path)

    def test_winner(self):
        def rates(learned, constant, paper):
            return {"by_geometry": {"learned": learned,
                                    "best_constant": constant,
                                    "paper_network": paper}}
        self.assertEqual(winner(rates(0.8, 0.7, 0.6)), "learned")
        # A tie is not a win; the best constant cell is a baseline only.
        self.assertEqual(winner(rates(0.7, 0.7, 0.6)), "paper_network")
        self.assertEqual(winner(rates(0.6, 0.7, 0.65)), "paper_network")


@unittest.skipUnless((FLIP / "maps.npz").exists(), "no flip +0 data set")
class ShippedDataTest(unittest.TestCase):
    def test_reads_a_data_set(self):
        data = PlannerData.load(FLIP)
        self.assertEqual(data.features.shape,
                         (len(data.objects), len(PLANNER_FEATURES)))
        self.assertTrue(np.all(np.isfinite(data.features)))
        self.assertEqual(len(set(data.geometries)), 9)
        share = data.share_in_target()
        self.assertEqual(share["maps"], len(data.objects))

    def test_train_command_on_a_small_data_set(self):
        # Two objects of each of three geometries: the command judges the
        # planner (3 + 6 splits) and writes it and its report.
        data = PlannerData.load(FLIP)
        keep = [k for g in ("can", "pill", "spool")
                for k in [i for i, x in enumerate(data.geometries)
                          if x == g][:2]]
        with tempfile.TemporaryDirectory() as d:
            small = Path(d) / "small"
            (small / "plans").mkdir(parents=True)
            shutil.copy(FLIP / "provenance.json", small)
            with np.load(FLIP / "maps.npz") as maps:
                np.savez_compressed(
                    small / "maps.npz",
                    **{k: (maps[k][keep] if k in ("objects", "caught",
                                                  "features") else maps[k])
                       for k in maps.files})
            for k in keep:
                shutil.copy(FLIP / "plans" / f"{data.objects[k]}.json",
                            small / "plans")
            out, report = Path(d) / "planner.json", Path(d) / "report.json"
            done = subprocess.run(
                [sys.executable, "-m", "regrasp_drake.cli", "train",
                 "--target", "flip", "--data", str(small), "--out", str(out),
                 "--json", str(report)], capture_output=True, text=True,
                cwd=REPO)
            self.assertEqual(done.returncode, 0, done.stderr)
            figures = json.loads(report.read_text())
            self.assertEqual(figures["target"], {"kind": "flip",
                                                 "offset_mm": 0.0})
            self.assertEqual(figures["by_geometry"]["splits"], 3)
            self.assertEqual(figures["by_object"]["splits"], 6)
            for kind in ("by_geometry", "by_object"):
                rates = figures[kind]
                for name in ("learned", "paper_network", "best_constant"):
                    self.assertLessEqual(rates[name], rates["ceiling"])
            self.assertIn(figures["planner"], ("learned", "best_constant",
                                               "paper_network"))
            SuccessModel.load(out)

    def test_offset_without_target_refused(self):
        done = subprocess.run(
            [sys.executable, "-m", "regrasp_drake.cli", "train",
             "--offset-mm", "30"], capture_output=True, text=True, cwd=REPO)
        self.assertEqual(done.returncode, 2)
        self.assertIn("--offset-mm: got 30 without --target", done.stderr)


@unittest.skipUnless((MODELS_DIR / "results" / "planner_flip+0.json").exists(),
                     "no flip +0 planner report")
class BenchmarkTest(unittest.TestCase):
    """benchmarks/learned_planner.py gathers the shipped reports (judging
    none again) into one JSON and a table; a bad target exits 2."""

    def run_script(self, *args):
        return subprocess.run(
            [sys.executable, "benchmarks/learned_planner.py", *args],
            capture_output=True, text=True, cwd=REPO)

    def test_gathers_the_reports(self):
        shipped = json.loads(
            (MODELS_DIR / "results" / "planner_flip+0.json").read_text())
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "planner.json"
            done = self.run_script("--targets", "flip+0", "--out", str(out))
            self.assertEqual(done.returncode, 0, done.stderr)
            (row,) = json.loads(out.read_text())["targets"]
        self.assertEqual(row["by_geometry"], shipped["by_geometry"])
        self.assertEqual(row["planner"], shipped["planner"])
        self.assertAlmostEqual(row["learned_lead_by_geometry"],
                               shipped["by_geometry"]["learned"]
                               - shipped["by_geometry"]["best_constant"], 4)
        self.assertIn("| flip+0 |", done.stdout)

    def test_bad_target_refused(self):
        done = self.run_script("--targets", "flip+7")
        self.assertEqual(done.returncode, 2)
        self.assertIn("--targets: got 'flip+7'", done.stderr)


class ConvergenceBenchmarkTest(unittest.TestCase):
    """benchmarks/planner_convergence.py: its figures on maps made up
    here, and its refusals (exit 2, naming the field)."""

    @classmethod
    def setUpClass(cls):
        sys.path.insert(0, str(REPO / "benchmarks"))
        import planner_convergence
        cls.bench = planner_convergence

    def test_figures(self):
        coarse = {n: np.zeros(SHAPE, bool) for n in ("a", "b")}
        fine = {n: np.zeros(SHAPE, bool) for n in ("a", "b")}
        coarse["a"][2, 3] = coarse["a"][5, 5] = True  # both in target at 1 ms
        fine["a"][2, 3] = True                        # one of them still so
        coarse["b"][0, 0] = True                      # b: lost at the finer step
        picks = {n: {"learned": (2, 3), "paper_network": (5, 5),
                     "best_constant": (0, 0)} for n in ("a", "b")}
        figures = self.bench.compare(["a", "b"], coarse, fine, picks)
        self.assertEqual(figures["maps"], 2)
        self.assertAlmostEqual(figures["cells_same"], 1 - 2 / 300, 4)
        self.assertAlmostEqual(figures["in_target_still_at_finer_step"], 1 / 3, 4)
        self.assertEqual(figures["coarse"], {"learned": 0.5, "paper_network": 0.5,
                                             "best_constant": 0.5, "ceiling": 1.0})
        self.assertEqual(figures["fine"], {"learned": 0.5, "paper_network": 0.0,
                                           "best_constant": 0.0, "ceiling": 0.5})

    def test_refusals(self):
        for args, expected in ((["--target", "flip+7"], "--target: 'flip+7'"),
                               (["--steps-ms", "2"], "finer than the data set's 1 ms"),
                               (["--workers", "0"], "--workers: got 0"),
                               (["--steps-ms", "0.125"],
                                "least the throw's plant step, 0.25 ms"),
                               (["--objects", "no-such"], "--objects: 'no-such'")):
            done = subprocess.run(
                [sys.executable, "benchmarks/planner_convergence.py", *args],
                capture_output=True, text=True, cwd=REPO)
            self.assertEqual(done.returncode, 2, done.stderr)
            self.assertIn(expected, done.stderr)
            self.assertEqual(len(done.stderr.strip().splitlines()), 1)


if __name__ == "__main__":
    unittest.main()
