"""Wheel odometry between keyframes of a user's Pose2 graph: one factor per interval.

A localization graph has Pose2 variables at keyframes (e.g. at every GNSS fix, 5 Hz) while
the wheel encoders run faster (40 Hz). Each interval's wheel steps are preintegrated once
(:class:`~graphcal.factors.PreintegratedWheelOdometry`, the wheel noise propagated into the
increment's covariance), and the interval becomes

* with theta a variable: a :class:`~graphcal.factors.WheelOdometryFactor` (a Python factor:
  first-order theta correction, re-integration only when theta moves far);
* with theta fixed (a calibrated vehicle): a built-in ``gtsam.BetweenFactorPose2`` with the
  preintegrated increment and covariance — no Python in the optimizer loop
  (``docs/localization.md`` has the cost of both).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import GraphcalError
from graphcal.factors import (
    PreintegratedWheelOdometry,
    WheelOdometryFactor,
    preintegrate,
    wheel_odometry_between_factor,
)
from graphcal.factors.preintegration import DEFAULT_FLOOR_SIGMAS, DEFAULT_WHEEL_NOISE
from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL


def odometry_covariance(
    start_state: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    wheel_noise: float = DEFAULT_WHEEL_NOISE,
    floor_sigmas: Sequence[float] = DEFAULT_FLOOR_SIGMAS,
) -> np.ndarray:
    """World-frame covariance ``(3, 3)`` [m², m², rad²] of the predicted end state of an
    interval started at ``start_state``: the wheel-rotation noise ``wheel_noise`` [rev] of
    every step propagated by eq. (1)'s Jacobian at ``theta``, plus ``diag(floor_sigmas²)``."""
    body = preintegrate(inputs, theta, wheel_noise).covariance
    c, s = np.cos(start_state[2]), np.sin(start_state[2])
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return rotation @ body @ rotation.T + np.diag(np.asarray(floor_sigmas, float) ** 2)


@dataclass(frozen=True)
class OdometryNoise:
    """The wheel odometry's noise between keyframes.

    Attributes:
        wheel: standard deviation [rev] of one measured wheel rotation.
        floor_sigmas: model-error floor [m, m, rad] added to the propagated covariance.
        quantization: rounding sigma [rev] of the wheels' cumulative tick counts, or 0
            (:func:`graphcal.log.quantization.quantization_sigma`).
    """

    wheel: float = DEFAULT_WHEEL_NOISE
    floor_sigmas: Sequence[float] = DEFAULT_FLOOR_SIGMAS
    quantization: float = 0.0


def keyframe_odometry_factor(
    start_key: int,
    end_key: int,
    theta_key: int | None,
    inputs: np.ndarray,
    *,
    theta: np.ndarray = THETA_NOMINAL,
    noise: OdometryNoise = OdometryNoise(),
    slip_key: int | None = None,
    slip_noise: np.ndarray | None = None,
) -> gtsam.NonlinearFactor:
    """Wheel odometry over ``len(inputs)`` steps between two Pose2 keyframes.

    Args:
        start_key, end_key: the user's Pose2 variables at the interval's ends.
        theta_key: the shared 4-vector theta variable, or ``None`` to use ``theta`` fixed
            (the factor is then a C++ ``BetweenFactorPose2``).
        inputs: measured ``[n_rl, n_rr, beta, ay]`` of the steps, ``(L, 4)``.
        theta: the fixed theta (``theta_key=None``), or where the interval is preintegrated.
        noise: the wheels' noise, the model-error floor and the ticks' rounding
            (:class:`OdometryNoise`).
        slip_key: a 2-vector of relative wheel-slip scales for the interval (needs
            ``theta_key``; see :class:`~graphcal.factors.WheelOdometryFactor`), or ``None``.
        slip_noise: ``(2, 2)`` covariance of slip scales taken as noise instead, or ``None``.
    """
    inputs = np.asarray(inputs, float)
    if inputs.ndim != 2 or inputs.shape[1] != 4 or len(inputs) == 0:
        raise GraphcalError(
            f"keyframe odometry needs inputs (L, 4) with L >= 1, got {inputs.shape}"
        )
    preintegrated = preintegrate(inputs, theta, noise.wheel, quantization=noise.quantization)
    return _factor(
        start_key,
        end_key,
        theta_key,
        preintegrated,
        theta,
        noise.floor_sigmas,
        slip_key,
        slip_noise,
    )


def _factor(
    start_key: int,
    end_key: int,
    theta_key: int | None,
    preintegrated: PreintegratedWheelOdometry,
    theta: np.ndarray,
    floor_sigmas: Sequence[float],
    slip_key: int | None = None,
    slip_noise: np.ndarray | None = None,
) -> gtsam.NonlinearFactor:
    if theta_key is None:
        if slip_key is not None or slip_noise is not None:
            raise GraphcalError("wheel slip needs theta as a variable (theta_key)")
        return wheel_odometry_between_factor(start_key, end_key, preintegrated, theta, floor_sigmas)
    return WheelOdometryFactor(
        start_key,
        end_key,
        theta_key,
        preintegrated,
        floor_sigmas,
        slip_key=slip_key,
        slip_noise=slip_noise,
    ).factor()


def keyframe_odometry_factors(
    log: DriveLog,
    keyframes: np.ndarray,
    pose_keys: Sequence[int],
    theta_key: int | None,
    *,
    theta: np.ndarray = THETA_NOMINAL,
    noise: OdometryNoise = OdometryNoise(),
    slip_keys: Sequence[int | None] | None = None,
    slip_noise: Sequence[np.ndarray | None] | None = None,
) -> list[gtsam.NonlinearFactor]:
    """Odometry factors between consecutive keyframes of a slice of a drive log.

    Args:
        log: the drive log (its wheel rotations, sideslip and lateral acceleration are used).
        keyframes: increasing sample indices of the keyframes, ``(M,)``.
        pose_keys: the Pose2 keys of the keyframes, ``(M,)``.
        theta_key, theta, noise: as :func:`keyframe_odometry_factor`.
        slip_keys: per interval ``(M − 1,)``, the key of its slip scales (intervals may share
            one; ``None`` for an interval without), or ``None`` for no slip scales.
        slip_noise: per interval, a ``(2, 2)`` covariance of slip scales taken as noise
            instead (for intervals without a slip key), or ``None``.

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
    for name, given in (("slip keys", slip_keys), ("slip noises", slip_noise)):
        if given is not None and len(given) != len(keyframes) - 1:
            raise GraphcalError(
                f"{len(given)} {name} for {len(keyframes) - 1} intervals; give one each"
            )
    inputs = log.inputs
    intervals = [inputs[a:b] for a, b in itertools.pairwise(keyframes)]
    preintegrated = PreintegratedWheelOdometry.from_intervals(
        intervals, theta, noise.wheel, noise.quantization
    )
    return [
        _factor(
            pose_keys[i],
            pose_keys[i + 1],
            theta_key,
            p,
            theta,
            noise.floor_sigmas,
            None if slip_keys is None else slip_keys[i],
            None if slip_noise is None else slip_noise[i],
        )
        for i, p in enumerate(preintegrated)
    ]
