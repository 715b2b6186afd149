"""The segment odometry factor: its Jacobians against numerical derivatives through GTSAM."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graphcal.data.segments import gather_segments, split_segments
from graphcal.factors import pose_sigmas, segment_odometry_factor, state_from_pose2

THETA_KEY, POSE_KEY = gtsam.symbol("t", 0), gtsam.symbol("x", 0)


def numerical_jacobian(factor, values, key, h=1e-6):
    """d error / d tangent of the variable at ``key``, by central differences of retractions."""
    is_pose = key == POSE_KEY
    dim = 3 if is_pose else 4
    columns = []
    for i in range(dim):
        delta = np.zeros(dim)
        delta[i] = h
        errors = []
        for sign in (1.0, -1.0):
            v = gtsam.Values(values)
            if is_pose:
                v.update(key, values.atPose2(key).retract(sign * delta))
            else:
                v.update(key, values.atVector(key) + sign * delta)
            errors.append(factor.unwhitenedError(v))
        columns.append((errors[0] - errors[1]) / (2 * h))
    return np.column_stack(columns)


@pytest.mark.parametrize("estimate_start", [True, False])
def test_segment_factor_jacobians(drive, estimate_start):
    data = gather_segments(drive.measured, split_segments(drive.measured, 150.0))
    k = int(data.n_steps[2])
    poses, inputs = data.poses[2, : k + 1], data.inputs[2, :k]
    factor = segment_odometry_factor(
        THETA_KEY, poses, inputs, start_key=POSE_KEY if estimate_start else None
    )
    values = gtsam.Values()
    values.insert(THETA_KEY, np.array([1.99, 0.5e-3, 1.57, 1e-3]))
    # A start pose away from the measurement, with a heading beyond pi to exercise unwrapping.
    values.insert(POSE_KEY, gtsam.Pose2(poses[0, 0] + 0.3, poses[0, 1] - 0.2, poses[0, 2] + 0.05))
    linear = factor.linearize(values)
    analytic = linear.jacobian()[0]  # whitened, columns ordered like the keys
    sigmas = np.tile(pose_sigmas(), k)
    numeric = (
        np.column_stack([numerical_jacobian(factor, values, key) for key in factor.keys()])
        / sigmas[:, None]
    )
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-4)
    assert factor.dim() == 3 * k


def test_error_is_zero_on_noise_free_data(clean_drive):
    data = gather_segments(clean_drive.truth, split_segments(clean_drive.truth, 150.0))
    k = int(data.n_steps[0])
    factor = segment_odometry_factor(
        THETA_KEY, data.poses[0, : k + 1], data.inputs[0, :k], start_key=POSE_KEY
    )
    values = gtsam.Values()
    values.insert(THETA_KEY, clean_drive.theta_true)
    values.insert(POSE_KEY, gtsam.Pose2(*data.poses[0, 0]))
    assert np.abs(factor.unwhitenedError(values)).max() < 1e-9


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
