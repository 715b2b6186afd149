"""Preintegrated wheel odometry and its factor (like PreintegratedImuMeasurements, ImuFactor)."""

from __future__ import annotations

import itertools

import gtsam
import numpy as np
import pytest
from numerical import retract_jacobian

from graphcal.factors.preintegration import PreintegratedWheelOdometry
from graphcal.factors.wheel_odometry import (
    WheelOdometryFactor,
    preintegrate,
    wheel_odometry_between_factor,
)
from graphcal.model import THETA_NOMINAL, integrate
from graphcal.rotation_jacobians import end_wheel_rotation_jacobian, wheel_rotation_jacobian
from graphcal.simulate.drive import simulate_drive

WHEEL_NOISE = 0.0005
XI, XJ, T = gtsam.symbol("x", 0), gtsam.symbol("x", 1), gtsam.symbol("t", 0)


@pytest.fixture(scope="module")
def drive_inputs() -> np.ndarray:
    """Measured inputs (K, 4) of a 1 km synthetic city drive."""
    return simulate_drive(length_km=1.0, seed=3).measured.inputs


@pytest.fixture(scope="module")
def turn_start(drive_inputs) -> int:
    """Start index of the 40 steps (1 s) with the largest heading change of the drive."""
    psi = integrate(np.zeros(3), drive_inputs, THETA_NOMINAL)[:, 2]
    turn = np.abs(psi[40:] - psi[:-40])
    start = int(np.argmax(turn))
    assert turn[start] > 0.4  # a real turn: > 0.4 rad in 1 s
    return start


def interval(drive_inputs, turn_start, steps: int) -> np.ndarray:
    return drive_inputs[turn_start : turn_start + steps]


def test_end_wheel_rotation_jacobian_is_the_last_row_of_the_full_one(rng):
    inputs = np.stack([rng.uniform(0.05, 0.2, (2, 30)), rng.uniform(0.05, 0.2, (2, 30))], -1)
    inputs = np.concatenate(
        [inputs, rng.normal(0, 0.02, (2, 30, 1)), rng.normal(0, 2, (2, 30, 1))], -1
    )
    theta = THETA_NOMINAL + np.array([[0.0, 0.0, 0.0, 0.0], [-0.01, 2e-3, 0.03, 1e-3]])
    states = integrate(np.array([[1.0, -2.0, 0.3], [0.0, 5.0, 3.5]]), inputs, theta)
    end = end_wheel_rotation_jacobian(states, inputs, theta)
    assert end.shape == (2, 3, 30, 2)
    full = wheel_rotation_jacobian(states, inputs, theta)[..., -1, :, :, :]
    np.testing.assert_allclose(end, full, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("split", [1, 13, 39])
def test_merging_two_intervals_equals_integrating_both_at_once(drive_inputs, turn_start, split):
    inputs = interval(drive_inputs, turn_start, 40)
    whole = preintegrate(inputs, THETA_NOMINAL, keep_correction_jacobian=True)
    first = preintegrate(inputs[:split], THETA_NOMINAL, keep_correction_jacobian=True)
    second = preintegrate(inputs[split:], THETA_NOMINAL, keep_correction_jacobian=True)
    merged = PreintegratedWheelOdometry.merged(first, second)
    assert first.n_steps == split  # merged() leaves its arguments alone
    assert merged.n_steps == 40
    np.testing.assert_array_equal(merged.inputs, inputs)
    np.testing.assert_allclose(merged.delta, whole.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(merged.d_delta_d_theta, whole.d_delta_d_theta, rtol=0, atol=1e-11)
    np.testing.assert_allclose(merged.covariance, whole.covariance, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(
        merged.d_delta_d_corrections, whole.d_delta_d_corrections, rtol=0, atol=1e-12
    )
    # The single block is the model's end Jacobian, columns [n_rl_0, n_rr_0, n_rl_1, ...].
    states = integrate(np.zeros(3), inputs, THETA_NOMINAL)
    expected = end_wheel_rotation_jacobian(states, inputs, THETA_NOMINAL).reshape(3, 80)
    np.testing.assert_allclose(whole.d_delta_d_corrections, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        whole.covariance, WHEEL_NOISE**2 * expected @ expected.T, rtol=1e-12, atol=1e-20
    )


def test_merging_intervals_at_different_theta_is_rejected(drive_inputs, turn_start):
    inputs = interval(drive_inputs, turn_start, 10)
    first = preintegrate(inputs[:5], THETA_NOMINAL)
    second = preintegrate(inputs[5:], THETA_NOMINAL + [1e-3, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="different theta"):
        first.merge(second)


@pytest.mark.parametrize("read_every", [None, 1, 7], ids=["no-reads", "read-each", "read-7th"])
@pytest.mark.parametrize("quantization", [0.0, 0.003], ids=["white", "ticks"])
def test_sample_by_sample_equals_one_block(drive_inputs, turn_start, read_every, quantization):
    inputs = interval(drive_inputs, turn_start, 40)
    block = preintegrate(
        inputs, THETA_NOMINAL, keep_correction_jacobian=True, quantization=quantization
    )
    single = PreintegratedWheelOdometry(
        THETA_NOMINAL, keep_correction_jacobian=True, quantization=quantization
    )
    for i, row in enumerate(inputs):
        single.integrate_measurement(*row)
        if read_every is not None and i % read_every == 0:
            assert single.n_steps == i + 1  # reading a result integrates the samples so far
            single.covariance  # noqa: B018
    assert single.n_steps == 40
    np.testing.assert_array_equal(single.inputs, inputs)
    np.testing.assert_allclose(single.delta, block.delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(single.d_delta_d_theta, block.d_delta_d_theta, rtol=0, atol=1e-11)
    np.testing.assert_allclose(single.covariance, block.covariance, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(
        single.d_delta_d_corrections, block.d_delta_d_corrections, rtol=0, atol=1e-12
    )


@pytest.mark.parametrize("steps", [8, 20])
def test_first_order_theta_correction_matches_reintegration(drive_inputs, turn_start, steps):
    inputs = interval(drive_inputs, turn_start, steps)
    preintegrated = preintegrate(inputs, THETA_NOMINAL)
    theta = THETA_NOMINAL + np.array([2e-3, 0.0, 0.0, 0.0])  # c_e + 2 mm
    exact = integrate(np.zeros(3), inputs, theta)[-1]
    moved = exact - preintegrated.delta
    assert np.hypot(*moved[:2]) > 5e-4  # the correction itself is not negligible
    predicted = preintegrated.predict(theta)
    assert np.all(np.abs(predicted[:2] - exact[:2]) < 1e-6)  # [m]
    assert abs(predicted[2] - exact[2]) < 1e-12  # [rad]; the heading is affine in c_e
    reintegrated = preintegrated.copy()
    reintegrated.reintegrate(theta)
    np.testing.assert_allclose(reintegrated.delta, exact, rtol=0, atol=1e-13)


def test_covariance_matches_monte_carlo(drive_inputs, turn_start):
    inputs = interval(drive_inputs, turn_start, 40)
    preintegrated = preintegrate(inputs, THETA_NOMINAL, wheel_noise=WHEEL_NOISE)
    rng = np.random.default_rng(2024)
    n = 20000
    noisy = np.broadcast_to(inputs, (n, *inputs.shape)).copy()
    noisy[..., :2] += rng.normal(0.0, WHEEL_NOISE, (n, len(inputs), 2))
    deltas = integrate(np.zeros(3), noisy, THETA_NOMINAL)[:, -1]

    # Sample covariances whitened by the propagated ones: identity up to sampling noise (~1 %).
    def whitened(sample_covariance: np.ndarray, covariance: np.ndarray) -> np.ndarray:
        chol = np.linalg.cholesky(covariance)
        return np.linalg.solve(chol, np.linalg.solve(chol, sample_covariance).T)

    np.testing.assert_allclose(
        whitened(np.cov(deltas.T), preintegrated.covariance), np.eye(3), atol=0.05
    )
    # The same in the Pose2 tangent at the delta pose (retract is body-frame).
    nominal = preintegrated.delta_pose()
    tangent = np.array([gtsam.Pose2.Logmap(nominal.between(gtsam.Pose2(*d))) for d in deltas])
    np.testing.assert_allclose(
        whitened(np.cov(tangent.T), preintegrated.tangent_covariance(floor_sigmas=None)),
        np.eye(3),
        atol=0.05,
    )


def test_quantization_covariance_matches_monte_carlo_of_rounded_counts(drive_inputs, turn_start):
    """Counts of 96 ticks/rev: each step's rotation is the difference of two rounded
    cumulative counts, so neighbouring steps' errors cancel. The propagated covariance matches
    a Monte Carlo of random counter phases, and is far below treating the errors as white."""
    inputs = interval(drive_inputs, turn_start, 8)  # one 5 Hz keyframe interval
    ticks = 96
    sigma = 1.0 / (ticks * np.sqrt(12.0))
    preintegrated = preintegrate(inputs, THETA_NOMINAL, wheel_noise=0.0, quantization=sigma)
    rng = np.random.default_rng(7)
    n = 20000
    # Intervals like this one whose rotations differ by up to a tick per step (what varies
    # between a drive's intervals), counted from a random counter phase.
    true = np.broadcast_to(inputs, (n, *inputs.shape)).copy()
    true[..., :2] += rng.uniform(-1.0, 1.0, (n, len(inputs), 2)) / ticks
    cumulative = np.concatenate([np.zeros((n, 1, 2)), np.cumsum(true[..., :2], axis=1)], axis=1)
    counts = np.floor(cumulative * ticks + rng.uniform(0.0, 1.0, (n, 1, 2)))
    counted = true.copy()
    counted[..., :2] = np.diff(counts, axis=1) / ticks
    end = integrate(np.zeros(3), counted, THETA_NOMINAL)[:, -1]
    errors = end - integrate(np.zeros(3), true, THETA_NOMINAL)[:, -1]
    chol = np.linalg.cholesky(preintegrated.covariance)
    whitened = np.linalg.solve(chol, np.linalg.solve(chol, errors.T @ errors / n).T)
    np.testing.assert_allclose(whitened, np.eye(3), atol=0.06)
    white = preintegrate(inputs, THETA_NOMINAL, wheel_noise=np.sqrt(2.0) * sigma).covariance
    assert preintegrated.covariance[2, 2] < 0.5 * white[2, 2]


def poses_around(delta: np.ndarray) -> tuple[gtsam.Pose2, gtsam.Pose2]:
    """A start pose with heading beyond pi and an end pose 5 cm / 0.02 rad off the odometry."""
    pose_i = gtsam.Pose2(120.0, -35.0, 3.3)
    pose_j = pose_i.compose(gtsam.Pose2(*delta)).compose(gtsam.Pose2(0.04, -0.03, 0.02))
    return pose_i, pose_j


def values_at(pose_i: gtsam.Pose2, pose_j: gtsam.Pose2, theta: np.ndarray) -> gtsam.Values:
    values = gtsam.Values()
    values.insert(XI, pose_i)
    values.insert(XJ, pose_j)
    values.insert(T, np.asarray(theta, float))
    return values


@pytest.mark.parametrize(
    "theta_offset, reintegrations",
    [([2e-3, 0.4e-3, -1e-2, 0.5e-3], 0), ([8e-3, 0.0, 0.0, 0.0], 1)],
    ids=["first-order", "reintegrated"],
)
def test_factor_jacobians_match_numerical(drive_inputs, turn_start, theta_offset, reintegrations):
    preintegrated = preintegrate(interval(drive_inputs, turn_start, 20), THETA_NOMINAL)
    wheel = WheelOdometryFactor(XI, XJ, T, preintegrated)
    factor = wheel.factor()
    values = values_at(*poses_around(preintegrated.delta), THETA_NOMINAL + theta_offset)
    analytic = factor.linearize(values).jacobian()[0]
    assert wheel.n_reintegrations == reintegrations
    numeric = retract_jacobian(factor.whitenedError, values, [XI, XJ, T])[0]
    assert wheel.n_reintegrations == reintegrations  # the finite differences stay inside
    assert np.abs(factor.whitenedError(values)).max() > 5.0  # evaluated away from the optimum
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-4)


def test_slip_scales_act_as_scaled_wheel_rotations_with_exact_jacobians(drive_inputs, turn_start):
    inputs = interval(drive_inputs, turn_start, 20)
    preintegrated = preintegrate(inputs, THETA_NOMINAL)
    slip_key = gtsam.symbol("s", 0)
    wheel = WheelOdometryFactor(XI, XJ, T, preintegrated, slip_key=slip_key)
    factor = wheel.factor()
    slip = np.array([1.5e-3, -2.0e-3])
    theta = THETA_NOMINAL + [1e-3, 0.2e-3, 5e-3, 0.2e-3]
    # The predicted increment with slip scales = the increment of the scaled rotations.
    scaled = inputs.copy()
    scaled[:, :2] *= 1.0 + slip
    pose_i = gtsam.Pose2(120.0, -35.0, 3.3)
    pose_j = pose_i.compose(gtsam.Pose2(*integrate(np.zeros(3), scaled, theta)[-1]))
    values = values_at(pose_i, pose_j, theta)
    values.insert(slip_key, slip)
    # First order in theta + slip (c_d moves by 7 mm here): within 5e-5 m, rad, a twentieth
    # of what the slip itself moves the increment.
    assert np.abs(factor.unwhitenedError(values)).max() < 5e-5
    unslipped = WheelOdometryFactor(XI, XJ, T, preintegrated).factor()
    assert np.abs(unslipped.unwhitenedError(values)).max() > 1e-3
    # Jacobians against central differences, away from the optimum.
    values.update(XJ, pose_j.compose(gtsam.Pose2(0.04, -0.03, 0.02)))
    analytic = factor.linearize(values).jacobian()[0]
    numeric = retract_jacobian(factor.whitenedError, values, [XI, XJ, T, slip_key])[0]
    np.testing.assert_allclose(analytic, numeric, rtol=1e-6, atol=1e-4)


def test_between_factor_equals_the_python_factor_at_fixed_theta(drive_inputs, turn_start):
    preintegrated = preintegrate(interval(drive_inputs, turn_start, 20), THETA_NOMINAL)
    wheel = WheelOdometryFactor(XI, XJ, T, preintegrated)
    between = wheel.between_factor(THETA_NOMINAL)
    assert isinstance(between, gtsam.BetweenFactorPose2)
    values = values_at(*poses_around(preintegrated.delta), THETA_NOMINAL)
    factor = wheel.factor()
    np.testing.assert_allclose(
        between.unwhitenedError(values), factor.unwhitenedError(values), rtol=1e-12, atol=1e-15
    )
    np.testing.assert_allclose(
        between.whitenedError(values), factor.whitenedError(values), rtol=1e-9, atol=1e-9
    )
    assert between.error(values) == pytest.approx(factor.error(values), rel=1e-12)
    # The pose Jacobians agree as well (theta is the third key of the Python factor only).
    np.testing.assert_allclose(
        between.linearize(values).jacobian()[0],
        factor.linearize(values).jacobian()[0][:, :6],
        rtol=1e-9,
        atol=1e-9,
    )


def exact_error(inputs, theta, pose_i, pose_j) -> np.ndarray:
    end = gtsam.Pose2(*integrate(np.zeros(3), inputs, theta)[-1])
    return gtsam.Pose2.Logmap(end.between(pose_i.between(pose_j)))


def test_reintegration_beyond_the_threshold(drive_inputs, turn_start):
    inputs = interval(drive_inputs, turn_start, 40)
    preintegrated = preintegrate(inputs, THETA_NOMINAL)
    wheel = WheelOdometryFactor(XI, XJ, T, preintegrated)
    factor = wheel.factor()
    pose_i, pose_j = poses_around(preintegrated.delta)

    near = THETA_NOMINAL + np.array([4e-3, 0.0, 0.0, 0.0])  # inside the 5 mm c_e threshold
    error = factor.unwhitenedError(values_at(pose_i, pose_j, near))
    assert wheel.n_reintegrations == 0
    first_order = gtsam.Pose2.Logmap(
        gtsam.Pose2(*preintegrated.predict(near)).between(pose_i.between(pose_j))
    )
    np.testing.assert_allclose(error, first_order, rtol=0, atol=1e-14)

    far = THETA_NOMINAL + np.array([0.0, 0.0, 0.05, 0.0])  # t_r + 5 cm, beyond 2 cm
    error = factor.unwhitenedError(values_at(pose_i, pose_j, far))
    assert wheel.n_reintegrations == 1
    np.testing.assert_array_equal(wheel.preintegrated.theta_linearization, far)
    exact = exact_error(inputs, far, pose_i, pose_j)
    np.testing.assert_allclose(error, exact, rtol=0, atol=1e-12)
    first_order = gtsam.Pose2.Logmap(
        gtsam.Pose2(*preintegrated.predict(far)).between(pose_i.between(pose_j))
    )
    assert np.abs(first_order - exact).max() > 1e-5  # re-integration made a difference
    np.testing.assert_array_equal(preintegrated.theta_linearization, THETA_NOMINAL)  # a copy

    # The fixed-theta factor re-integrates a copy as well.
    between = wheel_odometry_between_factor(XI, XJ, preintegrated, far)
    np.testing.assert_allclose(
        between.unwhitenedError(values_at(pose_i, pose_j, far)), exact, rtol=0, atol=1e-12
    )
    np.testing.assert_array_equal(preintegrated.theta_linearization, THETA_NOMINAL)


def test_many_intervals_at_once_equal_one_at_a_time():
    """The vectorized preintegration of unequal intervals equals preintegrating each."""
    inputs = simulate_drive(length_km=1.0, seed=3).measured.inputs
    bounds = [100, 108, 125, 126, 166]
    intervals = [inputs[a:b] for a, b in itertools.pairwise(bounds)]
    theta = np.array([1.99, 0.5e-3, 1.57, 1e-3])
    many = PreintegratedWheelOdometry.from_intervals(intervals, theta)
    for block, together in zip(intervals, many, strict=True):
        alone = PreintegratedWheelOdometry(theta)
        alone.integrate_measurements(block)
        assert together.n_steps == len(block)
        np.testing.assert_allclose(together.delta, alone.delta, atol=1e-12)
        np.testing.assert_allclose(together.d_delta_d_theta, alone.d_delta_d_theta, atol=1e-12)
        np.testing.assert_allclose(together.covariance, alone.covariance, rtol=1e-9, atol=1e-20)
        np.testing.assert_array_equal(together.inputs, block)
