"""The wheel-vs-pose time offset: undone by interpolation of the cumulative rotation."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.log.timing import shift_wheel_rotations
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


@pytest.fixture(scope="module")
def clean():
    return simulate_drive(4.0, 1)


@pytest.fixture(scope="module")
def late(clean):
    return degrade(clean, parse_defects("latency"), 1)  # wheels 0.05 s late


def test_shifting_the_wheels_undoes_a_latency(clean, late):
    truth = clean.truth
    undone = shift_wheel_rotations(late.measured, 0.05)
    inner = slice(10, -10)  # the ends continue at the edge rates
    residual = undone.n_rl[inner] - truth.n_rl[inner]
    late_residual = late.measured.n_rl[inner] - truth.n_rl[inner]
    assert np.std(residual) < 1.2 * clean.noise.wheel_rotation  # only the white noise is left
    assert np.std(late_residual) > 1.5 * np.std(residual)  # 0.05 s late: 1.9x here
    np.testing.assert_allclose(undone.n_rl.sum(), late.measured.n_rl.sum(), rtol=1e-3)
