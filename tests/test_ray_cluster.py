"""The data set on a real multi-node Ray cluster (Ray's own
ray.cluster_utils.Cluster: a head and worker nodes, each a raylet of its
own, on this machine), reached by its address (RAY_ADDRESS) as on a real
cluster: the serial run's rows, plans and samples; and the same when a
worker node dies in the middle of the run (its entry is computed again)."""

import importlib.util
import os
import tempfile
import threading
import time
import unittest
from pathlib import Path

from regrasp_drake.learning.dataset import generate
from regrasp_drake.station.scenario import load_scenario, scenario_yaml
from tests.test_dataset import COARSE, OBJECTS, _rows

HAVE_RAY = importlib.util.find_spec("ray") is not None


@unittest.skipUnless(HAVE_RAY, "Ray is not installed (pip install '.[ray]')")
class RayClusterTest(unittest.TestCase):
    """Two objects on the coarse grid under the Fast scenario (1 ms step)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)
        cls.scenario = cls.root / "fast.yaml"
        cls.scenario.write_text(scenario_yaml(load_scenario(name="Fast")))
        generate(OBJECTS, cls.root / "serial", workers=1, only=COARSE,
                 scenario_path=cls.scenario, progress=False)

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
                              only=COARSE, scenario_path=self.scenario,
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
                              only=COARSE, scenario_path=self.scenario,
                              progress=False)
        thread.join(timeout=5)
        self.assertTrue(killed.is_set(), "the worker node was not killed while busy")
        self._check_same_as_serial(out, provenance)


if __name__ == "__main__":
    unittest.main()
