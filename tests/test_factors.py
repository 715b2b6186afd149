"""GTSAM factors: analytic Jacobians against numerical derivatives through GTSAM's retract."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from numerical import retract_jacobian

from graphcal.factors import (
    ChunkBatch,
    ChunkNoise,
    ChunkOdometryFactor,
    DefectKeys,
    DefectValues,
    MeasuredPoseFactor,
    OdometryChunk,
    chunk_boundary_smoothness,
    chunk_correction_prior,
    pose2_from_state,
    pose_measurement_factor,
    pose_sigmas,
    segment_odometry_factor,
    state_from_pose2,
    theta_prior_factor,
)
from graphcal.log.segments import gather_segments, split_segments
from graphcal.log.timing import rotation_rate_changes
from graphcal.model import THETA_NOMINAL

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
    return data.segment(2)


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
    chunk = OdometryChunk(inputs, poses)
    factor = ChunkOdometryFactor(
        chunk,
        start=X0 if free_start else poses[0],
        theta=T if free_theta else THETA,
        corrections=C(0),
        end=X1,
    ).factor()
    assert list(factor.keys()) == ([X0] if free_start else []) + [X1, C(0)] + (
        [T] if free_theta else []
    )
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    assert factor.dim() == 3 * 30 + 3
    assert_jacobians(factor, values)


@pytest.mark.parametrize("reference_offset", [0.0, 2.0 * np.pi, 3.5, -4.0])
def test_chunk_error_does_not_depend_on_the_reference_headings_branch(
    segment, reference_offset, rng
):
    """A chunk's start pose is unwrapped against its reference heading, which comes from the
    path the graph was built on: a path that turned through more than π too much (a
    skid-steer robot integrated with its datasheet track) put the start on another branch,
    and every heading residual 2π off (issue 43: χ²/dof 5942 where the truth fits at 1)."""
    poses, inputs = segment[0][:31], segment[1][:30]
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    errors = []
    for offset in (0.0, reference_offset):
        chunk = OdometryChunk(inputs, poses, reference_heading=poses[0, 2] + offset)
        factor = ChunkOdometryFactor(chunk, X0, T, corrections=C(0), end=X1).factor()
        errors.append(np.asarray(factor.unwhitenedError(values)))
    np.testing.assert_allclose(errors[1], errors[0], atol=1e-9)
    assert np.abs(errors[0][2::3]).max() < 0.5  # headings near the measured ones


@pytest.mark.parametrize("with_corrections", [True, False])
def test_chunk_factor_with_wheel_slip_scales(segment, with_corrections, rng):
    poses, inputs = segment[0][:31], segment[1][:30]
    S = gtsam.symbol("s", 0)
    factor = ChunkOdometryFactor(
        OdometryChunk(inputs, poses),
        start=X0,
        theta=T,
        corrections=C(0) if with_corrections else None,
        end=X1,
        defects=DefectKeys(slip=S),
    ).factor()
    assert list(factor.keys())[-1] == S
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    if with_corrections:
        values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    values.insert(S, np.array([2e-3, -1e-3]))
    assert_jacobians(factor, values)
    # A slip scale is a relative change of the measured rotations.
    scaled = inputs.copy()
    scaled[:, :2] *= 1.0 + np.array([2e-3, -1e-3])
    same = ChunkOdometryFactor(
        OdometryChunk(scaled, poses),
        X0,
        T,
        corrections=C(0) if with_corrections else None,
        end=X1,
    ).factor()
    np.testing.assert_allclose(
        factor.unwhitenedError(values), same.unwhitenedError(values), atol=1e-12
    )


@pytest.mark.parametrize("tracked", [True, False])
def test_chunk_factor_with_time_offset_lever_arm_heading_bias_and_fix_offset(segment, tracked, rng):
    poses, inputs = segment[0][:31], segment[1][:30]
    OFFSET, A, B = gtsam.symbol("o", 0), gtsam.symbol("a", 0), gtsam.symbol("b", 0)
    E0, E1, G = gtsam.symbol("e", 0), gtsam.symbol("e", 1), gtsam.symbol("g", 0)
    assert np.ptp(inputs[:, 3]) > 0.4 and np.any(inputs[:, 2] != 0)  # a turn, a sideslip
    rates = rotation_rate_changes(inputs[:, :2], 0.025)
    chunk = OdometryChunk(inputs, poses if tracked else None, float(poses[0, 2]), rates)
    factor = ChunkOdometryFactor(
        chunk,
        X0,
        T,
        corrections=C(0),
        end=X1,
        defects=DefectKeys(
            time_offset=OFFSET, lever_arm=A, heading_bias=B, fix_offset=(E0, E1), rear_slip_gain=G
        ),
    ).factor()
    assert list(factor.keys())[-6:] == [OFFSET, A, B, E0, E1, G]
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    values.insert(OFFSET, np.array([0.04]))
    values.insert(A, np.array([1.2, -0.4]))
    values.insert(B, np.array([0.01]))
    values.insert(E0, np.array([0.7, -1.1]))
    values.insert(E1, np.array([0.9, -0.6]))
    values.insert(G, np.array([0.005]))
    assert_jacobians(factor, values)


@pytest.mark.parametrize("fractions", [None, 0.4])
def test_a_rear_slip_gain_is_the_sideslip_minus_gain_times_lateral_acceleration(segment, fractions):
    # A rear axle whose tyres slip at -g a_y moves as the model with that sideslip logged.
    poses, inputs = segment[0][:31], segment[1][:30]
    parts = None if fractions is None else np.full(30, fractions)
    slipping = inputs.copy()
    slipping[:, 2] -= 0.005 * inputs[:, 3]
    start = poses[0] + [0.1, 0.2, 0.01]
    logged = OdometryChunk(slipping, poses, fractions=parts).error(start, THETA, jacobians=False)
    gained = OdometryChunk(inputs, poses, fractions=parts).error(
        start, THETA, jacobians=False, defects=DefectValues(rear_slip_gain=0.005)
    )
    np.testing.assert_allclose(gained.error, logged.error, atol=1e-12)
    assert (
        np.abs(gained.error - OdometryChunk(inputs, poses).error(start, THETA).error).max() > 1e-3
    )


def test_a_fix_offset_is_the_error_the_fixes_share(segment):
    # Fixes whose error drifts linearly through the chunk, from (1.5, -0.8) m at its start to
    # (1.8, -0.2) m at its end, are fitted as the true fixes are when the chunk's fix errors
    # are those two values.
    poses, inputs = segment[0][:31], segment[1][:30]
    along = np.arange(31)[:, None] / 30
    error = (1 - along) * [1.5, -0.8] + along * [1.8, -0.2]
    chunk = OdometryChunk(inputs, poses)
    shifted = OdometryChunk(inputs, poses + np.c_[error, np.zeros(31)], float(poses[0, 2]))
    start = poses[0] + [0.1, 0.2, 0.01]
    plain = chunk.error(start, THETA, jacobians=False).error
    offsets = DefectValues(fix_offset=np.array([[1.5, -0.8], [1.8, -0.2]]))
    drifted = shifted.error(start, THETA, jacobians=False, defects=offsets).error
    np.testing.assert_allclose(drifted, plain, atol=1e-9)


def test_a_chunk_of_one_run_reads_its_element_of_the_runs_time_offsets(segment, rng):
    # A recording of three runs has one time offset each: a chunk of run 1 reads element 1
    # (its error is the one-run factor's at that offset) and its Jacobian has only that column.
    poses, inputs = segment[0][:31], segment[1][:30]
    OFFSET = gtsam.symbol("o", 0)
    chunk = OdometryChunk(
        inputs, poses, float(poses[0, 2]), rotation_rate_changes(inputs[:, :2], 0.025)
    )
    factor = ChunkOdometryFactor(
        chunk,
        X0,
        T,
        corrections=C(0),
        end=X1,
        defects=DefectKeys(time_offset=OFFSET, time_offset_slot=(1, 3)),
    ).factor()
    single = ChunkOdometryFactor(
        chunk, X0, T, corrections=C(0), end=X1, defects=DefectKeys(time_offset=OFFSET)
    )
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    values.insert(OFFSET, np.array([-0.2, 0.04, 0.3]))
    assert_jacobians(factor, values)
    alone = gtsam.Values(values)
    alone.update(OFFSET, np.array([0.04]))
    np.testing.assert_allclose(
        factor.unwhitenedError(values), single.factor().unwhitenedError(alone), atol=1e-12
    )


def test_chunks_in_one_batch_give_what_each_gives_alone(segment, rng):
    # Chunks of two shapes (30 steps with an end, 20 steps without) share one batch; each
    # answer must equal the chunk's own evaluation, also after the values change and when a
    # Values holds only one chunk's variables.
    poses, inputs = segment
    OFFSET, A = gtsam.symbol("o", 0), gtsam.symbol("a", 0)
    rates = rotation_rate_changes(inputs[:, :2], 0.025)
    bounds = [0, 30, 60, 80]
    batch = ChunkBatch()
    pairs = []
    for j in range(3):
        a, b = bounds[j], bounds[j + 1]
        end = None if j == 2 else gtsam.symbol("x", j + 1)
        kwargs = dict(
            corrections=C(j),
            end=end,
            defects=DefectKeys(time_offset=OFFSET, lever_arm=A),
            noise=ChunkNoise(tracking=None),
        )
        chunk = OdometryChunk(inputs[a:b], poses[a : b + 1], None, rates[a:b])
        start = gtsam.symbol("x", j)
        shared = ChunkOdometryFactor(chunk, start, T, batch=batch, **kwargs).factor()
        alone = ChunkOdometryFactor(chunk, start, T, **kwargs).factor()
        pairs.append((shared, alone, bounds[j], b))
    values = gtsam.Values()
    for j in range(4):
        values.insert(gtsam.symbol("x", j), pose2_from_state(poses[bounds[j]] + [0.1, 0.2, 0.01]))
    for j in range(3):
        values.insert(C(j), rng.normal(0, 1e-3, 2 * (bounds[j + 1] - bounds[j])))
    values.insert(T, THETA)
    values.insert(OFFSET, np.array([0.03]))
    values.insert(A, np.array([1.0, 0.2]))
    for trial in range(2):
        for shared, alone, _, _ in pairs:
            assert np.array_equal(shared.unwhitenedError(values), alone.unwhitenedError(values))
            np.testing.assert_allclose(
                shared.linearize(values).jacobian()[0],
                alone.linearize(values).jacobian()[0],
                rtol=1e-12,
                atol=1e-12,
            )
        values.update(T, THETA * (1 + 1e-3 * (trial + 1)))
    assert_jacobians(pairs[0][0], values)
    only_first = gtsam.Values()
    for key in pairs[0][0].keys():
        only_first.insert(
            key,
            values.atPose2(key) if gtsam.Symbol(key).chr() == ord("x") else values.atVector(key),
        )
    shared, alone = pairs[0][0], pairs[0][1]
    assert np.array_equal(shared.unwhitenedError(only_first), alone.unwhitenedError(only_first))


def test_time_offset_is_the_shifted_rotation_to_first_order(segment):
    # Rotations over [t_k + tau, t_k+1 + tau] of a smooth cumulative rotation, against the
    # chunk's first-order shift.
    poses, inputs = segment[0][:201], segment[1][:200]
    dt, tau = 0.025, 0.03
    t = np.arange(201) * dt
    cumulative = 3.0 * t + 0.4 * t**2  # rev
    shifted = inputs.copy()
    shifted[:, 0] = shifted[:, 1] = np.diff(cumulative + 3.0 * tau + 0.4 * (2 * t * tau + tau**2))
    base = inputs.copy()
    base[:, 0] = base[:, 1] = np.diff(cumulative)
    rates = rotation_rate_changes(base[:, :2], dt)
    chunk = OdometryChunk(base, poses, rotation_rates=rates)
    exact = OdometryChunk(shifted, poses)
    start = poses[0]
    np.testing.assert_allclose(
        chunk.error(start, THETA, jacobians=False, defects=DefectValues(time_offset=tau)).error,
        exact.error(start, THETA, jacobians=False).error,
        atol=1e-9,
    )


@pytest.mark.parametrize("arm, bias", [(True, True), (True, False), (False, True)])
def test_start_pose_factor_jacobians_and_error(arm, bias):
    A, B = gtsam.symbol("a", 0), gtsam.symbol("b", 0)
    measured = np.array([10.0, -4.0, 3.0])  # heading beyond pi/2 near the branch cut
    factor = MeasuredPoseFactor(
        X0, measured, np.array([0.2, 0.2, 0.01]), A if arm else None, B if bias else None
    ).factor()
    values = gtsam.Values()
    values.insert(X0, gtsam.Pose2(9.0, -4.5, 3.1))
    values.insert(A, np.array([1.2, 0.5]))
    values.insert(B, np.array([-0.02]))
    assert_jacobians(factor, values)
    # An antenna 1.2 m ahead and 0.5 m left of a vehicle heading 3.1 rad, biased -0.02 rad.
    c, s = np.cos(3.1), np.sin(3.1)
    expected = np.array(
        [
            9.0 + (c * 1.2 - s * 0.5 if arm else 0.0) - 10.0,
            -4.5 + (s * 1.2 + c * 0.5 if arm else 0.0) + 4.0,
            3.1 + (-0.02 if bias else 0.0) - 3.0,
        ]
    )
    np.testing.assert_allclose(factor.unwhitenedError(values), expected, atol=1e-12)
    position = MeasuredPoseFactor(
        X0, measured, np.array([0.2, 0.2, 0.01]), A if arm else None, with_heading=False
    ).factor()
    assert position.dim() == 2
    assert_jacobians(position, values)
    np.testing.assert_allclose(position.unwhitenedError(values), expected[:2], atol=1e-12)


def test_a_measured_pose_factor_keeps_its_own_copy_of_a_logs_row():
    # A localization graph makes one factor per fix from rows of the log's (N, 3) poses: a
    # view kept by each factor held the whole array alive per fix (5.4 GB on a 12 km log).
    poses = np.arange(3000.0).reshape(1000, 3)
    measured = MeasuredPoseFactor(X0, poses[7], poses[8], with_heading=False)
    assert not np.shares_memory(measured.measured, poses)
    assert not np.shares_memory(measured.sigmas, poses)
    poses[7] = 0.0  # the caller's array changes afterwards: the factor's measurement does not
    np.testing.assert_array_equal(measured.measured, [21.0, 22.0, 23.0])


def test_down_weighted_fixes_get_wider_sigmas(segment):
    poses, inputs = segment[0][:11], segment[1][:10]
    weights = np.ones(10)
    weights[3] = 0.04
    factor = ChunkOdometryFactor(
        OdometryChunk(inputs, poses), X0, T, noise=ChunkNoise(fix_weights=weights)
    )
    sigmas = factor.sigmas.reshape(10, 3)
    np.testing.assert_allclose(sigmas[3, :2], 5.0 * sigmas[2, :2])
    assert sigmas[3, 2] == sigmas[2, 2]  # the heading is not a GNSS fix
    with pytest.raises(ValueError, match="fix weights"):
        ChunkOdometryFactor(
            OdometryChunk(inputs, poses), X0, T, noise=ChunkNoise(fix_weights=np.zeros(10))
        )


def test_one_step_between_poses_is_eq_1_as_pose2_composition(rng):
    inputs = np.array([0.16, 0.17, 0.02, 1.5])
    x0 = np.array([10.0, -4.0, 3.0])  # near pi: Pose2 wraps, the model does not
    chunk = OdometryChunk(inputs[None], reference_heading=3.0)
    from graphcal.model import step_increments

    v, omega = step_increments(inputs, THETA)
    angle = 0.5 * omega + inputs[2]
    v = v / np.cos(inputs[2])  # the centre of gravity's travel at the sideslip
    composed = pose2_from_state(x0).compose(
        gtsam.Pose2(v * np.cos(angle), v * np.sin(angle), omega)
    )
    x1 = state_from_pose2(composed, x0[2])
    factor = ChunkOdometryFactor(chunk, X0, T, corrections=C(0), end=X1).factor()
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(x0))
    values.insert(X1, pose2_from_state(x1))
    values.insert(C(0), np.zeros(2))
    values.insert(T, THETA)
    assert np.abs(factor.unwhitenedError(values)).max() < 1e-12
    values.update(C(0), rng.normal(0, 1e-3, 2))
    values.update(X1, pose2_from_state(x1 + [0.01, -0.02, 0.003]))
    assert_jacobians(factor, values)


def test_error_is_zero_on_noise_free_data(clean_drive):
    data = gather_segments(clean_drive.truth, split_segments(clean_drive.truth, 150.0))
    poses, inputs = data.segment(0)
    factor = segment_odometry_factor(T, poses, inputs, start_key=X0)
    values = gtsam.Values()
    values.insert(T, clean_drive.theta_true)
    values.insert(X0, gtsam.Pose2(*data.poses[0, 0]))
    assert np.abs(factor.unwhitenedError(values)).max() < 1e-9


def test_smoothness_penalizes_the_change_of_corrected_rotations():
    measured = np.array([[0.15, 0.16], [0.151, 0.158], [0.149, 0.161]])
    next_first = np.array([0.152, 0.157])
    c0 = np.array([1e-3, -2e-3, -5e-4, 1e-3, 2e-4, 3e-4])
    c1 = np.array([-4e-4, 6e-4])
    values = gtsam.Values()
    values.insert(C(0), c0)
    values.insert(C(1), c1)
    within = chunk_correction_prior(C(0), measured, np.full((3, 2), 1e-3), 0.03)
    corrected = measured + c0.reshape(3, 2)
    size = c0
    change = np.diff(corrected, axis=0).ravel()
    expected = 0.5 * (np.sum((size / 1e-3) ** 2) + np.sum((change / 0.03) ** 2))
    assert within.error(values) == pytest.approx(expected, rel=1e-9)
    across = chunk_boundary_smoothness(C(0), 3, measured[-1], C(1), 1, next_first, 0.03)
    step = (next_first + c1) - (measured[-1] + c0[-2:])
    assert across.error(values) == pytest.approx(0.5 * np.sum((step / 0.03) ** 2), rel=1e-9)


def test_the_size_prior_is_the_corrections_noise_white_or_from_rounded_counts():
    """Without smoothness the prior is ½ cᵀ Σ⁻¹ c under the corrections' covariance Σ —
    white ``size²``, plus ``q²`` times [−1, 2, −1] per wheel for counts rounded by q — with
    one row per correction, as the dense linear factor it replaced (80 KB a chunk)."""
    rng = np.random.default_rng(3)
    measured = rng.uniform(0.1, 0.2, (4, 2))
    sizes = rng.uniform(4e-4, 6e-4, (4, 2))
    c = rng.normal(0.0, 1e-3, 8)
    values = gtsam.Values()
    values.insert(C(0), c)
    for q in (0.0, 0.003):
        prior = chunk_correction_prior(C(0), measured, sizes, None, q)
        n = 8
        covariance = np.diag(sizes.reshape(-1) ** 2) + q**2 * (
            2.0 * np.eye(n) - np.eye(n, k=2) - np.eye(n, k=-2)
        )
        expected = 0.5 * c @ np.linalg.solve(covariance, c)
        assert prior.error(values) == pytest.approx(expected, rel=1e-9)
        assert prior.dim() == n
        information = prior.linearize(values).information()
        np.testing.assert_allclose(information, np.linalg.inv(covariance), rtol=1e-9)


def test_theta_and_pose_factors_have_the_stated_sigmas():
    values = gtsam.Values()
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


def test_chunk_factor_needs_something_to_compare_with(segment):
    chunk = OdometryChunk(segment[1][:5], reference_heading=0.0)
    with pytest.raises(ValueError, match="measured poses to track or an end"):
        ChunkOdometryFactor(chunk, segment[0][0], T)
    with pytest.raises(ValueError, match="theta must be a key"):
        ChunkOdometryFactor(OdometryChunk(segment[1][:5], segment[0][:6]), X0, np.zeros(3))


@pytest.mark.parametrize("end", [True, False])
def test_chunk_factor_with_fixes_between_samples_and_missing_components(segment, end, rng):
    """Sparse fixes at their own times (part-way through steps), some samples without a
    fix, no heading at most: Jacobians of every slot against numerical derivatives."""
    poses, inputs = segment[0][:31], segment[1][:30]
    OFFSET, A, S = gtsam.symbol("o", 0), gtsam.symbol("a", 0), gtsam.symbol("s", 0)
    G = gtsam.symbol("g", 0)
    rates = rotation_rate_changes(inputs[:, :2], 0.025)
    fractions = rng.uniform(0.05, 1.0, 30)
    fractions[::7] = 1.0  # some fixes on the samples
    measured = np.zeros((31, 2), bool)
    measured[::4, 0] = True  # a position fix every 4th sample
    measured[::8, 1] = True  # a heading every 8th
    chunk = OdometryChunk(inputs, poses, float(poses[0, 2]), rates, fractions, measured)
    factor = ChunkOdometryFactor(
        chunk,
        X0,
        T,
        corrections=C(0),
        end=X1 if end else None,
        defects=DefectKeys(slip=S, time_offset=OFFSET, lever_arm=A, rear_slip_gain=G),
    ).factor()
    positions, headings = measured[1:, 0].sum(), measured[1:, 1].sum()
    assert factor.dim() == 2 * positions + headings + (3 if end else 0)
    values = gtsam.Values()
    values.insert(X0, pose2_from_state(poses[0] + [0.2, -0.1, 0.02]))
    if end:
        values.insert(X1, pose2_from_state(poses[-1] + [0.3, 0.1, -0.03]))
    values.insert(C(0), rng.normal(0, 1e-3, 60))
    values.insert(T, THETA)
    values.insert(S, np.array([1e-3, -2e-3]))
    values.insert(OFFSET, np.array([0.04]))
    values.insert(A, np.array([1.2, -0.4]))
    values.insert(G, np.array([0.005]))
    assert_jacobians(factor, values)


@pytest.mark.parametrize("sparse", [False, True])
def test_theta_systems_are_gtsams_linearization_at_each_theta(segment, sparse, rng):
    """A held-start chunk on theta alone (the paper's Step 1), evaluated at many thetas in
    one call: at each, GTSAM's augmented Hessian of the factor linearized there — with
    every sample tracked, and with fixes part-way through steps and headings missing."""
    poses, inputs = segment[0][:41], segment[1][:40]
    fractions = measured = None
    if sparse:
        fractions = rng.uniform(0.05, 1.0, 40)
        measured = np.zeros((41, 2), bool)
        measured[::3, 0] = True
        measured[::5, 1] = True
    chunk = OdometryChunk(inputs, poses, float(poses[0, 2]), None, fractions, measured)
    factor = ChunkOdometryFactor(chunk, poses[0], T, noise=ChunkNoise(pose_sigmas()))
    thetas = THETA + rng.normal(0.0, 1.0, (5, 4)) * [2e-3, 1e-3, 2e-2, 1e-3]
    systems = factor.theta_augmented_hessians(thetas)
    gtsam_factor = factor.factor()
    for theta, system in zip(thetas, systems, strict=True):
        values = gtsam.Values()
        values.insert(T, theta)
        augmented = gtsam_factor.linearize(values).augmentedInformation()
        h, g = system[:4, :4], system[:4, 4]
        np.testing.assert_allclose(h, augmented[:4, :4], rtol=1e-10)
        np.testing.assert_allclose(g, augmented[:4, 4], rtol=1e-10, atol=1e-12 * np.abs(g).max())
    with pytest.raises(ValueError, match="theta alone"):
        ChunkOdometryFactor(chunk, X0, T).theta_augmented_hessians(thetas)


def test_a_fix_part_way_through_a_step_is_eq_1_with_the_rotation_scaled(segment):
    """The prediction of a fix at fraction f of step k is eq. (1) from state k with the
    step's rotations times f: at f = 1 exactly state k+1, between the two in between."""
    from graphcal.model import integrate, partial_steps

    poses, inputs = segment[0][:11], segment[1][:10]
    states = integrate(poses[0], inputs, THETA)
    whole = partial_steps(states, inputs, THETA, np.ones(10))[0]
    np.testing.assert_array_equal(whole, states[1:])
    half = partial_steps(states, inputs, THETA, np.full(10, 0.5))[0]
    scaled = inputs.copy()
    scaled[:, :2] *= 0.5
    for k in range(10):
        expected = integrate(states[k], scaled[k : k + 1], THETA)[1]
        np.testing.assert_allclose(half[k], expected, atol=1e-12)
    travelled = np.linalg.norm(half[:, :2] - states[:-1, :2], axis=1)
    step = np.linalg.norm(states[1:, :2] - states[:-1, :2], axis=1)
    np.testing.assert_allclose(travelled, 0.5 * step, rtol=1e-4)
