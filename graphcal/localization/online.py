"""Online recalibration: theta estimated while the vehicle drives, in a fixed-lag smoother.

Keyframes arrive at the GNSS rate; each update adds the new Pose2 with its GNSS factor and
the wheel-odometry factor from the previous keyframe (:func:`keyframe_odometry_factor`) to a
``gtsam.IncrementalFixedLagSmoother`` (iSAM2 underneath). Variables older than the lag are
marginalized, so the cost of an update does not grow with the length of the drive.

Theta changes slowly in real vehicles (tyre pressure and wear, load), so it is modelled as a
**random walk between time slices**: a new theta variable every ``theta_slice_s`` seconds,
joined to the previous one by a zero-mean ``BetweenFactorVector`` with standard deviation
``theta_random_walk · sqrt(theta_slice_s)``. Compared with re-anchoring (restarting the
estimate when a change is detected) this needs no change detector, follows gradual drifts as
well as steps, and its one tuning knob has a plain meaning: the random walk sets the
estimator's time constant, ``τ ≈ 1 / sqrt(q · I)`` for a random-walk intensity ``q`` and an
information rate ``I`` about the parameter. The default for c_e, 4e-5 m/√s, gives τ ≈ 50 s on
city driving (a 3 mm step is followed within about a kilometre) with a steady-state
standard deviation of about 0.3 mm.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.errors import GraphcalError
from graphcal.factors import pose2_from_state, state_from_pose2, theta_prior_factor
from graphcal.factors.measured_pose import MeasuredPoseFactor
from graphcal.factors.preintegration import DEFAULT_WHEEL_NOISE
from graphcal.graph.construction.keyframes import fix_offsets, gnss_keyframes
from graphcal.graph.construction.keys import keyframe as _pose_key
from graphcal.graph.construction.keys import theta as _theta_key
from graphcal.graph.construction.slip import slip_noise_covariance
from graphcal.localization.keyframe_odometry import OdometryNoise, keyframe_odometry_factor
from graphcal.localization.smoothing import gnss_noise, gnss_usable
from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS, integrate
from graphcal.progress import Progress, reports_progress, say


@dataclass(frozen=True)
class OnlineSettings:
    """Settings of :func:`run_online` (SI).

    Attributes:
        gnss_rate_hz, gnss_sigma, heading_sigma: keyframe/GNSS rate [Hz], position sigma
            [m], heading sigma [rad] or ``None`` for positions only.
        lag_s: smoother window [s]; older variables are marginalized.
        theta_slice_s: duration [s] of one theta variable.
        theta_random_walk: random-walk intensity of ``[c_e, c_d, t_r, d]`` per √s.
        theta_initial, theta_prior_sigmas: start and prior of the first theta.
        initial_heading_sigma: prior [rad] on the first keyframe's heading (from the log).
        wheel_noise: wheel-rotation noise [rev] propagated into the odometry factors.
        relinearize_threshold: iSAM2 relinearization threshold on variable updates.
        relinearize_skip: iSAM2 checks for relinearization every this many updates. Theta
            moves at every update and touches every odometry factor of the window, so each
            check relinearizes all of them (Python factors): 50 instead of GTSAM's 10 cut
            the update cost 2.0× on the bench's 3.5 km drive (13.3 → 6.5 ms per second of
            driving), every theta slice within 0.027σ and σ within 1.1 % of it
            (``docs/performance.md``).
        gnss_huber: Huber threshold [in σ] of the GNSS factors (0: Gaussian). Keyframes at
            masked or flagged samples get no GNSS factor. Correct a time offset or lever arm
            beforehand with the calibration's estimates
            (:func:`graphcal.pipeline.methods.sensor_estimates.correct_log`).
        tick_quantization: rounding sigma [rev] of the wheels' cumulative tick counts, or 0.
        slip_sigma, slip_time: slow wheel slip (stationary relative sigma, correlation time
            [s]), or ``slip_sigma`` 0 for none. Online it is noise of each interval with the
            slip's long-run variance
            (:func:`graphcal.graph.construction.slip.slip_noise_covariance`), not scale variables:
            on a 4 km drive with 0.15 % slip and 96-tick counts that kept every theta slice within
            3σ at 1.1× the update cost of the plain smoother, where scale variables (one per second)
            cost about 2×.
    """

    gnss_rate_hz: float = 5.0
    gnss_sigma: float = 0.2
    heading_sigma: float | None = None
    lag_s: float = 30.0
    theta_slice_s: float = 10.0
    theta_random_walk: np.ndarray = field(
        default_factory=lambda: np.array([4e-5, 1e-6, 1e-4, 1e-6])
    )
    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    initial_heading_sigma: float = 0.1
    wheel_noise: float = DEFAULT_WHEEL_NOISE
    relinearize_threshold: float = 1e-5
    relinearize_skip: int = 50
    gnss_huber: float = 3.0
    tick_quantization: float = 0.0
    slip_sigma: float = 0.0
    slip_time: float = 5.0

    def __post_init__(self) -> None:
        if not all(np.isfinite(v) and v >= 0 for v in (self.tick_quantization, self.slip_sigma)):
            raise GraphcalError("online: tick_quantization and slip_sigma must be numbers >= 0")
        if not self.slip_time > 0:
            raise GraphcalError("online: slip_time must be positive seconds")
        if not (isinstance(self.relinearize_skip, int) and self.relinearize_skip >= 1):
            raise GraphcalError("online: relinearize_skip must be a whole number >= 1")
        if not (self.lag_s > 0 and self.theta_slice_s > 0):
            raise GraphcalError("online: lag_s and theta_slice_s must be positive seconds")
        if self.theta_slice_s > self.lag_s:
            raise GraphcalError(
                f"online: theta_slice_s ({self.theta_slice_s:g} s) must not exceed lag_s "
                f"({self.lag_s:g} s), or a theta slice would leave the window before it ends"
            )


@dataclass(frozen=True)
class OnlineResult:
    """Theta as the vehicle drove (SI).

    Attributes:
        t: end time [s] of each theta slice ``(S,)``; ``distance_m`` the distance travelled
            by then ``(S,)`` (from the wheel rotations with c_e = 2 m).
        theta, sigma: the estimate of the slice's theta when the slice ended and its standard
            deviation, ``(S, 4)``.
        update_seconds: wall time of every smoother update ``(U,)``; ``update_t`` the drive
            time [s] of each.
        states: the filtered keyframe states ``(M, 3)`` (each estimated when it arrived) and
            ``keyframes`` their sample indices.
    """

    t: np.ndarray
    distance_m: np.ndarray
    theta: np.ndarray
    sigma: np.ndarray
    update_seconds: np.ndarray
    update_t: np.ndarray
    states: np.ndarray
    keyframes: np.ndarray

    def seconds_per_drive_second(self) -> float:
        """Total update time per second of driving."""
        span = float(self.update_t[-1] - self.update_t[0]) if len(self.update_t) > 1 else 1.0
        return float(self.update_seconds.sum() / span)


@reports_progress
def run_online(
    log: DriveLog,
    settings: OnlineSettings | None = None,
    progress: Progress | None = None,
) -> OnlineResult:
    """Feed ``log`` keyframe by keyframe into a fixed-lag smoother that estimates the
    trajectory and a slowly varying theta; return theta per slice and the update times."""
    settings = settings or OnlineSettings()
    keyframes = gnss_keyframes(log, settings.gnss_rate_hz)
    if len(keyframes) < 2:
        raise GraphcalError("online: the log is shorter than two GNSS intervals")
    run = _OnlineRun(log, settings, keyframes)
    t0 = run.start()
    report_every = max(1, len(keyframes) // 10)
    for i in range(1, len(keyframes)):
        t = run.add_keyframe(i)
        if i % report_every == 0:
            say(f"online: {t - t0:.0f} s driven, c_e {run.theta[0]:.5f} m")
    return run.result()


def _fixed_lag_smoother(settings: OnlineSettings) -> gtsam.IncrementalFixedLagSmoother:
    """iSAM2 under a fixed lag of ``settings.lag_s`` seconds."""
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(settings.relinearize_threshold)
    params.relinearizeSkip = settings.relinearize_skip
    return gtsam.IncrementalFixedLagSmoother(settings.lag_s, params)


class _KeyframeMeasurements:
    """The GNSS factors of the keyframes: a position prior at a usable fix (a measured-pose
    factor with a known offset behind the pose when the fix was taken before the row's
    time) and, with a heading sigma, a heading prior where the heading was measured."""

    def __init__(self, log: DriveLog, keyframes: np.ndarray, settings: OnlineSettings):
        self.log, self.settings = log, settings
        self.position_noise = gnss_noise(settings.gnss_sigma, settings.gnss_huber)
        self.usable = dict(
            zip(keyframes.tolist(), gnss_usable(log, keyframes).tolist(), strict=True)
        )
        self.offsets = dict(
            zip(
                keyframes.tolist(),
                fix_offsets(log, keyframes, settings.theta_initial[0]),
                strict=True,
            )
        )
        self.heading_noise = (
            None
            if settings.heading_sigma is None
            else gtsam.noiseModel.Isotropic.Sigma(1, settings.heading_sigma)
        )

    def factors(self, key: int, k: int) -> list:
        """The factors on pose ``key`` of the keyframe at sample ``k``."""
        log, usable, offsets = self.log, self.usable, self.offsets
        out = []
        if usable[int(k)] and offsets[int(k)] == 0.0:
            point = gtsam.Point2(log.px[k], log.py[k])
            out.append(gtsam.PoseTranslationPrior2D(key, point, self.position_noise))
        elif usable[int(k)]:  # a fix taken before the row's time: a known offset behind
            sigmas = np.full(3, self.settings.gnss_sigma)
            offset = np.array([offsets[int(k)], 0.0])
            factor = MeasuredPoseFactor(
                key, log.pose(k), sigmas, None, None, False, self.settings.gnss_huber, offset
            )
            out.append(factor.factor())
        if self.heading_noise is not None and log.heading_measured[k]:
            out.append(gtsam.PoseRotationPrior2D(key, gtsam.Rot2(log.psi[k]), self.heading_noise))
        return out


class _OnlineRun:
    """The smoother of :func:`run_online` as it goes: the latest state and theta, the theta
    slice open now, and what the result keeps (closed slices, filtered states, update
    times)."""

    def __init__(self, log: DriveLog, settings: OnlineSettings, keyframes: np.ndarray):
        self.log, self.settings, self.keyframes = log, settings, keyframes
        self.inputs = log.inputs
        self.smoother = _fixed_lag_smoother(settings)
        self.measurements = _KeyframeMeasurements(log, keyframes, settings)
        self.walk = gtsam.noiseModel.Diagonal.Sigmas(
            np.asarray(settings.theta_random_walk, float) * np.sqrt(settings.theta_slice_s)
        )
        self.theta = np.asarray(settings.theta_initial, float)
        self.state = log.poses[keyframes[0]].copy()
        self.states = [self.state]
        self.slice_index, self.slice_start = 0, 0.0
        self.slice_t: list[float] = []
        self.slice_theta: list[np.ndarray] = []
        self.slice_sigma: list[np.ndarray] = []
        self.update_seconds: list[float] = []
        self.update_t: list[float] = []

    def start(self) -> float:
        """Add the first keyframe (its GNSS factors and a heading prior from the log) and
        the first theta with its prior; return the first keyframe's time [s]."""
        log, settings, first = self.log, self.settings, self.keyframes[0]
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        t0 = float(log.t[first])
        values.insert(_pose_key(0), pose2_from_state(log.poses[first]))
        values.insert(_theta_key(0), self.theta)
        for f in self.measurements.factors(_pose_key(0), first):
            graph.add(f)
        graph.add(
            gtsam.PoseRotationPrior2D(
                _pose_key(0),
                gtsam.Rot2(log.psi[first]),
                gtsam.noiseModel.Isotropic.Sigma(1, settings.initial_heading_sigma),
            )
        )
        prior_sigmas = np.asarray(settings.theta_prior_sigmas)
        graph.add(theta_prior_factor(_theta_key(0), prior_sigmas, self.theta))
        stamps = {_pose_key(0): t0, _theta_key(0): t0}
        self.smoother.update(graph, values, _timestamps(stamps))
        self.slice_start = t0
        return t0

    def close_slice(
        self, t: float, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, stamps: dict
    ) -> None:
        """Keep the open slice's theta and sigma as of ``t`` [s] and open the next slice,
        joined to it by the random walk (into ``graph``, ``values`` and ``stamps``)."""
        covariance = self.smoother.marginalCovariance(_theta_key(self.slice_index))
        self.slice_t.append(t)
        self.slice_theta.append(self.theta)
        self.slice_sigma.append(np.sqrt(np.diag(covariance)))
        self.slice_index, self.slice_start = self.slice_index + 1, t
        previous, key = _theta_key(self.slice_index - 1), _theta_key(self.slice_index)
        values.insert(key, self.theta)
        graph.add(gtsam.BetweenFactorVector(previous, key, np.zeros(4), self.walk))
        stamps[previous] = t

    def add_keyframe(self, i: int) -> float:
        """Add keyframe ``i`` (a new theta slice first when the open one is over), update
        the smoother and take its estimates of the keyframe's state and theta; return the
        keyframe's time [s]."""
        log, settings = self.log, self.settings
        a, b = int(self.keyframes[i - 1]), int(self.keyframes[i])
        t = float(log.t[b])
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), {}
        if t - self.slice_start >= settings.theta_slice_s:  # close the slice, open the next
            self.close_slice(t, graph, values, stamps)
        predicted = integrate(self.state, self.inputs[a:b], self.theta)[-1]
        values.insert(_pose_key(i), pose2_from_state(predicted))
        for f in self.measurements.factors(_pose_key(i), b):
            graph.add(f)
        graph.add(self.odometry_factor(i, a, b))
        stamps[_pose_key(i)] = t
        stamps[_theta_key(self.slice_index)] = t
        start = time.perf_counter()
        try:
            self.smoother.update(graph, values, _timestamps(stamps))
        except RuntimeError as exc:
            raise GraphcalError(f"online update at t = {t:.1f} s failed: {exc}") from exc
        self.update_seconds.append(time.perf_counter() - start)
        self.update_t.append(t)
        estimate = self.smoother.calculateEstimatePose2(_pose_key(i))
        self.state = state_from_pose2(estimate, float(predicted[2]))
        self.theta = np.asarray(self.smoother.calculateEstimateVector(_theta_key(self.slice_index)))
        self.states.append(self.state)
        return t

    def odometry_factor(self, i: int, a: int, b: int) -> gtsam.NonlinearFactor:
        """The wheel-odometry factor from keyframe ``i-1`` (sample ``a``) to ``i`` (sample
        ``b``) on the open slice's theta, with the slip's noise if modelled."""
        log, settings = self.log, self.settings
        slip_noise = None
        if settings.slip_sigma > 0:
            slip_noise = slip_noise_covariance(
                float(log.t[b] - log.t[a]), settings.slip_sigma, settings.slip_time
            )
        return keyframe_odometry_factor(
            _pose_key(i - 1),
            _pose_key(i),
            _theta_key(self.slice_index),
            self.inputs[a:b],
            theta=self.theta,
            noise=OdometryNoise(settings.wheel_noise, quantization=settings.tick_quantization),
            slip_noise=slip_noise,
        )

    def result(self) -> OnlineResult:
        """Theta per closed slice, the filtered states and the update times."""
        travelled = self.log.travelled_distance()
        return OnlineResult(
            np.asarray(self.slice_t),
            np.interp(self.slice_t, self.log.t, travelled),
            np.asarray(self.slice_theta),
            np.asarray(self.slice_sigma),
            np.asarray(self.update_seconds),
            np.asarray(self.update_t),
            np.asarray(self.states),
            self.keyframes,
        )


def _timestamps(stamps: dict[int, float]) -> gtsam.FixedLagSmootherKeyTimestampMap:
    out = gtsam.FixedLagSmootherKeyTimestampMap()
    for key, t in stamps.items():
        out.insert((key, t))
    return out
