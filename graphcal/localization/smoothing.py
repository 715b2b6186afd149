"""A Pose2 smoothing graph with GNSS and graphcal's wheel odometry, theta as a variable.

The drop-in example of how graphcal's factors sit in a localization graph: Pose2 keyframes at
each GNSS fix (5 Hz by default, a lower rate than the 40 Hz wheel data), a GNSS position
factor on each, optionally a heading factor, :func:`keyframe_odometry_factor` between
consecutive keyframes, and theta as one 4-vector variable under a weak prior. One
Levenberg–Marquardt solve smooths the trajectory and calibrates theta together.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.factors import theta_prior_factor
from graphcal.factors.preintegration import DEFAULT_WHEEL_NOISE
from graphcal.graph.keyframes import gnss_keyframes
from graphcal.graph.keys import THETA, keyframe
from graphcal.graph.observability import Observability, assess_observability
from graphcal.graph.solve import marginal_covariance, solve_lm
from graphcal.localization.keyframe_odometry import keyframe_odometry_factors
from graphcal.localization.values import insert_states, insert_theta, states_from_values
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS


@dataclass(frozen=True)
class SmoothingSettings:
    """Settings of :func:`smooth_drive` (SI).

    Attributes:
        gnss_rate_hz: keyframe and GNSS rate [Hz]; must divide the log's sampling rate.
        gnss_sigma: GNSS position standard deviation [m].
        heading_sigma: heading measurement sigma [rad], or ``None`` for GNSS positions only.
        theta_initial, theta_prior_sigmas: start and weak prior of theta.
        wheel_noise: wheel-rotation noise [rev] propagated into the odometry factors.
        max_iterations: Levenberg–Marquardt iteration limit.
    """

    gnss_rate_hz: float = 5.0
    gnss_sigma: float = 0.2
    heading_sigma: float | None = None
    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    wheel_noise: float = DEFAULT_WHEEL_NOISE
    max_iterations: int = 50


@dataclass(frozen=True)
class SmoothingResult:
    """The smoothed trajectory and theta (SI).

    Attributes:
        keyframes: sample indices of the keyframes ``(M,)``; ``t`` their times [s].
        states: smoothed ``[px, py, psi]`` at the keyframes ``(M, 3)``.
        theta, covariance: calibrated theta and its marginal covariance.
        observability: which parameters the drive determined.
        iterations: Levenberg–Marquardt iterations.
    """

    keyframes: np.ndarray
    t: np.ndarray
    states: np.ndarray
    theta: np.ndarray
    covariance: np.ndarray
    observability: Observability
    iterations: int


def build_smoothing_graph(
    log: DriveLog, settings: SmoothingSettings, keyframes: np.ndarray | None = None
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, np.ndarray]:
    """The smoothing graph of ``log``, its initial values (measured poses, nominal theta) and
    the keyframes' sample indices."""
    if keyframes is None:
        keyframes = gnss_keyframes(log, settings.gnss_rate_hz)
    keys = [keyframe(i) for i in range(len(keyframes))]
    theta0 = np.asarray(settings.theta_initial, float)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(theta_prior_factor(THETA, np.asarray(settings.theta_prior_sigmas), theta0))
    position_noise = gtsam.noiseModel.Isotropic.Sigma(2, settings.gnss_sigma)
    for key, k in zip(keys, keyframes, strict=True):
        graph.add(
            gtsam.PoseTranslationPrior2D(key, gtsam.Point2(log.px[k], log.py[k]), position_noise)
        )
    if settings.heading_sigma is not None:
        heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, settings.heading_sigma)
        for key, k in zip(keys, keyframes, strict=True):
            graph.add(gtsam.PoseRotationPrior2D(key, gtsam.Rot2(log.psi[k]), heading_noise))
    for factor in keyframe_odometry_factors(
        log, keyframes, keys, THETA, theta=theta0, wheel_noise=settings.wheel_noise
    ):
        graph.add(factor)
    values = gtsam.Values()
    insert_theta(values, THETA, theta0)
    insert_states(values, keys, log.poses[keyframes])
    return graph, values, keyframes


def smooth_drive(log: DriveLog, settings: SmoothingSettings | None = None) -> SmoothingResult:
    """Smooth ``log``'s trajectory from its GNSS positions and wheel odometry and calibrate
    theta in the same Levenberg–Marquardt solve.

    Raises:
        GraphcalError: if the solve fails.
    """
    settings = settings or SmoothingSettings()
    graph, values, keyframes = build_smoothing_graph(log, settings)
    result, iterations = solve_lm(graph, values, settings.max_iterations, 1e-8, "smoothing")
    keys = [keyframe(i) for i in range(len(keyframes))]
    covariance = marginal_covariance(graph, result, THETA, "smoothing")
    return SmoothingResult(
        keyframes,
        log.t[keyframes],
        states_from_values(result, keys, float(log.psi[keyframes[0]])),
        np.asarray(result.atVector(THETA)),
        covariance,
        assess_observability(covariance, settings.theta_prior_sigmas),
        iterations,
    )
