"""The heading's white noise read from the log (graphcal.data.noise), on uniform and on
sparse logs: what sets the heading's weight, so an overstated noise biases t_r and d."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.data.noise import heading_noise
from graphcal.data.quantization import quantization_sigma
from graphcal.model import THETA_NOMINAL
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive

WHITE = np.deg2rad(0.3)  # the heading_bias defect's white noise


@pytest.fixture(scope="module")
def counted():
    """6 km with a 0.3° fused heading (and its slow bias), 96-tick wheels, 10 Hz fixes."""
    drive = simulate_drive(6.0, seed=3)
    return degrade(drive, parse_defects("gnss10hz,heading_bias,ticks"), 3).measured


def test_a_uniform_logs_heading_noise_is_its_white_noise():
    drive = simulate_drive(6.0, seed=3)
    log = degrade(drive, parse_defects("heading_bias"), 3).measured
    assert heading_noise(log) == pytest.approx(WHITE, rel=0.1)


def test_sparse_headings_between_rows_of_fixes(counted):
    """Headings at most rows (not at a fix between rows): runs of consecutive rows."""
    assert counted.sparse
    assert heading_noise(counted, THETA_NOMINAL) == pytest.approx(WHITE, rel=0.1)


def test_headings_only_at_10_hz_discount_the_wheels_tick_rounding(counted):
    """Headings at 10 Hz only (every 4th row): measured against the wheels' yaw, whose
    96-tick rounding adds about 0.3° to each second difference. Discounted, the estimate is
    the heading's noise; not discounted it was 0.44° on a 24 km drive with every defect, and
    t_r and d came out 8–10σ off."""
    measured = counted.measured.copy()
    phase = (np.flatnonzero(measured[:, 0])[0] + 2) % 4  # midway between the fixes' rows
    measured[np.arange(len(measured)) % 4 != phase, 1] = False
    log = dataclasses.replace(counted, measured=measured)
    assert not (np.diff(np.flatnonzero(log.heading_measured)) == 1).any()
    rounding = quantization_sigma(96)
    found = heading_noise(log, THETA_NOMINAL, 0.0005, rounding)
    assert found == pytest.approx(WHITE, rel=0.15)
    assert heading_noise(log, THETA_NOMINAL) > 1.2 * WHITE  # the rounding not discounted


def test_position_noise_is_read_from_the_solve_and_used():
    """Fixes noisier than the settings assume (0.6 m against 0.2 m): the whole-log solve's
    residuals give the fixes' own noise, the log is solved again with it, and the σ is
    honest (χ²/dof about 1, the truth within 3σ)."""
    from graphcal.pipeline.run import run_calibration
    from graphcal.simulate.drive import NoiseLevels

    drive = simulate_drive(6.0, seed=4, noise=NoiseLevels(position=0.6))
    run = run_calibration(drive.measured, method="whole", workers=1)
    assert run.whole.position_noise == pytest.approx(0.6, rel=0.1)
    assert run.settings.joint.position_sigma == pytest.approx(0.6, rel=0.1)
    assert run.whole.chi2_per_dof == pytest.approx(1.0, abs=0.1)
    sigma = np.sqrt(np.diag(run.covariance))
    assert np.all(np.abs(run.theta - drive.theta_true) < 3 * sigma)
