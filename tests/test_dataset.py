"""The data set: labels, generation, resuming after a kill, determinism."""

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset import generate, generate_targets
from regrasp_drake.learning.dataset_files import FEATURE_NAMES, load_map
from regrasp_drake.learning.labels import SHAPE, label_cell, robustness
from regrasp_drake.learning.provenance import check_same_scenario, scenario_text
from regrasp_drake.planning.grasp import Target
from regrasp_drake.station.scenario import (
    load_scenario,
    scenario_yaml,
    with_target,
)

REPO = Path(__file__).parents[1]
OBJECTS = ["table1-row2", "table1-row1"]
# A coarse grid: h_catch 0.12, 0.28 × h_down -0.11, -0.05.
COARSE = [(i, j) for i in (2, 6) for j in (3, 9)]


class LabelTest(unittest.TestCase):
    def test_robustness_is_distance_to_nearest_failure(self):
        caught = np.zeros(SHAPE, bool)
        caught[2:7, 3:10] = True  # a 5 × 7 block of catches
        r = robustness(caught)
        self.assertEqual(r[0, 0], 0)
        self.assertEqual(r[2, 3], 1)   # on the block's edge
        self.assertEqual(r[4, 6], 3)   # its centre
        self.assertEqual(label_cell(caught), (4, 6))

    def test_ties_go_to_the_middle_then_low_indices(self):
        caught = np.zeros(SHAPE, bool)
        caught[0, 0:3] = True  # three cells of robustness 1
        self.assertEqual(label_cell(caught), (0, 1))
        caught = np.zeros(SHAPE, bool)
        caught[5, 5] = caught[5, 9] = True  # equal, mean between them
        self.assertEqual(label_cell(caught), (5, 5))

    def test_no_catch_no_label(self):
        self.assertIsNone(label_cell(np.zeros(SHAPE, bool)))
        self.assertEqual(robustness(np.ones(SHAPE, bool)).min(), 15)


class SplitTest(unittest.TestCase):
    def test_paper_proportions(self):
        from regrasp_drake.learning.train import split_indices
        train, val, test = split_indices(64, seed=0)
        self.assertEqual((len(train), len(val), len(test)), (44, 10, 10))
        self.assertEqual(sorted(train + val + test), list(range(64)))

    def test_catch_points_of_one_object_stay_together(self):
        """Two catch points per object: an object's samples are all in one
        split, and the splits keep the proportions to within one object."""
        from regrasp_drake.learning.train import split_indices
        groups = [f"object{k // 2}" for k in range(90)]
        splits = split_indices(90, seed=4, groups=groups)
        owner = {}
        for name, split in zip(("train", "val", "test"), splits):
            for i in split:
                self.assertEqual(owner.setdefault(groups[i], name), name)
        self.assertEqual(sorted(sum(splits, [])), list(range(90)))
        for split, share in zip(splits, (44, 10, 10)):
            self.assertLessEqual(abs(len(split) - 90 * share / 64), 2)

    def test_repeated_splits_count_the_splits_each_way(self):
        """Over several splits of the shipped data set, each split's catch
        rates are its own training's, and the network's splits better than,
        equal to and worse than a baseline add up to the splits."""
        from regrasp_drake.learning.train import repeated_splits, train
        from regrasp_drake.paths import MODELS_DIR
        data = MODELS_DIR / "dataset"
        report = repeated_splits(data, [0, 1, 2], epochs=40)
        rates = report["catch_rates"]
        for baseline, counts in report["network_vs"].items():
            self.assertEqual(sum(counts.values()), 3)
            self.assertEqual(counts["better"], sum(
                n > b for n, b in zip(rates["network"], rates[baseline])))
            self.assertEqual(counts["worse"], sum(
                n < b for n, b in zip(rates["network"], rates[baseline])))
        with tempfile.TemporaryDirectory() as tmp:
            seed1 = train(data, Path(tmp) / "w.pt", seed=1, epochs=40)["test"]
        self.assertEqual([rates[k][1] for k in rates],
                         [round(seed1[k]["catch_rate"], 4) for k in rates])


def _rows(out: Path) -> dict:
    """Every object's cells, without wall times (the only thing that may
    differ between runs)."""
    return {(name, cell): row for name in OBJECTS
            for cell, row in _rows_of(out, name).items()}


def _rows_of(out: Path, entry: str) -> dict:
    rows = {}
    for line in (out / "cells" / f"{entry}.jsonl").read_text().splitlines():
        row = json.loads(line)
        row.pop("wall_s")
        rows[tuple(row["cell"])] = row
    return rows


class OldPhysicsTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.addCleanup(self.tmp.cleanup)

    def test_a_finger_throw_set_is_not_resumed_under_the_palm_toss(self):
        # A set begun under the retired throw (its scenario.yaml the named
        # scenario FingerThrow's), resumed under the shipped one: refused
        # before any simulation, naming the first field that differs, and
        # what it holds is left as it was.
        old = Path(self.tmp.name) / "finger_throw"
        (old / "cells").mkdir(parents=True)
        text = scenario_yaml(load_scenario(name="FingerThrow"))
        (old / "scenario.yaml").write_text(text)
        (old / "cells" / "table1-row2.jsonl").write_text('{"cell": [0, 0]}\n')
        with self.assertRaises(InputError) as e:
            generate(OBJECTS, old, workers=1, only=COARSE, progress=False)
        self.assertEqual(
            str(e.exception).split(" (")[0],
            f"--scenario: catch.catch_height_m is 0.45 here but 0.78 in the "
            f"data set in {old}")
        self.assertEqual((old / "scenario.yaml").read_text(), text)
        self.assertEqual((old / "cells" / "table1-row2.jsonl").read_text(),
                         '{"cell": [0, 0]}\n')

    def test_a_set_of_other_robot_models_is_not_resumed(self):
        # A set begun with other robot model files (the scenario names them
        # by path only; its robot_models.sha256 not sdf/'s digest now) is
        # refused before any simulation, naming sdf/ and both digests, and
        # what it holds is left as it was.
        from regrasp_drake.learning.provenance import robot_models_digest
        old = Path(self.tmp.name) / "other_hand"
        (old / "cells").mkdir(parents=True)
        text = scenario_yaml(load_scenario())
        (old / "scenario.yaml").write_text(text)
        (old / "robot_models.sha256").write_text("0123456789abcdef\n")
        (old / "cells" / "table1-row2.jsonl").write_text('{"cell": [0, 0]}\n')
        with self.assertRaises(InputError) as e:
            generate(OBJECTS, old, workers=1, only=COARSE, progress=False)
        self.assertTrue(str(e.exception).startswith(
            f"sdf/: the robot models (*.sdf, *.dmd.yaml) have digest "
            f"{robot_models_digest()} here but 0123456789abcdef in the data "
            f"set in {old}"), str(e.exception))
        self.assertEqual((old / "robot_models.sha256").read_text(),
                         "0123456789abcdef\n")
        self.assertEqual((old / "cells" / "table1-row2.jsonl").read_text(),
                         '{"cell": [0, 0]}\n')


class TargetSetsTest(unittest.TestCase):
    """Several targets' data sets in one run (dataset --all-targets): each
    the data set `generate` makes under its target, and a directory of one
    target not resumed under another."""

    def test_one_run_makes_each_targets_data_set(self):
        keep, flip = Target("keep"), Target("flip")
        with tempfile.TemporaryDirectory() as d:
            root = Path(d)
            made = generate_targets(OBJECTS[:1], root, targets=(keep, flip),
                                    workers=2, only=COARSE[:1],
                                    progress=False)
            self.assertEqual(sorted(made), ["dataset_flip+0", "dataset_keep+0"])
            alone = generate(OBJECTS[:1], root / "alone", workers=1,
                             only=COARSE[:1], progress=False,
                             scenario=with_target(load_scenario(), flip))
            self.assertEqual(made["dataset_flip+0"]["scenario"],
                             alone["scenario"])
            self.assertIn("target: keep", made["dataset_keep+0"]["scenario"])
            for rows in ("alone", "dataset_flip+0"):
                line = json.loads((root / rows / "cells" / f"{OBJECTS[0]}.jsonl")
                                  .read_text())
                line.pop("wall_s")
                if rows == "alone":
                    first = line
            self.assertEqual(line, first)
            # The keep set moved to flip's place: refused before any work.
            shutil.rmtree(root / "dataset_flip+0")
            (root / "dataset_keep+0").rename(root / "dataset_flip+0")
            with self.assertRaises(InputError) as e:
                generate_targets(OBJECTS[:1], root, targets=(flip,),
                                 only=COARSE[:1], progress=False)
            self.assertIn("regrasp.target is", str(e.exception))

    def test_all_targets_with_a_target_refused(self):
        done = subprocess.run(
            [sys.executable, "-m", "regrasp_drake.cli", "dataset",
             "--all-targets", "--target", "flip"], capture_output=True,
            text=True, cwd=REPO)
        self.assertEqual(done.returncode, 2)
        self.assertIn("--all-targets: got it with --target flip",
                      done.stderr)


class GenerateTest(unittest.TestCase):
    """Two objects on a coarse grid: serial, and with 2 workers killed
    mid-run and resumed with 2 workers (or on Ray), give the same rows."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)
        cls.serial = generate(OBJECTS, cls.root / "serial", workers=1,
                              only=COARSE, progress=False)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_serial_files(self):
        out = self.root / "serial"
        self.assertEqual(self.serial["maps"], 2)
        for name in OBJECTS:
            lines = (out / "cells" / f"{name}.jsonl").read_text().splitlines()
            self.assertEqual(len(lines), len(COARSE))
            caught = load_map(out, name)
            self.assertEqual(caught.shape, SHAPE)
            # Only the coarse cells can catch.
            self.assertFalse(np.any(np.delete(caught.ravel(), [
                i * SHAPE[1] + j for i, j in COARSE])))
        samples = (out / "samples.csv").read_text().splitlines()
        self.assertEqual(len(samples), 1 + self.serial["samples"])
        self.assertGreaterEqual(self.serial["samples"], 1)
        with np.load(out / "maps.npz") as maps:
            self.assertEqual(maps["caught"].shape, (2, *SHAPE))
            # Each map's features (the map prior's kernel) are its plan's.
            self.assertEqual(list(maps["feature_names"]), list(FEATURE_NAMES))
            for name, features in zip(maps["objects"], maps["features"]):
                plan = json.loads((out / "plans" / f"{name}.json").read_text())
                self.assertEqual(features.tolist(), [
                    plan["features"][k] for k in FEATURE_NAMES])
        provenance = json.loads((out / "provenance.json").read_text())
        self.assertIn("plant_config", provenance["scenario"])
        # The run records the kernels it computed with (numerics.py): this
        # test process is pinned, so no AVX-512 kernels.
        from regrasp_drake import numerics
        self.assertEqual(provenance["runs"][-1]["numerics"], numerics.status())
        self.assertFalse(provenance["runs"][-1]["numerics"]["numpy_avx512_kernels"])
        self.assertEqual(len(provenance["catalogue_sha256"]), 64)
        # One run computed both entries; its record is kept.
        self.assertEqual(provenance["entries_computed"], 2)
        self.assertEqual([r["entries_computed"] for r in provenance["runs"]],
                         [2])

    def test_a_run_with_nothing_to_do_keeps_the_runs_record(self):
        out = self.root / "rerun"
        shutil.copytree(self.root / "serial", out)
        again = generate(OBJECTS, out, workers=1, only=COARSE,
                         progress=False)
        self.assertEqual(again["entries_computed"], 0)
        self.assertEqual(again["runs"], self.serial["runs"])

    def test_another_scenario_is_not_resumed(self):
        # The finished set (provenance.json) and a set whose first run was
        # killed (scenario.yaml only) both refuse another scenario before
        # any simulation, naming the first field that differs.
        # The grasp monitor's hold doubled.
        hold = load_scenario(text="{monitor: {hold_s: 0.5}}")
        killed = self.root / "killed"
        killed.mkdir()
        (killed / "scenario.yaml").write_text(scenario_text())
        for out in (self.root / "serial", killed):
            with self.subTest(out=out.name):
                with self.assertRaises(InputError) as e:
                    generate(OBJECTS, out, workers=1, only=COARSE,
                             scenario=hold, progress=False)
                self.assertEqual(
                    str(e.exception).split(" (")[0],
                    f"--scenario: monitor.hold_s is 0.5 here but 0.25 in the "
                    f"data set in {out}")
        self.assertFalse((self.root / "serial" / "scenario.yaml").exists())

    def test_a_field_added_since_at_its_former_behaviour_resumes(self):
        # A set started before catch.closing_order existed (its text
        # without the field) resumes under "together", which digests and
        # behaves as before; another order is another scenario.
        started = self.root / "started_before"
        started.mkdir()
        (started / "scenario.yaml").write_text(
            scenario_text().replace("  closing_order: together\n", ""))
        check_same_scenario(started)
        with self.assertRaisesRegex(InputError, "catch.closing_order is "
                                    "'thumb_first' here but None"):
            check_same_scenario(started, load_scenario(
                text="{catch: {closing_order: thumb_first}}"))

    def test_two_catch_points_per_object(self):
        """--catch-points 2: a second entry per object, planned at another
        moment of the same watched flight (at least the separation later or
        earlier), with its own map; its first entry is the one-point set's."""
        from regrasp_drake.learning.dataset import CATCH_POINT_SEPARATION_S
        out = self.root / "points"
        provenance = generate(OBJECTS[:1], out, workers=1, only=COARSE,
                              progress=False, catch_points=2)
        self.assertEqual((provenance["objects"], provenance["entries"],
                          provenance["catch_points_per_object"]), (1, 2, 2))
        name = OBJECTS[0]
        first = json.loads((out / "plans" / f"{name}.json").read_text())
        second = json.loads((out / "plans" / f"{name}@2.json").read_text())
        self.assertEqual((first["catch_point"], second["catch_point"]), (1, 2))
        self.assertGreaterEqual(
            abs(first["plan"]["catch_point"]["t_s"]
                - second["plan"]["catch_point"]["t_s"]),
            CATCH_POINT_SEPARATION_S - 1e-9)
        self.assertNotEqual(first["features"]["v_catch"],
                            second["features"]["v_catch"])
        self.assertEqual(first["free_flight"], second["free_flight"])
        self.assertEqual(_rows_of(out, name), _rows_of(self.root / "serial", name))
        self.assertEqual(len(_rows_of(out, f"{name}@2")), len(COARSE))
        with self.assertRaises(InputError):
            generate(OBJECTS[:1], out, catch_points=0, progress=False)

    def test_train_and_predict(self):
        """The tiny set trains, and the saved network predicts inside the
        parameter space for each sample."""
        from regrasp_drake.learning.learning_phase import predict
        from regrasp_drake.learning.train import train
        from regrasp_drake.station.mlp_system import load_weights
        out = self.root / "net" / "w.pt"
        report = train(self.root / "serial", out, epochs=200,
                       curve_png=self.root / "net" / "curve.png")
        self.assertTrue((self.root / "net" / "curve.png").stat().st_size > 1000)
        model, metadata = load_weights(out)
        self.assertEqual(metadata["features"],
                         ["v_catch", "h_cm", "r_cm", "d_obj", "v_conv"])
        self.assertLess(report["final_training_loss"], 1.0)
        rows = (self.root / "serial" / "samples.csv").read_text().splitlines()
        for line in rows[1:]:
            values = line.split(",")
            _, (h_catch, h_down) = predict(model, [float(v) for v in values[1:6]])
            self.assertTrue(0.0 <= h_catch <= 0.40 and -0.14 <= h_down <= 0.0)
        for name in ("network", "best_constant_cell", "mean_label"):
            self.assertIn(report["test"][name]["catch_rate"], (0.0, 0.5, 1.0))
        # Two objects cannot be split: the report says its figures are on
        # the training samples.
        self.assertFalse(report["held_out"])

    @unittest.skipUnless(importlib.util.find_spec("ray"),
                         "Ray is not installed (pip install '.[ray]')")
    def test_ray_same_rows_and_resumes(self):
        """--backend ray on a local Ray of 2 CPUs (RAY_ADDRESS unset): the
        serial run's rows and plans; an entry already in the directory is
        kept, not computed again."""
        out = self.root / "ray"
        kept = OBJECTS[0]
        for sub, suffix in (("plans", "json"), ("cells", "jsonl")):
            (out / sub).mkdir(parents=True)
            shutil.copy(self.root / "serial" / sub / f"{kept}.{suffix}",
                        out / sub)
        address = os.environ.pop("RAY_ADDRESS", None)
        try:
            provenance = generate(OBJECTS, out, workers=2, backend="ray",
                                  only=COARSE, progress=False)
        finally:
            if address is not None:
                os.environ["RAY_ADDRESS"] = address
        self.assertEqual(provenance["entries_computed"], 1)
        self.assertEqual(provenance["runs"][-1]["backend"], "ray")
        self.assertEqual(_rows(out), _rows(self.root / "serial"))
        for name in OBJECTS:
            self.assertEqual(
                (out / "plans" / f"{name}.json").read_text(),
                (self.root / "serial" / "plans" / f"{name}.json").read_text())
        self.assertEqual((out / "samples.csv").read_text(),
                         (self.root / "serial" / "samples.csv").read_text())
        import ray
        self.assertFalse(ray.is_initialized())  # the local Ray is shut down

    def test_killed_and_resumed_same_rows(self):
        out = self.root / "killed"
        code = ("from regrasp_drake.learning.dataset import generate; "
                f"generate({OBJECTS!r}, {str(out)!r}, workers=2, "
                f"only={COARSE!r}, progress=False)")
        process = subprocess.Popen([sys.executable, "-c", code],
                                   start_new_session=True,
                                   stderr=subprocess.DEVNULL)
        # Kill the whole run (workers and their children) once some cells
        # are written but not all.
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            written = sum(len(p.read_text().splitlines())
                          for p in (out / "cells").glob("*.jsonl")) \
                if (out / "cells").exists() else 0
            if written >= 3:
                break
            time.sleep(0.05)
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        written = sum(len(p.read_text().splitlines())
                      for p in (out / "cells").glob("*.jsonl"))
        self.assertLess(written, 2 * len(COARSE), "killed too late to test")
        generate(OBJECTS, out, workers=2, only=COARSE, progress=False)
        self.assertEqual(_rows(out), _rows(self.root / "serial"))
        for name in OBJECTS:  # no duplicate rows
            lines = (out / "cells" / f"{name}.jsonl").read_text().splitlines()
            cells = [tuple(json.loads(x)["cell"]) for x in lines
                     if x.strip().endswith("}")]
            self.assertEqual(len(cells), len(set(cells)))


# The data set on a real multi-node Ray cluster (Ray's own
# ray.cluster_utils.Cluster: a head and worker nodes, each a raylet of its
# own, on this machine), reached by its address (RAY_ADDRESS) as on a real
# cluster: the serial run's rows, plans and samples; and the same when a
# worker node dies in the middle of the run (its entry is computed again).
# In this module, so that no other Ray test runs beside it.
HAVE_RAY = importlib.util.find_spec("ray") is not None


@unittest.skipUnless(HAVE_RAY, "Ray is not installed (pip install '.[ray]')")
class RayClusterTest(unittest.TestCase):
    """Two objects on the coarse grid under the Fast scenario (1 ms step)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)
        cls.scenario = load_scenario(name="Fast")
        generate(OBJECTS, cls.root / "serial", workers=1, only=COARSE,
                 scenario=cls.scenario, progress=False)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def _cluster(self):
        """A head of 1 CPU and a worker node of 1 CPU; RAY_ADDRESS set to
        the head's address for the test's duration."""
        from ray.cluster_utils import Cluster
        cluster = Cluster(initialize_head=True, head_node_args={
            "num_cpus": 1, "include_dashboard": False})
        self.addCleanup(cluster.shutdown)
        worker = cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        previous = os.environ.get("RAY_ADDRESS")
        os.environ["RAY_ADDRESS"] = cluster.address
        self.addCleanup(self._restore, previous)
        return cluster, worker

    @staticmethod
    def _restore(previous):
        if previous is None:
            os.environ.pop("RAY_ADDRESS", None)
        else:
            os.environ["RAY_ADDRESS"] = previous

    def _check_same_as_serial(self, out: Path, provenance: dict):
        serial = self.root / "serial"
        self.assertEqual(provenance["entries_computed"], len(OBJECTS))
        self.assertEqual(provenance["runs"][-1]["backend"], "ray")
        for name in OBJECTS:
            # Each cell exactly once: no cell lost or written twice.
            lines = (out / "cells" / f"{name}.jsonl").read_text().splitlines()
            self.assertEqual(len(lines), len(COARSE))
            self.assertEqual(
                (out / "plans" / f"{name}.json").read_text(),
                (serial / "plans" / f"{name}.json").read_text())
        self.assertEqual(_rows(out), _rows(serial))
        self.assertEqual(sorted(cell for _, cell in _rows(out)),
                         sorted(COARSE * len(OBJECTS)))
        self.assertEqual((out / "samples.csv").read_text(),
                         (serial / "samples.csv").read_text())
        import ray
        self.assertFalse(ray.is_initialized())  # the driver disconnected

    def test_same_rows_on_a_two_node_cluster(self):
        self._cluster()
        out = self.root / "cluster"
        provenance = generate(OBJECTS, out, workers=2, backend="ray",
                              only=COARSE, scenario=self.scenario,
                              progress=False)
        self._check_same_as_serial(out, provenance)

    def test_a_worker_node_lost_mid_run(self):
        """The worker node is killed (as by a crash) while it computes an
        entry: the run still finishes, with the serial run's rows."""
        cluster, worker = self._cluster()
        out = self.root / "lost_node"
        killed = threading.Event()

        def busy():  # the worker node's CPU taken (by an entry's task)
            import ray
            from ray._private.state import available_resources_per_node
            if not ray.is_initialized():
                return False
            free = available_resources_per_node().get(worker.node_id)
            return free is not None and free.get("CPU", 0) == 0

        def kill_when_busy():
            deadline = time.monotonic() + 90
            while time.monotonic() < deadline:
                if busy():
                    time.sleep(1.0)  # inside the entry (a few seconds)
                    if busy():  # still computing it: kill -9 its node
                        cluster.remove_node(worker, allow_graceful=False)
                        killed.set()
                        return
                time.sleep(0.1)

        thread = threading.Thread(target=kill_when_busy, daemon=True)
        thread.start()
        provenance = generate(OBJECTS, out, workers=2, backend="ray",
                              only=COARSE, scenario=self.scenario,
                              progress=False)
        thread.join(timeout=5)
        self.assertTrue(killed.is_set(), "the worker node was not killed while busy")
        self._check_same_as_serial(out, provenance)


if __name__ == "__main__":
    unittest.main()
