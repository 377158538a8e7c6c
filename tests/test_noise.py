"""Release noise: none reproduces the deterministic throw; seeded noise is
reproducible; different throws of a run differ."""

import dataclasses as dc
import unittest

import numpy as np

from regrasp_drake.episode.episode import run_episode
from regrasp_drake.errors import InputError
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.scenario import ThrowNoise, validate
from tests.fixtures import Row2Fixture


def _with_noise(scenario, noise):
    return dc.replace(scenario, throw=dc.replace(scenario.throw, noise=noise))


class ThrowNoiseTest(Row2Fixture, unittest.TestCase):

    def _flight(self, scenario, throw_number=1):
        return run_episode(scenario, self.obj, ik=self.ik, X_WG=None,
                           throw_number=throw_number).logs.object_state

    def test_zero_noise_is_the_deterministic_throw(self):
        plain = self._flight(self.scenario)
        zero = self._flight(_with_noise(self.scenario, ThrowNoise(0.0, 0.0, 7)))
        np.testing.assert_array_equal(plain, zero)

    def test_seeded_noise_is_reproducible_and_moves_the_flight(self):
        noisy = _with_noise(self.scenario, ThrowNoise(0.005, 0.1, 3))
        a = self._flight(noisy, throw_number=2)
        b = self._flight(noisy, throw_number=2)
        np.testing.assert_array_equal(a, b)
        c = self._flight(noisy, throw_number=3)
        plain = self._flight(self.scenario)
        apex = [f[4:7, np.argmax(f[6])] for f in (a, c, plain)]
        # Each noisy apex is centimetres from the other and from the plain one.
        self.assertGreater(np.linalg.norm(apex[0] - apex[1]), 0.005)
        self.assertGreater(np.linalg.norm(apex[0] - apex[2]), 0.005)

    def test_pulse_peaks_at_the_release(self):
        p = ThrowPerturbation(0.0, (0.1, -0.2, 0.0, 0.0, 0.0, 0.3))
        dq, dv, da = p.pulse(0.31, 0.31)
        np.testing.assert_allclose(dv, [0.1, -0.2, 0, 0, 0, 0.3])
        np.testing.assert_allclose(da, 0.0, atol=1e-12)
        dq0, dv0, _ = p.pulse(0.0, 0.31)
        np.testing.assert_allclose(dq0, 0.0, atol=1e-12)
        np.testing.assert_allclose(dv0, 0.0, atol=1e-20)

    def test_bad_noise_refused(self):
        with self.assertRaisesRegex(InputError, "throw.noise.release_time_std_s"):
            validate(_with_noise(self.scenario, ThrowNoise(-0.1, 0.0, 0)))
        with self.assertRaisesRegex(InputError, "throw.noise.seed"):
            validate(_with_noise(self.scenario, ThrowNoise(0.0, 0.0, -1)))


if __name__ == "__main__":
    unittest.main()
