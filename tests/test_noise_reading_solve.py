"""A whole-log solve under fix weights far too tight only reads the fixes' noise for the
next: its χ² to ``NOISE_READING_TOLERANCE`` or ``NOISE_READING_ITERATIONS`` iterations, no
time-offset rounds, which the solve under the noise it reads then takes to the end (campaign
seed 41's shape 36: a robot's 50 Hz fixes sharing 1.4 m crept 55, 52 and 70 iterations,
76 s, before their shared error was read; 28 s so, the same calibration)."""

from __future__ import annotations

import dataclasses

import numpy as np

import graphcal.pipeline.methods.runaways as runaways
import graphcal.pipeline.methods.whole_log as whole_log
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.end_to_end.trust import MAX_CHI2_PER_DOF
from graphcal.pipeline.solvers.joint_settings import TOLERANCE, JointSettings
from graphcal.simulate.drive import simulate_drive


def _wandering(log, sigma: float, tau: float, seed: int):
    """``log`` whose fixes share a Gauss–Markov error of ``sigma`` [m] per axis and
    correlation time ``tau`` [s]: second differences do not show it, residuals do."""
    rng = np.random.default_rng(seed)
    phi = np.exp(-float(log.dt) / tau)
    kick = sigma * np.sqrt(1.0 - phi**2) * rng.standard_normal((len(log.t), 2))
    error = np.zeros_like(kick)
    error[0] = sigma * rng.standard_normal(2)
    for k in range(1, len(error)):  # a test fixture's recursion, not a hot path
        error[k] = phi * error[k - 1] + kick[k]
    return dataclasses.replace(log, px=log.px + error[:, 0], py=log.py + error[:, 1])


def test_a_solve_under_far_wrong_fix_weights_only_reads_their_noise(monkeypatch):
    drive = simulate_drive(2.0, seed=2)
    log = _wandering(drive.measured, sigma=1.5, tau=30.0, seed=2)
    solves = []
    original = runaways.solve_with_time_offset

    def recorded(prepared, settings, workers=1, start=None, rounds=4, solved=None, stop_if=None):
        solves.append((settings.tolerance, settings.max_iterations, rounds, solved is None))
        return original(prepared, settings, workers, start, rounds, solved, stop_if)

    monkeypatch.setattr(runaways, "solve_with_time_offset", recorded)
    run = run_calibration(log, method="whole", workers=1)
    assert run.whole is not None
    # the first solve (one round, stopped to read the noise), the one under the fixes' RMS
    # that reads whether they share an error (loose, no rounds), then the solve to the end
    # (a few iterations: the noise it reads, not its theta, is what the next solve takes)
    limit = JointSettings().max_iterations
    assert [solve[:3] for solve in solves[:2]] == [
        (TOLERANCE, limit, 1),
        (whole_log.NOISE_READING_TOLERANCE, whole_log.NOISE_READING_ITERATIONS, 1),
    ]
    assert solves[-1] == (TOLERANCE, limit, whole_log.OFFSET_ROUNDS, True)
    assert run.settings.joint.tolerance == TOLERANCE
    assert run.settings.joint.max_iterations == limit
    assert run.settings.joint.fix_error_sigma > 0.5  # the error they share, read and modelled
    # the fit within the noise model (below 1: 40 fixes a second weighted for the error they
    # share within a chunk, not as 20 independent ones)
    assert 0.2 < run.whole.chi2_per_dof <= MAX_CHI2_PER_DOF
    calibrated = run.observability.calibrated
    sigma = np.sqrt(np.diag(run.covariance))
    assert calibrated.any()
    assert np.all(np.abs(run.theta - drive.theta_true)[calibrated] < 3 * sigma[calibrated])
