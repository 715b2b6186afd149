"""GTSAM factors: analytic Jacobians against numerical derivatives through GTSAM's retract."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from numerical import retract_jacobian

from graphcal.data.segments import gather_segments, split_segments
from graphcal.factors import (
    OdometryChunkError,
    correction_size_factor,
    correction_smoothness_factor,
    odometry_chunk_factor,
    pose2_from_state,
    pose_measurement_factor,
    pose_sigmas,
    segment_odometry_factor,
    state_from_pose2,
    theta_prior_factor,
    wheel_odometry_factor,
)
from graphcal.model import THETA_NOMINAL, integrate

THETA = np.array([1.99, 0.5e-3, 1.57, 1e-3])
T = gtsam.symbol("t", 0)
X0, X1 = gtsam.symbol("x", 0), gtsam.symbol("x", 1)


def C(k: int) -> int:
    return gtsam.symbol("c", k)


def numerical_jacobian(factor: gtsam.NonlinearFactor, values: gtsam.Values) -> np.ndarray:
    """Whitened d error / d tangent for all of the factor's keys."""
    return retract_jacobian(factor.whitenedError, values, factor.keys())[0]


def assert_jacobians(factor, values, rtol=1e-5, atol=1e-4):
    analytic = factor.linearize(values).jacobian()[0]
    np.testing.assert_allclose(analytic, numerical_jacobian(factor, values), rtol=rtol, atol=atol)


@pytest.fixture(scope="module")
def segment(drive):
    data = gather_segments(drive.measured, split_segments(drive.measured, 150.0))
    k = int(data.n_steps[2])
    return data.poses[2, : k + 1], data.inputs[2, :k]


@pytest.mark.parametrize("estimate_start", [True, False])
def test_segment_factor_jacobians(segment, estimate_start):
    poses, inputs = segment
    factor = segment_odometry_factor(T, poses, inputs, start_key=X0 if estimate_start else None)
    values = gtsam.Values()
    values.insert(T, THETA)
    # A start pose away from the measurement, with a heading beyond pi to exercise unwrapping.
    values.insert(X0, gtsam.Pose2(poses[0, 0] + 0.3, poses[0, 1] - 0.2, poses[0, 2] + 0.05))
    assert factor.dim() == 3 * len(inputs)
    assert_jacobians(factor, values)


@pytest.mark.parametrize("free_start, free_theta", [(False, False), (True, True)])
def test_chunk_factor_with_corrections_and_end_pose(segment, free_start, free_theta, rng):
    poses, inputs = segment[0][:31], segment[1][:30]
    error = OdometryChunkError(
        inputs,
        poses,
        start_state=None if free_start else poses[0],
        has_end=True,
        has_corrections=True,
        theta=None if free_theta else THETA,
    )
    keys = ([X0] if free_start else []) + [X1] + [C(k) for k in range(30)]
    keys += [T] if free_theta else []
    factor = odometry_chunk_factor(error, keys)
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    for k in range(30):
        values.insert(C(k), rng.normal(0, 1e-3, 2))
    values.insert(T, THETA)
    assert factor.dim() == 3 * 30 + 3
    assert_jacobians(factor, values)


def test_wheel_odometry_factor_is_eq_1_as_pose2_composition(rng):
    inputs = np.array([0.16, 0.17, 0.02, 1.5])
    x0 = np.array([10.0, -4.0, 3.0])  # near pi: Pose2 wraps, the model does not
    x1 = integrate(x0, inputs[None], THETA)[-1]
    factor = wheel_odometry_factor(X0, X1, T, inputs, np.array([0.01, 0.01, 0.001]), C(0), 3.0)
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(x0))
    values.insert(X1, pose2_from_state(x1))
    values.insert(C(0), np.zeros(2))
    values.insert(T, THETA)
    assert np.abs(factor.unwhitenedError(values)).max() < 1e-12
    # Pose2 composition with the body-frame increment gives the same next pose.
    from graphcal.model import step_increments

    v, omega = step_increments(inputs, THETA)
    angle = 0.5 * omega + inputs[2]
    composed = pose2_from_state(x0).compose(
        gtsam.Pose2(v * np.cos(angle), v * np.sin(angle), omega)
    )
    np.testing.assert_allclose(state_from_pose2(composed, x1[2]), x1, atol=1e-12)
    values.update(C(0), rng.normal(0, 1e-3, 2))
    values.update(X1, pose2_from_state(x1 + [0.01, -0.02, 0.003]))
    assert_jacobians(factor, values)


def test_error_is_zero_on_noise_free_data(clean_drive):
    data = gather_segments(clean_drive.truth, split_segments(clean_drive.truth, 150.0))
    k = int(data.n_steps[0])
    factor = segment_odometry_factor(T, data.poses[0, : k + 1], data.inputs[0, :k], start_key=X0)
    values = gtsam.Values()
    values.insert(T, clean_drive.theta_true)
    values.insert(X0, gtsam.Pose2(*data.poses[0, 0]))
    assert np.abs(factor.unwhitenedError(values)).max() < 1e-9


def test_smoothness_factor_penalizes_the_change_of_corrected_rotations():
    measured, next_measured = np.array([0.15, 0.16]), np.array([0.151, 0.158])
    factor = correction_smoothness_factor(C(0), C(1), measured, next_measured, 0.03)
    values = gtsam.Values()
    c0, c1 = np.array([1e-3, -2e-3]), np.array([-5e-4, 1e-3])
    values.insert(C(0), c0)
    values.insert(C(1), c1)
    change = (next_measured + c1) - (measured + c0)
    np.testing.assert_allclose(factor.unwhitenedError(values), change, atol=1e-15)


def test_size_theta_and_pose_factors_have_the_stated_sigmas():
    values = gtsam.Values()
    values.insert(C(0), np.array([0.003, -0.006]))
    size = correction_size_factor(C(0), np.array([0.003, 0.003]))
    np.testing.assert_allclose(size.whitenedError(values), [1.0, -2.0])
    values.insert(T, THETA_NOMINAL + [0.01, 0, 0, 0])
    prior = theta_prior_factor(T, np.array([0.01, 1e-3, 0.1, 1e-3]))
    np.testing.assert_allclose(prior.whitenedError(values), [1.0, 0, 0, 0], atol=1e-12)
    values.insert(X0, gtsam.Pose2(1.0, 2.0, 0.3))
    pose = pose_measurement_factor(X0, np.array([1.0, 2.0, 0.3 - 0.01]))
    np.testing.assert_allclose(
        pose.whitenedError(values), [0, 0, 0.01 / pose_sigmas()[2]], atol=1e-9
    )


def test_start_heading_stays_on_the_measured_branch():
    pose = gtsam.Pose2(1.0, 2.0, 0.1)  # Pose2 wraps its angle
    state = state_from_pose2(pose, reference_heading=4 * np.pi + 0.05)
    assert state[2] == pytest.approx(4 * np.pi + 0.1)


def test_pose_sigmas_follow_the_paper_weights():
    sigmas = pose_sigmas((1.0, 1.0, 50.0), 0.2)
    weights = 1 / sigmas**2
    np.testing.assert_allclose(weights / weights[0], [1, 1, 50])
    with pytest.raises(ValueError):
        pose_sigmas((1.0, 0.0, 50.0))


def test_chunk_factor_rejects_wrong_keys(segment):
    error = OdometryChunkError(segment[1][:5], segment[0][:6], start_state=segment[0][0])
    with pytest.raises(ValueError, match="expects 1 keys"):
        odometry_chunk_factor(error, [T, X0])
