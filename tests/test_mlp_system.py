import os
import tempfile
import unittest

import numpy as np
import torch
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from regrasp_drake.errors import InputError
from regrasp_drake.station.mlp_system import (
    CatchMlp,
    MlpSystem,
    ParameterSpace,
    load_weights,
    save_weights,
)


class NotAWeight:
    """A custom class: a file that pickles one must not load."""

    def __reduce__(self):
        return (os.getcwd, ())


def _trained_model(seed=0):
    """A CatchMlp with random weights and a normalization fitted to features
    and parameters of the paper's scale."""
    torch.manual_seed(seed)
    model = CatchMlp()
    features = torch.rand(50, 5, dtype=torch.float64) * torch.tensor(
        [3.0, 0.1, 0.05, 0.1, 1.0], dtype=torch.float64
    )
    parameters = torch.rand(50, 2, dtype=torch.float64) * torch.tensor(
        [0.4, -0.14], dtype=torch.float64
    )
    model.set_normalization(features, parameters)
    return model


class WeightsFileTest(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.TemporaryDirectory()
        self.path = os.path.join(self.dir.name, "catch_mlp.pt")

    def tearDown(self):
        self.dir.cleanup()

    def test_round_trip_gives_identical_outputs(self):
        model = _trained_model()
        metadata = {"trained_on": "unit test", "episodes": 50, "loss": 0.125}
        save_weights(self.path, model, metadata)
        loaded, loaded_metadata = load_weights(self.path)
        self.assertEqual(loaded_metadata, metadata)
        x = torch.randn(20, 5, dtype=torch.float64)
        with torch.no_grad():
            self.assertTrue(torch.equal(model(x), loaded(x)))
        # The normalization is part of the file.
        self.assertTrue(torch.equal(model.input_std, loaded.input_std))
        self.assertFalse(torch.equal(loaded.input_std, CatchMlp().input_std))

    def test_missing_file_is_refused(self):
        with self.assertRaisesRegex(InputError, "no such weights file") as cm:
            load_weights(self.path)
        self.assertIn(self.path, str(cm.exception))

    def test_directory_is_refused(self):
        directory = os.path.dirname(self.path)
        with self.assertRaises(InputError) as cm:
            load_weights(directory)
        self.assertEqual(str(cm.exception),
                         f"{directory}: a directory, expected a weights file")

    def test_random_bytes_are_refused(self):
        with open(self.path, "wb") as f:
            f.write(np.random.default_rng(1).bytes(4096))
        with self.assertRaises(InputError) as cm:
            load_weights(self.path)
        self.assertIn(self.path, str(cm.exception))
        self.assertNotIn("\n", str(cm.exception))

    def test_wrong_shaped_tensor_is_refused(self):
        save_weights(self.path, _trained_model(), {})
        data = torch.load(self.path, weights_only=True)
        data["state_dict"]["hidden.weight"] = torch.zeros(12, 5, dtype=torch.float64)
        torch.save(data, self.path)
        with self.assertRaisesRegex(
            InputError, r"hidden\.weight shape.*\(12, 5\).*\(13, 5\)"
        ) as cm:
            load_weights(self.path)
        self.assertIn(self.path, str(cm.exception))

    def test_absurd_magnitudes_are_refused_when_loaded(self):
        # Finite but absurd values would make the network's output
        # non-finite only in the episode, after the watching throw.
        for name, value, message in (
                ("hidden.weight", 1e6, r"hidden\.weight magnitude: got "
                 r"1000000\.0, expected at most 10000"),
                ("input_std", 0.0, r"input_std minimum: got 0\.0, expected "
                 r"at least 1e-09")):
            with self.subTest(name=name):
                save_weights(self.path, _trained_model(), {})
                data = torch.load(self.path, weights_only=True)
                data["state_dict"][name].view(-1)[0] = value
                torch.save(data, self.path)
                with self.assertRaisesRegex(InputError, message) as cm:
                    load_weights(self.path)
                self.assertEqual(len(str(cm.exception).splitlines()), 1)

    def test_missing_tensor_is_refused(self):
        save_weights(self.path, _trained_model(), {})
        data = torch.load(self.path, weights_only=True)
        del data["state_dict"]["output_std"]
        torch.save(data, self.path)
        with self.assertRaisesRegex(InputError, "output_std missing"):
            load_weights(self.path)

    def test_pickled_code_is_refused(self):
        save_weights(self.path, _trained_model(), {})
        data = torch.load(self.path, weights_only=True)
        data["metadata"] = {"note": NotAWeight()}
        torch.save(data, self.path)  # A full pickle would load this class.
        with self.assertRaisesRegex(InputError, "weights_only") as cm:
            load_weights(self.path)
        self.assertIn(self.path, str(cm.exception))
        # The unpickler's reason, not torch's advice to load without the guard.
        self.assertIn("unsupported GLOBAL posix.getcwd", str(cm.exception))
        self.assertNotIn("set to `False`", str(cm.exception))
        # Unpickled without the guard, the file would run os.getcwd.
        unguarded = torch.load(self.path, weights_only=False)
        self.assertEqual(unguarded["metadata"]["note"], os.getcwd())

    def test_metadata_must_be_json(self):
        with self.assertRaisesRegex(InputError, "metadata"):
            save_weights(self.path, _trained_model(), {"x": object()})


class ParameterSpaceTest(unittest.TestCase):
    def test_clamp(self):
        space = ParameterSpace()
        self.assertEqual(space.clamp(0.2, -0.05), (0.2, -0.05))
        self.assertEqual(space.clamp(0.9, 0.3), (0.40, 0.0))
        self.assertEqual(space.clamp(-1.0, -1.0), (0.0, -0.14))
        with self.assertRaises(InputError):
            space.clamp(float("nan"), 0.0)


class MlpSystemTest(unittest.TestCase):
    def _run_system(self, system, features):
        builder = DiagramBuilder()
        builder.AddSystem(system)
        source = builder.AddSystem(
            ConstantVectorSource(np.asarray(features, dtype=float))
        )
        builder.Connect(source.get_output_port(), system.get_input_port())
        diagram = builder.Build()
        simulator = Simulator(diagram)
        context = simulator.get_mutable_context()
        output = system.get_output_port()
        system_context = system.GetMyContextFromRoot(context)
        before = output.Eval(system_context).copy()
        simulator.Initialize()
        at_start = output.Eval(system_context).copy()
        simulator.AdvanceTo(0.05)
        return before, at_start, output.Eval(system_context).copy()

    def test_output_is_the_clamped_forward_pass(self):
        model = _trained_model()
        space = ParameterSpace()
        features = [2.0, 0.05, 0.03, 0.06, 0.5]
        before, at_start, later = self._run_system(MlpSystem(model, space), features)
        with torch.no_grad():
            h_catch, h_down = model(
                torch.tensor(features, dtype=torch.float64)
            ).tolist()
        np.testing.assert_array_equal(at_start, space.clamp(h_catch, h_down))
        np.testing.assert_array_equal(later, at_start)
        self.assertTrue(np.isnan(before).all())  # Not computed before Initialize.

    def test_outputs_stay_in_the_parameter_space(self):
        space = ParameterSpace()
        rng = np.random.default_rng(3)
        system = MlpSystem(_trained_model(seed=7), space)
        outside = 0
        for scale in [1.0, 1e3, 1e8]:
            for features in rng.normal(scale=scale, size=(200, 5)):
                with torch.no_grad():
                    raw = system._model(torch.tensor(features)).tolist()
                outside += not (0.0 <= raw[0] <= 0.4 and -0.14 <= raw[1] <= 0.0)
                h_catch, h_down = system.parameters_for(features)
                self.assertTrue(space.h_catch_min <= h_catch <= space.h_catch_max)
                self.assertTrue(space.h_down_min <= h_down <= space.h_down_max)
        # The clamp mattered: the raw network left the space for some inputs.
        self.assertGreater(outside, 0)



class ShippedWeightsTest(unittest.TestCase):
    def test_shipped_network_predicts_inside_the_parameter_space(self):
        import csv

        from regrasp_drake.learning.learning_phase import predict
        from regrasp_drake.paths import MODELS_DIR
        model, metadata = load_weights(MODELS_DIR / "catch_mlp.pt")
        self.assertEqual(metadata["hidden"], 13)
        with (MODELS_DIR / "dataset" / "samples.csv").open() as f:
            rows = list(csv.DictReader(f))
        self.assertGreaterEqual(len(rows), 40)
        for row in rows:
            features = [float(row[k]) for k in
                        ("v_catch", "h_cm", "r_cm", "d_obj", "v_conv")]
            _, (h_catch, h_down) = predict(model, features)
            self.assertTrue(0.0 <= h_catch <= 0.40, row["object"])
            self.assertTrue(-0.14 <= h_down <= 0.0, row["object"])


if __name__ == "__main__":
    unittest.main()
