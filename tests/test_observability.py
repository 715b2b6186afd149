"""Degeneracy detection: which parameters a drive determines, and what the CLI says."""

from __future__ import annotations

import json

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.evaluation import cramer_rao_bound
from graphcal.graph.observability import assess_observability
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL
from graphcal.pipeline.joint import JointSettings, calibrate_joint
from graphcal.pipeline.run import run_calibration
from graphcal.pipeline.settings import BatchingSettings, Settings
from graphcal.simulate.drive import simulate_drive

PRIOR = np.array([0.1, 0.01, 0.2, 0.01])


def test_parameters_left_at_their_prior_are_not_calibrated():
    # c_e and c_d shrunk 1000× and 100×, t_r barely, d not at all.
    sigma = PRIOR * [1e-3, 1e-2, 0.9, 1.0]
    verdict = assess_observability(np.diag(sigma**2), PRIOR)
    assert verdict.not_calibrated == ["t_r", "d"] and verdict.degenerate
    assert verdict.verdicts()["c_e"] == "calibrated"
    assert "t_r not observable" in verdict.message() and "d not observable" in verdict.message()
    # The unobservable directions are t_r and d themselves.
    assert len(verdict.weak_directions) == 2
    assert np.allclose(np.abs(verdict.weak_directions[:, 2:]).sum(axis=1), 1.0, atol=1e-9)


def test_a_parameter_tied_to_an_unobservable_one_is_named_with_it():
    # c_d known only relative to t_r: correlation 0.99 with an unobservable t_r.
    sigma = PRIOR * [1e-3, 0.05, 0.95, 1e-2]
    correlation = np.eye(4)
    correlation[1, 2] = correlation[2, 1] = 0.99
    verdict = assess_observability(correlation * np.outer(sigma, sigma), PRIOR)
    assert verdict.verdicts()["c_d"] == "calibrated given t_r = prior (σ conditional)"
    assert verdict.verdicts()["t_r"] == "not observable"
    assert "c_d holds only given t_r = prior" in verdict.message()


def _covariance(ratio, correlations):
    """Theta's posterior covariance (SI) with σ = ``ratio`` × prior σ and the given
    ``{(i, j): ρ}``."""
    correlation = np.eye(4)
    for (i, j), rho in correlations.items():
        correlation[i, j] = correlation[j, i] = rho
    sigma = PRIOR * np.asarray(ratio, float)
    return correlation * np.outer(sigma, sigma)


def _held_at(covariance, calibrated, prior_mean):
    from graphcal.graph.observability import condition_on_prior

    return condition_on_prior(THETA_NOMINAL, covariance, calibrated, prior_mean, PRIOR)


def test_a_moderate_correlation_with_a_barely_determined_parameter_is_named():
    """d correlated only 0.6 with t_r, which the data shrank to half its prior σ: were t_r's
    prior one σ off, d (held at t_r's prior) would move by 1.5 of its conditional σ — so
    its value and σ hold only given t_r = prior, and the verdict says so."""
    covariance = _covariance([1e-3, 1e-2, 0.5, 0.05], {(3, 2): 0.6})
    verdict = assess_observability(covariance, PRIOR)
    assert verdict.not_calibrated == ["t_r"]
    assert verdict.verdicts()["d"] == "calibrated given t_r = prior (σ conditional)"
    assert verdict.verdicts()["c_e"] == "calibrated"
    # What the verdict claims, measured: move t_r's prior by one σ, d moves by 1.5 σ.
    calibrated = verdict.calibrated
    held, conditioned = _held_at(covariance, calibrated, THETA_NOMINAL)
    moved, _ = _held_at(covariance, calibrated, THETA_NOMINAL + [0, 0, PRIOR[2], 0])
    shift = abs(moved[3] - held[3]) / np.sqrt(conditioned[3, 3])
    assert shift == pytest.approx(1.5, rel=1e-9)
    assert verdict.prior_shifts()[3, 2] == pytest.approx(shift, rel=1e-9)


def test_two_unobservable_parameters_are_both_named():
    covariance = _covariance([1e-3, 0.05, 0.9, 0.9], {(1, 2): 0.6, (1, 3): -0.6})
    verdict = assess_observability(covariance, PRIOR)
    assert verdict.verdicts()["c_d"] == "calibrated given t_r, d = prior (σ conditional)"


@pytest.mark.slow
def test_a_4_km_day_names_what_c_d_holds_only_given():
    """A 4 km city day where neither t_r nor d is observable: c_d, conditioned on them at
    their prior, is nearly 6 of its σ from its truth. Its verdict says that its value and σ
    hold only given t_r and d at their prior (the former rule called it calibrated)."""
    drive = simulate_drive(length_km=4.0, seed=56)
    run = run_calibration(drive.measured, Settings(), "whole", workers=1)
    verdicts = run.verdicts()
    assert verdicts["t_r"] == verdicts["d"] == "not observable"
    assert verdicts["c_d"] == "calibrated given t_r, d = prior (σ conditional)"
    error = abs(run.theta[1] - drive.theta_true[1]) / np.sqrt(run.covariance[1, 1])
    assert error > 3
    assert verdicts["c_e"] == "calibrated"  # a prior one σ off moves it by < 1 σ


def test_a_city_batch_determines_every_parameter(drive):
    log = drive.measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    result = calibrate_joint(data.take(np.arange(3)))
    assert not result.observability.degenerate
    assert np.all(result.observability.sigma_ratio < 0.1)


@pytest.mark.slow
def test_cramer_rao_bound_matches_the_reported_covariance(drive):
    """At the paper's noise the problem is nearly linear: the covariance at the estimate is the
    bound at the truth to a few per cent, and both are far below the prior."""
    log = drive.measured
    segments = select_segments(log, split_segments(log, 150.0))
    data, truth = gather_segments(log, segments), gather_segments(drive.truth, segments)
    batch = np.arange(3)
    settings = JointSettings()
    result = calibrate_joint(data.take(batch), settings)
    bound = cramer_rao_bound(data.take(batch), truth.take(batch), drive.theta_true, settings)
    np.testing.assert_allclose(np.sqrt(np.diag(bound)), result.theta_sigma, rtol=0.05)
    assert np.all(np.sqrt(np.diag(bound)) < 0.1 * PRIOR)


@pytest.fixture(scope="module")
def straight_drive():
    """A noisy 2 km drive on a straight road (paper noise levels)."""
    return simulate_drive(length_km=2.0, seed=5, route="straight")


@pytest.mark.slow
def test_straight_drive_run_keeps_unobservable_parameters_at_the_prior(straight_drive):
    settings = Settings(batches=BatchingSettings(count=3))
    run = run_calibration(straight_drive.measured, settings, "joint", workers=1)
    assert run.observability.not_calibrated == ["t_r", "d"]
    np.testing.assert_array_equal(run.theta[2:], THETA_NOMINAL[2:])
    error = np.abs(run.theta[:2] - straight_drive.theta_true[:2])
    assert np.all(error < 4 * np.sqrt(np.diag(run.covariance))[:2]), error
    # Every batch is degenerate: all are left out, each with its reason.
    assert list(run.batch_excluded["joint"]) == ["not observable: t_r, d"] * 3
    assert any("t_r, d not calibrated" in w for w in run.warnings)


@pytest.mark.slow
def test_cli_straight_drive_names_what_it_cannot_calibrate(tmp_path, capsys):
    log = tmp_path / "straight.csv"
    assert main(["simulate", "--route", "straight", "--length-km", "2", "--seed", "5",
                 "--out", str(log)]) == 0  # fmt: skip
    out = tmp_path / "out"
    assert main(["calibrate", str(log), "--out", str(out), "--batches", "0",
                 "--method", "joint"]) == 0  # fmt: skip
    printed = capsys.readouterr()
    calibrated_row = next(line for line in printed.out.splitlines() if line.startswith("calibr"))
    cells = calibrated_row.split()
    assert cells[3:] == ["n/o", "n/o"]  # t_r and d: no number presented as calibrated
    assert "no segment passes the yaw-rate selection" in printed.err
    doc = json.loads((out / "calibration.json").read_text())
    assert doc["method"] == "whole"
    status = {name: doc["parameters"][name]["status"] for name in PARAMETER_NAMES}
    assert status["c_e"].startswith("calibrated") and status["c_d"].startswith("calibrated")
    for name in ("t_r", "d"):
        assert status[name].startswith("not calibrated")
        assert doc["parameters"][name]["sigma"] is None
    truth = doc.get("theta_true")
    assert truth is not None
    for name, tolerance in (("c_e", 0.6e-3), ("c_d", 0.3e-3)):
        entry = doc["parameters"][name]
        low, high = entry["ci95"]
        assert low < entry["value"] < high and high - low < 2 * tolerance
        assert abs(entry["value"] - truth[name]) < tolerance


def test_holding_an_unobservable_parameter_at_its_prior_conditions_the_others(rng):
    """Gaussian conditioning: the calibrated block's covariance is the inverse of its
    information block, and the estimate moves along the correlation."""
    from graphcal.graph.observability import condition_on_prior

    root = rng.standard_normal((4, 4))
    covariance = root @ root.T * 1e-6 + np.diag(PRIOR**2) * [0, 0, 0.9, 0]
    theta = THETA_NOMINAL + [1e-3, 2e-4, 0.05, 1e-4]
    calibrated = np.array([True, True, False, True])
    held, conditioned = condition_on_prior(theta, covariance, calibrated, THETA_NOMINAL, PRIOR)
    c = np.flatnonzero(calibrated)
    information = np.linalg.inv(covariance)
    np.testing.assert_allclose(
        conditioned[np.ix_(c, c)], np.linalg.inv(information[np.ix_(c, c)]), rtol=1e-9
    )
    assert held[2] == THETA_NOMINAL[2] and conditioned[2, 2] == PRIOR[2] ** 2
    # The shift is what the information form gives: x_c = θ_c − I_cc⁻¹ I_cu (μ_u − θ_u).
    shift = -np.linalg.solve(information[np.ix_(c, c)], information[c, 2]) * (
        THETA_NOMINAL[2] - theta[2]
    )
    np.testing.assert_allclose(held[c], theta[c] + shift, rtol=1e-9)
