"""A Pose2 smoothing graph with GNSS and graphcal's wheel odometry, theta as a variable.

The drop-in example of how graphcal's factors sit in a localization graph: Pose2 keyframes at
each GNSS fix (5 Hz by default, a lower rate than the 40 Hz wheel data), a GNSS position
factor on each, optionally a heading factor, :func:`keyframe_odometry_factor` between
consecutive keyframes, and theta as one 4-vector variable under a weak prior. One
Levenberg–Marquardt solve smooths the trajectory and calibrates theta together.

Real logs: the GNSS factors have a Huber noise model (``gnss_huber``), keyframes at samples
the loader masked (frozen fixes, jumps) or flagged (isolated spikes) get no GNSS factor, and
the antenna's lever arm can be a variable (``lever_arm_sigma``; the GNSS factors then are
:class:`~graphcal.factors.MeasuredPoseFactor`). A wheel time offset is best corrected
beforehand with the calibration's estimate
(:func:`graphcal.pipeline.sensor_estimates.correct_log`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.factors import MeasuredPoseFactor, theta_prior_factor
from graphcal.factors.preintegration import DEFAULT_WHEEL_NOISE
from graphcal.graph.keyframes import gnss_keyframes
from graphcal.graph.keys import LEVER_ARM, THETA, keyframe
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
        gnss_huber: Huber threshold [in σ] of the GNSS factors (0: Gaussian).
        lever_arm_sigma: prior sigma [m] of the antenna's lever arm, estimated as a variable
            (0, the default: not estimated, the positions taken as the centre of gravity's;
            its Python factor per keyframe made a 12 km smoothing 1.8× slower, so correct
            the log with the calibration's arm instead, or opt in).
    """

    gnss_rate_hz: float = 5.0
    gnss_sigma: float = 0.2
    heading_sigma: float | None = None
    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    wheel_noise: float = DEFAULT_WHEEL_NOISE
    max_iterations: int = 50
    gnss_huber: float = 3.0
    lever_arm_sigma: float = 0.0


@dataclass(frozen=True)
class SmoothingResult:
    """The smoothed trajectory and theta (SI).

    Attributes:
        keyframes: sample indices of the keyframes ``(M,)``; ``t`` their times [s].
        states: smoothed ``[px, py, psi]`` at the keyframes ``(M, 3)``.
        theta, covariance: calibrated theta and its marginal covariance.
        observability: which parameters the drive determined.
        iterations: Levenberg–Marquardt iterations.
        lever_arm: estimated lever arm ``[ahead, left]`` [m] and its covariance ``(2, 2)``,
            or ``None`` when not estimated.
    """

    keyframes: np.ndarray
    t: np.ndarray
    states: np.ndarray
    theta: np.ndarray
    covariance: np.ndarray
    observability: Observability
    iterations: int
    lever_arm: tuple[np.ndarray, np.ndarray] | None = None


def gnss_usable(log: DriveLog, keyframes: np.ndarray) -> np.ndarray:
    """Per keyframe: its fix may be used (not masked, not flagged as an outlying spike)."""
    usable = np.ones(len(keyframes), dtype=bool)
    for flags in (log.masked, log.outlying):
        if flags is not None:
            usable &= ~np.asarray(flags)[keyframes]
    return usable


def gnss_noise(sigma: float, huber: float) -> gtsam.noiseModel.Base:
    """Isotropic 2-D GNSS noise, robust (Huber at ``huber`` σ) unless ``huber`` is 0."""
    noise = gtsam.noiseModel.Isotropic.Sigma(2, sigma)
    if huber > 0:
        noise = gtsam.noiseModel.Robust.Create(
            gtsam.noiseModel.mEstimator.Huber.Create(huber), noise
        )
    return noise


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
    position_noise = gnss_noise(settings.gnss_sigma, settings.gnss_huber)
    arm_key = LEVER_ARM if settings.lever_arm_sigma > 0 else None
    if arm_key is not None:
        graph.add(
            gtsam.PriorFactorVector(
                arm_key, np.zeros(2), gtsam.noiseModel.Isotropic.Sigma(2, settings.lever_arm_sigma)
            )
        )
    sigmas = np.full(3, settings.gnss_sigma)
    usable = gnss_usable(log, keyframes)
    for key, k in zip(np.asarray(keys)[usable], keyframes[usable], strict=True):
        if arm_key is None:
            point = gtsam.Point2(log.px[k], log.py[k])
            graph.add(gtsam.PoseTranslationPrior2D(int(key), point, position_noise))
        else:
            measured = log.poses[k]
            factor = MeasuredPoseFactor(
                int(key), measured, sigmas, arm_key, with_heading=False, robust=settings.gnss_huber
            )
            graph.add(factor.factor())
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
    if arm_key is not None:
        values.insert(arm_key, np.zeros(2))
    insert_states(values, keys, _initial_states(log, keyframes, usable))
    return graph, values, keyframes


def _initial_states(log: DriveLog, keyframes: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Initial keyframe states: the measured poses, with the positions of unusable fixes
    interpolated between the usable ones (an outlier's position is no starting point)."""
    states = log.poses[keyframes].copy()
    if usable.all() or usable.sum() < 2:
        return states
    good = np.flatnonzero(usable)
    for axis in (0, 1):
        states[~usable, axis] = np.interp(np.flatnonzero(~usable), good, states[good, axis])
    return states


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
    arm = None
    if settings.lever_arm_sigma > 0:
        joint = marginal_covariance(graph, result, [THETA, LEVER_ARM], "smoothing")
        covariance = joint[:4, :4]
        arm = (np.asarray(result.atVector(LEVER_ARM)), joint[4:, 4:])
    else:
        covariance = marginal_covariance(graph, result, THETA, "smoothing")
    return SmoothingResult(
        keyframes,
        log.t[keyframes],
        states_from_values(result, keys, float(log.psi[keyframes[0]])),
        np.asarray(result.atVector(THETA)),
        covariance,
        assess_observability(covariance, settings.theta_prior_sigmas),
        iterations,
        arm,
    )
