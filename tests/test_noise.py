"""The heading's white noise read from the log (graphcal.log.noise), on uniform and on
sparse logs: what sets the heading's weight, so an overstated noise biases t_r and d."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.log.noise import heading_noise
from graphcal.log.quantization import quantization_sigma
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


def _headings_every(log, rows: int):
    """``log`` with its heading kept at every ``rows``-th row only, midway between fixes."""
    measured = log.measured.copy()
    phase = (np.flatnonzero(measured[:, 0])[0] + 2) % rows
    measured[np.arange(len(measured)) % rows != phase, 1] = False
    return dataclasses.replace(log, measured=measured)


def test_headings_at_10_hz_are_measured_on_their_own(counted):
    """10 Hz headings: their own second differences (the motion over 0.1 s is far below
    0.3°), whatever the wheels' ticks."""
    log = _headings_every(counted, 4)
    assert heading_noise(log, THETA_NOMINAL) == pytest.approx(WHITE, rel=0.1)


def test_headings_at_1_hz_discount_the_wheels_tick_rounding():
    """1 Hz headings: measured against the wheels' yaw (nominal theta), whose 96-tick
    rounding adds about 0.3° to each second difference. The discount takes the rounding out
    without understating the noise (an understated heading noise overweights the heading:
    0.11–0.15° for 0.3° put t_r 6–23σ off); what remains over 1 s is the nominal yaw's own
    error (t_r, the load transfer), an overstatement (0.42° here)."""
    defects = dataclasses.replace(parse_defects("gnss10hz,ticks"), heading_white=WHITE)
    log = _headings_every(degrade(simulate_drive(6.0, seed=3), defects, 3).measured, 40)
    rounding = quantization_sigma(96)
    discounted = heading_noise(log, THETA_NOMINAL, 0.0005, rounding)
    assert 0.95 * WHITE < discounted < heading_noise(log, THETA_NOMINAL)


@pytest.mark.slow
def test_position_noise_is_read_from_the_solve_and_used():
    """Fixes noisier than the settings assume (0.6 m against 0.2 m): the whole-log solve's
    residuals give the fixes' own noise, the log is solved again with it, and the σ is
    honest (χ²/dof about 1, the truth within 3σ)."""
    from graphcal.pipeline.end_to_end.run import run_calibration
    from graphcal.simulate.drive import NoiseLevels

    drive = simulate_drive(6.0, seed=4, noise=NoiseLevels(position=0.6))
    run = run_calibration(drive.measured, method="whole", workers=1)
    assert run.whole.position_noise == pytest.approx(0.6, rel=0.1)
    assert run.settings.joint.position_sigma == pytest.approx(0.6, rel=0.1)
    assert run.whole.chi2_per_dof == pytest.approx(1.0, abs=0.1)
    sigma = np.sqrt(np.diag(run.covariance))
    assert np.all(np.abs(run.theta - drive.theta_true) < 3 * sigma)
    from graphcal.report.document import results_document

    noise = results_document(run)["noise"]  # reported with the result
    assert noise["position_sigma_m"] == pytest.approx(0.6, rel=0.1)
    assert noise["heading_sigma_deg"] == pytest.approx(1.5, rel=0.15)  # the drive's heading
