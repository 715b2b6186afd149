"""Wheel odometry between keyframes of a user's Pose2 graph: one factor per interval.

A localization graph has Pose2 variables at keyframes (e.g. at every GNSS fix, 5 Hz) while
the wheel encoders run faster (40 Hz). :func:`keyframe_odometry_factor` integrates eq. (1)
over all wheel steps between two keyframes inside one factor — like IMU preintegration — and
compares the predicted end pose with the next keyframe's Pose2:

    error = integrate(start pose, wheel inputs, theta)[end] − end pose      (world frame)

Its noise is the wheel-rotation noise propagated through the model (``J Σ_u Jᵀ`` with the
analytic Jacobian of eq. 1, plus a small floor for model error), so the factor weighs a
short, straight interval tightly and a long, turning one loosely, as it should. Theta is a
4-vector variable ``[c_e, c_d, t_r, d]`` (SI) shared by all factors, or a fixed value.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.errors import GraphcalError
from graphcal.factors.odometry import OdometryChunkError
from graphcal.model import THETA_NOMINAL, integrate, wheel_rotation_jacobian

#: Standard deviation [rev] of a measured wheel rotation per sample (the paper's, §3.3).
DEFAULT_WHEEL_NOISE = 0.0005
#: Model-error floor [m, m, rad] added to every interval's propagated covariance.
DEFAULT_FLOOR_SIGMAS = (1e-3, 1e-3, 1e-4)


def odometry_covariance(
    start_state: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    wheel_noise: float = DEFAULT_WHEEL_NOISE,
    floor_sigmas: Sequence[float] = DEFAULT_FLOOR_SIGMAS,
) -> np.ndarray:
    """Covariance ``(3, 3)`` [m², m², rad²] of the predicted end state of an interval.

    The wheel-rotation noise ``wheel_noise`` [rev] of every step, propagated by the
    Jacobian of eq. (1) at ``theta``, plus ``diag(floor_sigmas²)``.
    """
    states = integrate(np.asarray(start_state, float), inputs, theta)
    jacobian = wheel_rotation_jacobian(states, inputs, theta)[-1].reshape(3, -1)
    floor = np.asarray(floor_sigmas, float) ** 2
    return wheel_noise**2 * jacobian @ jacobian.T + np.diag(floor)


def keyframe_odometry_factor(
    start_key: int,
    end_key: int,
    theta_key: int | None,
    inputs: np.ndarray,
    reference_heading: float,
    theta: np.ndarray = THETA_NOMINAL,
    wheel_noise: float = DEFAULT_WHEEL_NOISE,
    floor_sigmas: Sequence[float] = DEFAULT_FLOOR_SIGMAS,
) -> gtsam.CustomFactor:
    """Wheel odometry over ``len(inputs)`` steps between two Pose2 keyframes.

    Args:
        start_key, end_key: the user's Pose2 variables at the interval's ends.
        theta_key: the shared 4-vector theta variable, or ``None`` to use ``theta`` fixed.
        inputs: measured ``[n_rl, n_rr, beta, ay]`` of the steps, ``(L, 4)``.
        reference_heading: approximate start heading [rad] (unwraps the Pose2 angle; any
            value within ±π of the truth gives the same factor).
        theta: the fixed theta (``theta_key=None``), and where the noise is propagated.
        wheel_noise, floor_sigmas: see :func:`odometry_covariance`.
    """
    inputs = np.asarray(inputs, float)
    if inputs.ndim != 2 or inputs.shape[1] != 4 or len(inputs) == 0:
        raise GraphcalError(
            f"keyframe odometry needs inputs (L, 4) with L >= 1, got {inputs.shape}"
        )
    theta = np.asarray(theta, float)
    error = OdometryChunkError(
        inputs,
        reference_heading=reference_heading,
        has_end=True,
        theta=None if theta_key is not None else theta,
    )
    start = np.array([0.0, 0.0, reference_heading])
    covariance = odometry_covariance(start, inputs, theta, wheel_noise, floor_sigmas)
    noise = gtsam.noiseModel.Gaussian.Covariance(covariance)
    keys = [start_key, end_key] + ([] if theta_key is None else [theta_key])
    return gtsam.CustomFactor(noise, keys, error)


def keyframe_odometry_factors(
    log: DriveLog,
    keyframes: np.ndarray,
    pose_keys: Sequence[int],
    theta_key: int | None,
    theta: np.ndarray = THETA_NOMINAL,
    wheel_noise: float = DEFAULT_WHEEL_NOISE,
    floor_sigmas: Sequence[float] = DEFAULT_FLOOR_SIGMAS,
) -> list[gtsam.CustomFactor]:
    """Odometry factors between consecutive keyframes of a slice of a drive log.

    Args:
        log: the drive log (its wheel rotations, sideslip and lateral acceleration are used;
            its measured heading only to unwrap angles).
        keyframes: increasing sample indices of the keyframes, ``(M,)``.
        pose_keys: the Pose2 keys of the keyframes, ``(M,)``.
        theta_key, theta, wheel_noise, floor_sigmas: as :func:`keyframe_odometry_factor`.

    Returns:
        ``M − 1`` factors; factor ``i`` joins keyframes ``i`` and ``i + 1``.
    """
    keyframes = np.asarray(keyframes, int)
    if len(keyframes) != len(pose_keys):
        raise GraphcalError(
            f"{len(keyframes)} keyframes but {len(pose_keys)} pose keys; give one key each"
        )
    if len(keyframes) < 2 or np.any(np.diff(keyframes) <= 0):
        raise GraphcalError("keyframes must be at least two strictly increasing sample indices")
    if keyframes[0] < 0 or keyframes[-1] >= len(log):
        raise GraphcalError(f"keyframes must lie within the log's {len(log)} samples")
    inputs = log.inputs
    return [
        keyframe_odometry_factor(
            pose_keys[i],
            pose_keys[i + 1],
            theta_key,
            inputs[a:b],
            float(log.psi[a]),
            theta,
            wheel_noise,
            floor_sigmas,
        )
        for i, (a, b) in enumerate(itertools.pairwise(keyframes))
    ]
