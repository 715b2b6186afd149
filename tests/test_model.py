"""The odometry model (eqs. 1–3): consistency, vectorization and analytic Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
from reference import step

from graphcal.model import (
    THETA_NOMINAL,
    integrate,
    integrate_with_jacobians,
    step_increments,
    wheel_rotations_for_motion,
)

THETA = np.array([1.985, 1.2e-3, 1.585, 1.5e-3])


def random_inputs(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    n_rl = rng.uniform(0.05, 0.2, shape)
    n_rr = n_rl + rng.normal(0.0, 0.01, shape)
    beta = rng.normal(0.0, 0.05, shape)
    ay = rng.normal(0.0, 2.0, shape)
    return np.stack([n_rl, n_rr, beta, ay], axis=-1)


def central_difference(f, x: np.ndarray, h: float) -> np.ndarray:
    """d f / d x by central differences; f maps (n,) to (...,) arrays."""
    columns = []
    for i in range(len(x)):
        dx = np.zeros_like(x)
        dx[i] = h
        columns.append((f(x + dx) - f(x - dx)) / (2 * h))
    return np.stack(columns, axis=-1)


def test_straight_drive_moves_by_wheel_distance():
    inputs = np.array([[0.1, 0.1, 0.0, 0.0]] * 10)
    states = integrate(np.zeros(3), inputs, THETA_NOMINAL)
    np.testing.assert_allclose(states[-1], [10 * 0.1 * 2.0, 0.0, 0.0], atol=1e-12)


def test_right_wheel_faster_turns_left_by_eq_2b():
    v, omega = step_increments(np.array([0.1, 0.11, 0.0, 0.0]), THETA_NOMINAL)
    assert v == pytest.approx(0.5 * (0.1 + 0.11) * 2.0)
    assert omega == pytest.approx((0.11 - 0.1) * 2.0 / 1.55)


def test_integrate_equals_repeated_steps(rng):
    inputs = random_inputs(rng, (200,))
    start = np.array([3.0, -2.0, 0.7])
    states = integrate(start, inputs, THETA)
    x = start
    for k in range(len(inputs)):
        x = step(x, inputs[k], THETA)
        np.testing.assert_allclose(states[k + 1], x, rtol=0, atol=1e-10)


def test_integration_is_vectorized_over_segments(rng):
    inputs = random_inputs(rng, (5, 60))
    starts = rng.normal(size=(5, 3))
    thetas = THETA + rng.normal(0, 1e-3, size=(5, 4))
    together = integrate(starts, inputs, thetas)
    for s in range(5):
        np.testing.assert_array_equal(together[s], integrate(starts[s], inputs[s], thetas[s]))


def test_zero_padding_leaves_the_pose_unchanged(rng):
    inputs = random_inputs(rng, (40,))
    padded = np.concatenate([inputs, np.zeros((15, 4))])
    states = integrate(np.zeros(3), padded, THETA)
    np.testing.assert_array_equal(states[40:], np.repeat(states[40:41], 16, axis=0))


def test_trajectory_jacobians_match_finite_differences(rng):
    inputs = random_inputs(rng, (3, 150))
    starts = np.array([[0.0, 0.0, 0.3], [10.0, -5.0, 2.0], [-3.0, 4.0, -1.0]])
    _states, d_start, d_theta = integrate_with_jacobians(starts, inputs, THETA)
    for s in range(3):
        num_theta = central_difference(
            lambda th, s=s: integrate(starts[s], inputs[s], th), THETA, 1e-7
        )
        num_start = central_difference(
            lambda x, s=s: integrate(x, inputs[s], THETA), starts[s], 1e-6
        )
        np.testing.assert_allclose(d_theta[s], num_theta, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(d_start[s], num_start, rtol=1e-6, atol=1e-7)


def test_wheel_rotations_for_motion_inverts_eq_2(rng):
    distance = rng.uniform(0.1, 0.5, 100)
    yaw = rng.normal(0, 0.01, 100)
    ay = rng.normal(0, 2, 100)
    n_rl, n_rr = wheel_rotations_for_motion(distance, yaw, ay, THETA)
    v, omega = step_increments(np.column_stack([n_rl, n_rr, np.zeros(100), ay]), THETA)
    np.testing.assert_allclose(v, distance, rtol=1e-12)
    np.testing.assert_allclose(omega, yaw, atol=1e-15)


def test_theta_with_wrong_length_is_rejected():
    with pytest.raises(ValueError, match="4 components"):
        integrate(np.zeros(3), np.zeros((5, 4)), np.ones(3))


def test_wheel_rotation_jacobian_matches_finite_differences(rng):
    from graphcal.rotation_jacobians import wheel_rotation_jacobian

    inputs = random_inputs(rng, (25,))
    start = np.array([1.0, -1.0, 0.4])
    states = integrate(start, inputs, THETA)
    analytic = wheel_rotation_jacobian(states, inputs, THETA)
    assert analytic.shape == (26, 3, 25, 2)

    def trajectory(wheels: np.ndarray) -> np.ndarray:
        changed = inputs.copy()
        changed[:, :2] = wheels.reshape(25, 2)
        return integrate(start, changed, THETA)

    numeric = central_difference(trajectory, inputs[:, :2].ravel(), 1e-7)
    np.testing.assert_allclose(analytic.reshape(26, 3, 50), numeric, rtol=1e-6, atol=1e-7)


def test_wheel_rotation_jacobian_of_a_batch_is_each_members(rng):
    from graphcal.rotation_jacobians import wheel_rotation_jacobian

    inputs = random_inputs(rng, (4, 20))
    thetas = THETA + rng.normal(0.0, 1e-3, (4, 4))
    states = integrate(rng.normal(0.0, 1.0, (4, 3)), inputs, thetas)
    batch = wheel_rotation_jacobian(states, inputs, thetas)
    for i in range(4):
        np.testing.assert_array_equal(
            batch[i], wheel_rotation_jacobian(states[i], inputs[i], thetas[i])
        )


def test_aligned_trajectory_moves_a_rigidly_moved_path_back(rng):
    from graphcal.alignment import aligned_trajectory

    inputs = random_inputs(rng, (200,))
    measured = integrate(np.array([12.0, -7.0, 2.5]), inputs, THETA)
    at_origin = integrate(np.zeros(3), inputs, THETA)  # the same path, turned and shifted
    np.testing.assert_allclose(aligned_trajectory(at_origin, measured), measured, atol=1e-9)
    # A fix 50 m off with weight 0 does not move the fit.
    spiked = measured.copy()
    spiked[100, :2] += 50.0
    weights = np.ones(len(spiked))
    weights[100] = 0.0
    np.testing.assert_allclose(aligned_trajectory(at_origin, spiked, weights), measured, atol=1e-9)
