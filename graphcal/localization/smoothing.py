"""A Pose2 smoothing graph with GNSS and graphcal's wheel odometry, theta as a variable.

The drop-in example of how graphcal's factors sit in a localization graph: Pose2 keyframes at
each GNSS fix (5 Hz by default, a lower rate than the 40 Hz wheel data), a GNSS position
factor on each, optionally a heading factor, :func:`keyframe_odometry_factor` between
consecutive keyframes, and theta as one 4-vector variable under a weak prior. One
Levenberg–Marquardt solve smooths the trajectory and calibrates theta together.

Real logs: the GNSS factors have a Huber noise model (``gnss_huber``), keyframes at samples
the loader masked (frozen fixes, jumps) or flagged (isolated spikes) get no GNSS factor, and
the antenna's lever arm can be a variable (``lever_arm_sigma``; the GNSS factors then are
:class:`~graphcal.factors.MeasuredPoseFactor`), tick counts get their rounding covariance
(``tick_quantization``) and slow wheel slip its scales (``slip_sigma``: one 2-vector per
``slip_span_s`` under a Gauss–Markov prior, :mod:`graphcal.graph.construction.slip`, and one per
GNSS gap). A wheel time offset is best corrected beforehand with the calibration's estimate
(:func:`graphcal.pipeline.methods.sensor_estimates.correct_log`), and the calibration's findings
about ticks and slip carried over (``scripts/smoothing_example.py
--sensors-from-calibration`` shows both).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.errors import GraphcalError
from graphcal.factors import MeasuredPoseFactor, theta_prior_factor
from graphcal.factors.preintegration import DEFAULT_WHEEL_NOISE
from graphcal.graph.construction.keyframes import fix_offsets, gnss_keyframes
from graphcal.graph.construction.keys import LEVER_ARM, THETA, gap_slip, keyframe, keyframe_slip
from graphcal.graph.construction.slip import slip_mean_sigma, slip_prior_factor, slip_step_factor
from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.covariance import marginal_covariance
from graphcal.graph.solution.observability import Observability, assess_observability
from graphcal.localization.keyframe_odometry import OdometryNoise, keyframe_odometry_factors
from graphcal.localization.values import insert_states, insert_theta, states_from_values
from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS, integrate, wrap_angle


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
    tick_quantization: float = 0.0
    slip_sigma: float = 0.0
    slip_time: float = 5.0
    slip_span_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("tick_quantization", "slip_sigma"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise GraphcalError(f"smoothing: {name} must be a number >= 0, got {value}")
        for name in ("slip_time", "slip_span_s"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise GraphcalError(f"smoothing: {name} must be positive seconds, got {value}")


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


def gnss_factor(
    log: DriveLog,
    key: int,
    k: int,
    offset: float,
    arm_key: int | None,
    settings: SmoothingSettings,
) -> gtsam.NonlinearFactor:
    """The fix of row ``k`` on keyframe ``key``: GTSAM's position prior, or, with a lever
    arm variable or a fix taken ``offset`` [m] behind the pose (its own time, before the
    row's), a :class:`~graphcal.factors.MeasuredPoseFactor`."""
    if arm_key is None and offset == 0.0:
        point = gtsam.Point2(log.px[k], log.py[k])
        return gtsam.PoseTranslationPrior2D(
            key, point, gnss_noise(settings.gnss_sigma, settings.gnss_huber)
        )
    return MeasuredPoseFactor(
        key,
        log.pose(k),
        np.full(3, settings.gnss_sigma),
        arm_key,
        with_heading=False,
        robust=settings.gnss_huber,
        offset=np.array([offset, 0.0]),
    ).factor()


def gnss_usable(log: DriveLog, keyframes: np.ndarray) -> np.ndarray:
    """Per keyframe: it holds a fix that may be used (not masked, not flagged as an
    outlying spike)."""
    usable = log.position_measured[keyframes].copy()
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
    arm_key = LEVER_ARM if settings.lever_arm_sigma > 0 else None
    if arm_key is not None:
        graph.add(
            gtsam.PriorFactorVector(
                arm_key, np.zeros(2), gtsam.noiseModel.Isotropic.Sigma(2, settings.lever_arm_sigma)
            )
        )
    usable = gnss_usable(log, keyframes)
    offsets = fix_offsets(log, keyframes, float(theta0[0]))
    for key, k, offset in zip(
        np.asarray(keys)[usable], keyframes[usable], offsets[usable], strict=True
    ):
        graph.add(gnss_factor(log, int(key), int(k), offset, arm_key, settings))
    if settings.heading_sigma is not None:
        heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, settings.heading_sigma)
        for key, k in zip(keys, keyframes, strict=True):
            if log.heading_measured[k]:  # no heading where none was logged
                graph.add(gtsam.PoseRotationPrior2D(key, gtsam.Rot2(log.psi[k]), heading_noise))
    slip_keys = None
    if settings.slip_sigma > 0:
        slip_keys = _slip_model(graph, log, keyframes, usable, settings)
    for factor in keyframe_odometry_factors(
        log,
        keyframes,
        keys,
        THETA,
        theta=theta0,
        noise=OdometryNoise(settings.wheel_noise, quantization=settings.tick_quantization),
        slip_keys=slip_keys,
    ):
        graph.add(factor)
    values = gtsam.Values()
    insert_theta(values, THETA, theta0)
    for key in [] if slip_keys is None else dict.fromkeys(slip_keys):
        values.insert(key, np.zeros(2))
    if arm_key is not None:
        values.insert(arm_key, np.zeros(2))
    insert_states(
        values, keys, _bridged_states(log, keyframes, usable, log.poses[keyframes], theta0)
    )
    return graph, values, keyframes


def _slip_model(
    graph: gtsam.NonlinearFactorGraph,
    log: DriveLog,
    keyframes: np.ndarray,
    usable: np.ndarray,
    settings: SmoothingSettings,
) -> list[int]:
    """The slip-scale key of each keyframe interval: spans of ``slip_span_s``
    (:func:`add_slip_spans`) where a usable fix ends both sides of the interval; across a
    GNSS gap (a run of intervals without), one scale for the whole gap under the prior of
    the Gauss–Markov process's mean over it
    (:func:`graphcal.graph.construction.slip.slip_mean_sigma`). Nothing but odometry holds the poses
    of a gap, and a chain of them with a scale per second (or noise of the slip's long-run variance
    per interval) was so loose that Levenberg–Marquardt crawled: 20 iterations instead of 8 on a
    12 km all-defects drive (seed 3), with theta within 2.5σ either way."""
    observed = usable[:-1] & usable[1:]
    keys: list[int] = [0] * (len(keyframes) - 1)
    modelled = np.flatnonzero(observed)
    if len(modelled):
        span_keys = add_slip_spans(
            graph,
            log.t[keyframes[modelled]],
            settings.slip_span_s,
            settings.slip_sigma,
            settings.slip_time,
        )
        for i, key in zip(modelled, span_keys, strict=True):
            keys[i] = key
    gaps = np.flatnonzero(~observed)
    if len(gaps):
        for number, run in enumerate(np.split(gaps, np.flatnonzero(np.diff(gaps) > 1) + 1)):
            duration = float(log.t[keyframes[run[-1] + 1]] - log.t[keyframes[run[0]]])
            sigma = slip_mean_sigma(duration, settings.slip_sigma, settings.slip_time)
            graph.add(slip_prior_factor(gap_slip(number), sigma))
            for i in run:
                keys[i] = gap_slip(number)
    return keys


def add_slip_spans(
    graph: gtsam.NonlinearFactorGraph,
    start_times: np.ndarray,
    span_s: float,
    sigma: float,
    slip_time: float,
) -> list[int]:
    """Slip scales for keyframe intervals starting at ``start_times`` [s]: one 2-vector per
    ``span_s`` of drive time that holds an interval, under the Gauss–Markov prior of
    :mod:`graphcal.graph.construction.slip` (added to ``graph``). Returns each interval's slip
    key."""
    span = np.floor((start_times - start_times[0]) / span_s).astype(int)
    spans, index = np.unique(span, return_inverse=True)
    span_keys = [keyframe_slip(i) for i in range(len(spans))]
    graph.add(slip_prior_factor(span_keys[0], sigma))
    for i in range(1, len(spans)):
        duration = float((spans[i] - spans[i - 1]) * span_s)
        graph.add(slip_step_factor(span_keys[i - 1], span_keys[i], duration, sigma, slip_time))
    return [span_keys[i] for i in index]


def _bridged_states(
    log: DriveLog,
    keyframes: np.ndarray,
    known: np.ndarray,
    states: np.ndarray,
    theta: np.ndarray,
) -> np.ndarray:
    """Keyframe states ``(M, 3)``: ``states`` where ``known``; across a run of unknown ones
    (an outlier, a frozen receiver) dead-reckoned with ``theta`` from the last known state
    and bent linearly onto the next one (headings too, so that they agree with the
    positions' direction) (a straight line across a 30 s outage
    would start the solve kilometres of odometry residual away). Runs at the log's ends
    hold the nearest usable position."""
    states = np.array(states, dtype=float)
    if known.all() or known.sum() < 2:
        return states
    good = np.flatnonzero(known)
    for axis in (0, 1):  # the ends' runs; the inner runs are replaced below
        states[~known, axis] = np.interp(np.flatnonzero(~known), good, states[good, axis])
    inputs = log.inputs
    gaps = np.flatnonzero(np.diff(good) > 1)
    for before, after in zip(good[gaps], good[gaps + 1], strict=True):
        a, b = int(keyframes[before]), int(keyframes[after])
        reckoned = integrate(states[before], inputs[a:b], theta)  # samples a .. b
        # Turned about the start so that it heads for the next fix: a fused heading's slow
        # bias at the gap's start would swing the whole chain (a nonlinear correction that
        # cost Levenberg–Marquardt 15 iterations instead of 7 on two 30 s outages).
        chord, reckoned_chord = (
            log.pose(b)[:2] - log.pose(a)[:2],
            reckoned[-1, :2] - reckoned[0, :2],
        )
        if np.hypot(*reckoned_chord) > 1.0:
            turn = wrap_angle(
                np.arctan2(chord[1], chord[0]) - np.arctan2(reckoned_chord[1], reckoned_chord[0])
            )
            c, s = np.cos(turn), np.sin(turn)
            offset = reckoned[:, :2] - reckoned[0, :2]
            reckoned[:, 0] = reckoned[0, 0] + c * offset[:, 0] - s * offset[:, 1]
            reckoned[:, 1] = reckoned[0, 1] + s * offset[:, 0] + c * offset[:, 1]
            reckoned[:, 2] += turn
        fraction = (keyframes[before : after + 1] - a) / (b - a)
        miss = states[after] - reckoned[-1]
        miss[2] = wrap_angle(miss[2])
        inside = slice(before + 1, after)
        states[inside] = reckoned[keyframes[inside] - a] + fraction[1:-1, None] * miss[None, :]
    return states


def smooth_drive(log: DriveLog, settings: SmoothingSettings | None = None) -> SmoothingResult:
    """Smooth ``log``'s trajectory from its GNSS positions and wheel odometry and calibrate
    theta in the same Levenberg–Marquardt solve.

    Raises:
        GraphcalError: if the solve fails.
    """
    settings = settings or SmoothingSettings()
    graph, values, keyframes = build_smoothing_graph(log, settings)
    options = SolveOptions(settings.max_iterations, 1e-8, "smoothing")
    result, outcome = solve_lm(graph, values, options, driver="python")
    keys = [keyframe(i) for i in range(len(keyframes))]
    arm = None
    if settings.lever_arm_sigma > 0:
        joint = marginal_covariance(graph, result, [THETA, LEVER_ARM], "smoothing", driver="python")
        covariance = joint[:4, :4]
        arm = (np.asarray(result.atVector(LEVER_ARM)), joint[4:, 4:])
    else:
        covariance = marginal_covariance(graph, result, THETA, "smoothing", driver="python")
    return SmoothingResult(
        keyframes,
        log.t[keyframes],
        states_from_values(result, keys, float(log.psi[keyframes[0]])),
        np.asarray(result.atVector(THETA)),
        covariance,
        assess_observability(covariance, settings.theta_prior_sigmas),
        outcome.iterations,
        arm,
    )
