"""graphcal inside a GTSAM localization: keyframe odometry, smoothing, online, outages, TUM."""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np
import pytest
from numerical import retract_jacobian

import graphcal
from graphcal.errors import GraphcalError
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.localization.dead_reckoning import OutageSettings, outage_errors, outage_table
from graphcal.localization.keyframe_odometry import (
    keyframe_odometry_factor,
    keyframe_odometry_factors,
    odometry_covariance,
)
from graphcal.localization.online import OnlineSettings, run_online
from graphcal.localization.smoothing import SmoothingSettings, smooth_drive
from graphcal.localization.values import insert_states, insert_theta, states_from_values
from graphcal.log.tum import read_tum, write_tum
from graphcal.model import THETA_NOMINAL, integrate
from graphcal.simulate.drive import THETA_TRUE_DEFAULT, ThetaStep, simulate_drive


def test_public_names_all_resolve():
    for name in graphcal.__all__:
        assert getattr(graphcal, name) is not None, name
    with pytest.raises(AttributeError):
        graphcal.no_such_name  # noqa: B018


def test_keyframe_factor_jacobians_match_numerical_derivatives(drive):
    log = drive.measured
    a, b = 1000, 1008  # one 5 Hz interval of 40 Hz wheel data
    x0, x1, th = gtsam.symbol("x", 0), gtsam.symbol("x", 1), gtsam.symbol("t", 0)
    factor = keyframe_odometry_factor(x0, x1, th, log.inputs[a:b])
    values = gtsam.Values()
    # Off the solution, so the error is not zero and all Jacobian blocks matter.
    insert_states(values, [x0, x1], log.poses[[a, b]] + [0.3, -0.2, 0.05])
    insert_theta(values, th, THETA_TRUE_DEFAULT)
    linear = factor.linearize(values)
    numerical, columns = retract_jacobian(lambda v: factor.whitenedError(v), values, [x0, x1, th])
    analytic = linear.jacobian()[0]
    order = np.concatenate([columns[k] for k in (x0, x1, th)])
    np.testing.assert_allclose(analytic, numerical[:, order], rtol=1e-5, atol=1e-6)


def test_odometry_covariance_matches_monte_carlo(drive, rng):
    """The propagated wheel-noise covariance of one interval equals the spread of the end
    state when the rotations are perturbed by that noise."""
    inputs = drive.measured.inputs[2000:2040]  # one second, in a bend or not
    start = np.array([0.0, 0.0, 0.3])
    noise = 0.0005
    samples = np.repeat(inputs[None], 4000, axis=0)
    samples[..., :2] += noise * rng.standard_normal(samples[..., :2].shape)
    ends = integrate(np.tile(start, (4000, 1)), samples, THETA_NOMINAL)[:, -1]
    covariance = odometry_covariance(start, inputs, THETA_NOMINAL, noise, floor_sigmas=(0, 0, 0))
    np.testing.assert_allclose(np.cov(ends.T), covariance, rtol=0.1, atol=1e-12)


def test_keyframe_factors_reject_bad_keyframes(drive):
    log = drive.measured
    keys = [gtsam.symbol("x", i) for i in range(3)]
    with pytest.raises(GraphcalError, match="strictly increasing"):
        keyframe_odometry_factors(log, np.array([0, 8, 8]), keys, None)
    with pytest.raises(GraphcalError, match="3 keyframes but 2 pose keys"):
        keyframe_odometry_factors(log, np.array([0, 8, 16]), keys[:2], None)
    with pytest.raises(GraphcalError, match="within the log"):
        keyframe_odometry_factors(log, np.array([0, 8, len(log)]), keys, None)


@pytest.fixture(scope="module")
def short_drive():
    return simulate_drive(length_km=1.5, seed=7)


@pytest.mark.slow
def test_smoothing_with_5hz_gnss_recovers_theta_and_the_trajectory(short_drive):
    result = smooth_drive(short_drive.measured, SmoothingSettings(gnss_rate_hz=5.0))
    truth = short_drive.theta_true
    sigma = np.sqrt(np.diag(result.covariance))
    assert not result.observability.degenerate
    # Honest: the truth lies within 3σ; useful: σ well below the nominal-to-truth distance.
    assert np.all(np.abs(result.theta - truth) < 3 * sigma), (result.theta - truth) / sigma
    assert np.all(sigma < [0.5e-3, 0.3e-3, 15e-3, 0.2e-3])
    true_positions = short_drive.truth.poses[result.keyframes, :2]
    smoothed = np.hypot(*(result.states[:, :2] - true_positions).T)
    gnss = np.hypot(*(short_drive.measured.poses[result.keyframes, :2] - true_positions).T)
    assert np.sqrt(np.mean(smoothed**2)) < 0.4 * np.sqrt(np.mean(gnss**2))
    assert np.median(result.t[1:] - result.t[:-1]) == pytest.approx(0.2)


@pytest.fixture(scope="module")
def slipping_counted_log():
    """4 km whose wheels slip slowly (0.15 %) and are counted in 96 ticks per revolution."""
    from graphcal.log.validation import validate_frame
    from graphcal.simulate.defects import degrade, parse_defects

    drive = degrade(simulate_drive(4.0, 1), parse_defects("slip,ticks"), 1)
    return drive, validate_frame(drive.measured.to_dataframe(), "slip", 150.0)


@pytest.mark.slow
def test_smoothing_models_tick_rounding_and_slow_slip(slipping_counted_log):
    from graphcal.log.quantization import quantization_sigma

    drive, log = slipping_counted_log
    modelled = SmoothingSettings(tick_quantization=quantization_sigma(96), slip_sigma=0.0015)

    def z(settings: SmoothingSettings) -> np.ndarray:
        result = smooth_drive(log, settings)
        assert np.all(result.observability.calibrated)
        return np.abs(result.theta - drive.theta_true) / np.sqrt(np.diag(result.covariance))

    assert z(modelled).max() < 3.0
    assert z(SmoothingSettings()).max() > 5.0  # white wheel noise only: confidently wrong


@pytest.mark.slow
def test_online_covers_tick_rounding_and_slow_slip(slipping_counted_log):
    from graphcal.log.quantization import quantization_sigma

    drive, log = slipping_counted_log
    modelled = OnlineSettings(tick_quantization=quantization_sigma(96), slip_sigma=0.0015)

    def within_3_sigma(settings: OnlineSettings) -> np.ndarray:
        result = run_online(log, settings)
        settled = result.distance_m > 1000.0
        z = (result.theta[settled] - drive.theta_true) / result.sigma[settled]
        return np.mean(np.abs(z) <= 3.0, axis=0)  # share of theta slices, per parameter

    assert within_3_sigma(modelled).min() >= 0.95
    assert within_3_sigma(OnlineSettings()).min() < 0.8  # white wheel noise only


@pytest.mark.slow
def test_prepare_localization_hands_over_the_calibrations_findings():
    from dataclasses import fields

    from graphcal.log.validation import validate_frame
    from graphcal.simulate.defects import degrade, parse_defects

    drive = degrade(simulate_drive(2.0, 3), parse_defects("latency,lever_arm"), 3)
    log = validate_frame(drive.measured.to_dataframe(), "sensors", 150.0)
    corrected, wheels, summary = graphcal.prepare_localization(log)
    assert "time_offset" in summary and "(detected, corrected)" in summary
    assert set(wheels) <= {f.name for f in fields(SmoothingSettings)}
    assert set(wheels) <= {f.name for f in fields(OnlineSettings)}
    assert np.abs(wheels["theta_initial"] - drive.theta_true)[0] < 1e-3  # c_e within 1 mm
    # Positions moved to the centre of gravity: nearer the truth than the antenna's.
    before = np.hypot(*(log.poses[:, :2] - drive.truth.poses[:, :2]).T).mean()
    after = np.hypot(*(corrected.poses[:, :2] - drive.truth.poses[:, :2]).T).mean()
    assert after < 0.5 * before


@pytest.mark.slow
def test_python_driven_lm_matches_gtsams_optimizer(short_drive):
    from graphcal.graph.construction.keys import THETA
    from graphcal.graph.optimization.solve import solve_lm
    from graphcal.localization.smoothing import build_smoothing_graph

    graph, values, _ = build_smoothing_graph(short_drive.measured, SmoothingSettings())
    ours, ours_iterations = solve_lm(
        graph, values, SolveOptions(50, 1e-8, "smoothing"), driver="python"
    )
    theirs, their_iterations = solve_lm(
        graph, values, SolveOptions(50, 1e-8, "smoothing"), driver="gtsam"
    )
    assert ours_iterations.iterations == their_iterations.iterations
    assert graph.error(ours) == pytest.approx(graph.error(theirs), rel=1e-9)
    np.testing.assert_allclose(ours.atVector(THETA), theirs.atVector(THETA), rtol=1e-9)


def test_states_round_trip_through_values_with_unwrapped_heading():
    states = np.array([[0.0, 0.0, 3.0], [1.0, 0.5, 3.3], [2.0, 1.5, 3.6]])  # crosses +π
    keys = [gtsam.symbol("x", i) for i in range(3)]
    values = gtsam.Values()
    insert_states(values, keys, states)
    np.testing.assert_allclose(states_from_values(values, keys, 3.0), states, atol=1e-12)


@pytest.mark.slow
def test_online_estimate_follows_a_tyre_pressure_drop():
    after = THETA_TRUE_DEFAULT + [-0.003, 0.0, 0.0, 0.0]
    drive = simulate_drive(length_km=3.5, seed=11, theta_change=ThetaStep(1.5, after))
    result = run_online(drive.measured, OnlineSettings())
    last_km = result.distance_m > result.distance_m[-1] - 1000.0
    assert np.all(np.abs(result.theta[last_km, 0] - after[0]) < 1e-3)
    before = (result.distance_m > 700.0) & (result.distance_m < 1400.0)
    assert np.all(np.abs(result.theta[before, 0] - THETA_TRUE_DEFAULT[0]) < 1e-3)
    settled = result.distance_m > 700.0
    assert np.all(np.isfinite(result.sigma)) and np.all(result.sigma[settled, 0] < 1e-3)


def test_calibrated_theta_cuts_the_dead_reckoning_error_of_an_outage(short_drive):
    thetas = {"nominal": THETA_NOMINAL, "true": short_drive.theta_true}
    settings = OutageSettings(durations_s=(30.0,), spacing_s=30.0)
    errors = outage_errors(short_drive.measured, short_drive.truth, thetas, settings)
    table = outage_table(errors)
    final = table.loc[30.0, "final_error_m"]
    assert final["true"] < final["nominal"] / 3
    assert set(errors.columns) >= {"theta", "duration_s", "final_error_m", "mean_error_m"}


def test_tum_round_trip(tmp_path):
    t = np.array([0.0, 0.2, 0.4])
    states = np.array([[0.0, 0.0, 3.1], [1.0, 0.5, -3.1], [2.0, 1.0, 0.2]])
    path = write_tum(tmp_path / "x.tum", t, states, "a comment")
    lines = path.read_text().splitlines()
    assert lines[0] == "# timestamp tx ty tz qx qy qz qw" and len(lines) == 5
    assert len(lines[-1].split()) == 8
    t2, states2 = read_tum(path)
    np.testing.assert_allclose(t2, t)
    np.testing.assert_allclose(states2[:, :2], states[:, :2], atol=1e-9)
    # Headings come back unwrapped, as graphcal's states are: -3.1 follows 3.1 as 2π − 3.1.
    np.testing.assert_allclose(states2[:, 2], np.unwrap(states[:, 2]), atol=1e-9)
    assert states2[1, 2] == pytest.approx(2 * np.pi - 3.1)
    with pytest.raises(GraphcalError, match="NaN"):
        write_tum(tmp_path / "bad.tum", t, states * np.nan)
    assert not (tmp_path / "bad.tum").exists()


@pytest.mark.slow
def test_smoothing_estimates_the_lever_arm_and_ignores_flagged_spikes():
    from graphcal.log.validation import validate_frame
    from graphcal.simulate.defects import degrade, parse_defects

    drive = degrade(simulate_drive(2.0, 3), parse_defects("lever_arm,outliers"), 3)
    log = validate_frame(drive.measured.to_dataframe(), "arm", 150.0)
    assert log.outlying is not None and log.outlying.any()
    result = smooth_drive(log, SmoothingSettings(lever_arm_sigma=2.0))
    arm, covariance = result.lever_arm
    assert abs(arm[0] - 1.2) < 0.2 and abs(arm[1]) < 0.2
    assert abs(arm[0] - 1.2) < 3 * np.sqrt(covariance[0, 0]) + 0.02
    sigma = np.sqrt(np.diag(result.covariance))
    calibrated = result.observability.calibrated
    error = np.abs(result.theta - drive.theta_true)
    assert np.all(error[calibrated] < 3 * sigma[calibrated])


@pytest.mark.slow
def test_smoothing_a_log_with_sparse_fixes_uses_each_fix_at_its_own_time(short_drive):
    """10 Hz fixes 5–20 ms before their rows, no heading: keyframes at the fixes' rows, a GNSS
    factor per fix at its own time (the distance driven since, behind the pose), no heading
    prior. theta within 3σ; ignoring the fixes' times would put the smoothed track a
    lag's travel behind the truth."""
    from graphcal.graph.construction.keyframes import fix_offsets, gnss_keyframes
    from graphcal.simulate.defects import degrade, parse_defects

    log = degrade(short_drive, parse_defects("gnss10hz"), 2).measured
    log = dataclasses.replace(log, measured=log.measured & [True, False])  # no heading
    from graphcal.localization.smoothing import build_smoothing_graph

    settings = SmoothingSettings(gnss_rate_hz=10.0, heading_sigma=0.01)
    keyframes = gnss_keyframes(log, settings.gnss_rate_hz)
    np.testing.assert_array_equal(keyframes, np.flatnonzero(log.position_measured))
    offsets = fix_offsets(log, keyframes, 2.0)
    assert np.all(offsets[1:] < 0)  # every fix before its row (a random phase, 10 Hz)
    result = smooth_drive(log, settings)
    sigma = np.sqrt(np.diag(result.covariance))
    error = result.theta - short_drive.theta_true
    assert np.all(np.abs(error) < 3 * sigma), error / sigma
    graph, _, _ = build_smoothing_graph(log, settings)
    heading_priors = sum(
        isinstance(graph.at(i), gtsam.PoseRotationPrior2D) for i in range(graph.size())
    )
    assert heading_priors == 0
    true_positions = short_drive.truth.poses[result.keyframes, :2]
    behind = np.hypot(*(result.states[:, :2] - true_positions).T)
    assert np.median(behind) < 0.08  # measured 0.03 m; 0.17 m with the fix times ignored
