"""The joint solve's settings (:class:`JointSettings`): the weak prior on theta, the noise
of each kind of measurement, the defect model's terms and their priors, and what a run has
decided for itself (parameters held, time offsets per run, the rear slip gain modelled);
:func:`without_defect_model` is the model of a clean log."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.errors import check_settings
from graphcal.factors import PAPER_POSE_WEIGHTS, pose_sigmas
from graphcal.graph.construction.graph_spec import (
    FIX_ERROR_TIME,
    CorrectionPrior,
    SegmentGraphSpec,
)
from graphcal.graph.solution.observability import (
    DEFAULT_MAX_SIGMA_RATIO,
    Observability,
    assess_observability,
)
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS, reference_sigmas
from graphcal.vehicle import held_prior_sigmas

#: Largest prior mean [s] of the wheels' time offset: the graph shifts the rotations to first
#: order, which holds for tens of milliseconds, not for seconds.
MAX_TIME_OFFSET_MEAN = 1.0
#: ``JointSettings.slip``: model slow wheel slip when the log shows it, always, or never.
SLIP_MODES = ("auto", "on", "off")
#: How an error the fixes share is modelled (:attr:`JointSettings.fix_error`).
FIX_ERROR_MODES = ("auto", "off")
#: Relative error tolerance of the joint solves.
TOLERANCE = 1e-7


@dataclass(frozen=True)
class JointSettings:
    """Settings of the joint solve (SI).

    Attributes:
        theta_initial, theta_prior_sigmas: start and weak prior of theta.
        pose_weights, position_sigma: the paper's W with the position noise give the pose
            sigmas of the measurement and tracking residuals.
        wheel_noise: sigma [rev] of the measured wheel rotations: the corrections' prior.
        tick_quantization: sigma [rev] of the rounding error of each wheel's cumulative
            encoder count, ``1 / (ticks per revolution · √12)`` (from the vehicle profile, or
            detected in the log), or 0 for none.
        smoothness_weight: R on the change of corrected rotations; 0 leaves it out (with
            white rotation noise it adds nothing measurable, ``docs/method.md``).
        chunk_steps: steps per Python factor.
        continuity_sigmas: chunk-boundary continuity [m, m, rad].
        max_iterations: Levenberg–Marquardt iteration limit.
        max_sigma_ratio: a parameter counts as calibrated when the data shrink its prior
            sigma to at most this fraction (:mod:`graphcal.graph.solution.observability`).
        slip: ``"auto"`` (model slow wheel slip when the log shows it: see
            :func:`calibrate_joint`), ``"on"`` or ``"off"``.
        slip_sigma: stationary sigma of the modelled relative slip scale of each rear wheel
            per chunk (slow, coloured slip; 0.0015 = 0.15 %).
        slip_time: correlation time [s] of the slip scales from chunk to chunk.
        slip_alpha: with ``slip = "auto"``, the false-alarm rate of the slip screen's test
            (:mod:`graphcal.pipeline.solvers.slip_screen`): slip is modelled when adding it lowers
            χ² by more than the data's own noise would at this rate.
        unseen_slip_sigma: relative σ of the slow variation of the wheels' effective
            circumference (speed, load, tyre temperature) that a drive cannot show: where slip
            is not modelled (``slip = "auto"``: the slip screen's system gives it; ``"off"``
            adds none), theta's σ includes what it moves the solved theta by
            (:func:`~graphcal.pipeline.solvers.slip_screen.unseen_slip_covariance`;
            0.002 = 0.2 %; 0: the data's σ alone).
        unseen_slip_time: its correlation time [s].
        time_offset_sigma: prior sigma [s] of the wheels' time offset against the pose,
            estimated with theta (0: not estimated).
        time_offset_mean: that prior's mean [s]: the offset left in the log's wheels after
            it was shifted by whole samples (the batches get the whole-log estimate's rest).
        lever_arm_sigma: prior sigma [m] of each component of the GNSS antenna's lever arm,
            estimated with theta (0: not estimated).
        heading_bias_sigma: prior sigma [rad] of a per-segment bias of the measured heading
            (a fused heading's slow bias; 0: none).
        rear_slip_gain_sigma: prior sigma [rad per m/s²] of the rear tyres' slip gain of a
            log without a sideslip (:mod:`graphcal.factors.rear_slip`; 0: never estimated),
            estimated where ``rear_slip_modelled``.
        fix_error: an error the fixes share, a first-order Gauss–Markov process (a GNSS
            receiver's slowly varying error): ``"auto"`` models it when the residuals show
            one (:mod:`graphcal.pipeline.methods.noise_levels`) or with ``fix_error_sigma`` when
            that is above 0, ``"off"`` never (white fix errors only).
        fix_error_sigma: its stationary sigma [m] per axis when known (0: from the
            residuals), and ``fix_error_time`` its correlation time [s].
        robust_threshold: fixes whose position residual exceeds this many times the
            residuals' scale are down-weighted (:mod:`graphcal.pipeline.solvers.robust`; 0: off).
        heading_noise_from_log: the heading weight of ``pose_weights`` follows the heading's
            white noise measured in the log (:mod:`graphcal.log.noise`) instead of the
            vehicle's ``heading_sigma``.
        wheel_noise_from_log: ``wheel_noise`` is raised to the white noise the recording's
            own wheel rates show (``DriveLog.wheel_noise``) where that is larger.
        fix_d: d is held at its ``theta_initial`` (the vehicle's ``fix_d``; its prior sigma in
            ``theta_prior_sigmas`` is then the vehicle's tight one): reported as fixed.
        tie_segments: consecutive segments of a continuous stretch are one trajectory (each
            starts at the end pose of the one before, :mod:`graphcal.graph.construction.builder`);
            ``False``: every segment has a free start under its measured pose.
        model_check: when the defect model finds a time offset, a lever arm or slip, check
            it against theta alone on held-apart segments and calibrate with the one that
            predicts them better (:mod:`graphcal.pipeline.methods.model_check`).
        time_offset_means: the time offset prior's mean per run of the log [s] (the rest
            each run's shift left, for the batches and the model check), overriding
            ``time_offset_mean``; empty: ``time_offset_mean`` for every run. Not a setting.
        held_at_prior: parameters the data did not determine, which a run holds at
            ``theta_initial`` by a tight prior (:meth:`holding`, :meth:`solve_prior_sigmas`);
            each is judged on the data's information all the same. Not a setting.
        tolerance: a solve stops when an iteration lowers χ² by less than this share of it
            (:data:`TOLERANCE`; looser for the model check's folds). Not a setting.
        rear_slip_modelled: the rear slip gain is a variable: the log has no sideslip and
            shows the gain (set by :func:`~graphcal.pipeline.methods.prepare.prepare_log`;
            a log of the centre of gravity's sideslip has its slip logged). Not a setting.
    """

    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    pose_weights: tuple[float, float, float] = PAPER_POSE_WEIGHTS
    position_sigma: float = 0.2
    wheel_noise: float = 0.0005
    tick_quantization: float = 0.0
    smoothness_weight: float = 0.0
    chunk_steps: int = 50
    continuity_sigmas: tuple[float, float, float] = (1e-3, 1e-3, 1e-4)
    max_iterations: int = 50
    max_sigma_ratio: float = DEFAULT_MAX_SIGMA_RATIO
    slip: str = "auto"
    slip_sigma: float = 0.0015
    slip_time: float = 5.0
    slip_alpha: float = 1e-3
    unseen_slip_sigma: float = 2e-3
    unseen_slip_time: float = 120.0
    time_offset_sigma: float = 0.5
    time_offset_mean: float = 0.0
    lever_arm_sigma: float = 2.0
    heading_bias_sigma: float = 0.02
    rear_slip_gain_sigma: float = 0.01
    fix_error: str = "auto"
    fix_error_sigma: float = 0.0
    fix_error_time: float = FIX_ERROR_TIME
    robust_threshold: float = 5.0
    heading_noise_from_log: bool = True
    wheel_noise_from_log: bool = True
    fix_d: bool = False
    tie_segments: bool = True
    model_check: bool = True
    held_at_prior: tuple[str, ...] = field(default=(), metadata={"run_state": True})
    time_offset_means: tuple[float, ...] = field(default=(), metadata={"run_state": True})
    tolerance: float = field(default=TOLERANCE, metadata={"run_state": True})
    rear_slip_modelled: bool = field(default=False, metadata={"run_state": True})

    def held(self) -> np.ndarray:
        """``(4,)`` the parameters a tight prior holds at ``theta_initial`` (``fix_d``)."""
        return np.array([False, False, False, self.fix_d])

    def held_names(self) -> tuple[str, ...]:
        """The parameters a solve holds at their prior: ``held_at_prior``, and d with
        ``fix_d``."""
        return (
            *self.held_at_prior,
            *(("d",) if self.fix_d and "d" not in self.held_at_prior else ()),
        )

    def holding(self, names: list[str] | tuple[str, ...]) -> JointSettings:
        """These settings with the parameters ``names`` held at ``theta_initial`` too
        (:meth:`solve_prior_sigmas`): what the data do not determine stays where the prior
        has it, whatever the prior's width."""
        added = tuple(n for n in names if n not in self.held_at_prior)
        return dataclasses.replace(self, held_at_prior=(*self.held_at_prior, *added))

    def solve_prior_sigmas(self) -> np.ndarray:
        """``(4,)`` the theta prior's sigmas a solve uses: ``theta_prior_sigmas``, those of
        the parameters ``held_at_prior`` :data:`~graphcal.vehicle.HELD_SIGMA_SCALE` times as
        large. A held parameter's uncertainty is still its ``theta_prior_sigmas``'."""
        return held_prior_sigmas(self.theta_prior_sigmas, self.held_at_prior)

    def observability(self, covariance: np.ndarray) -> Observability:
        """What a solve's theta ``covariance`` (under this prior) says the data determined,
        judged against the reference sigmas of a vehicle of nominal ``theta_initial``
        (:func:`graphcal.graph.solution.observability.assess_observability`), not the prior's."""
        return assess_observability(
            covariance,
            self.solve_prior_sigmas(),
            self.max_sigma_ratio,
            self.held(),
            reference_sigmas=reference_sigmas(self.theta_initial),
        )

    def __post_init__(self) -> None:
        if self.slip not in SLIP_MODES:
            raise ValueError(
                f"joint.slip must be one of {', '.join(SLIP_MODES)}, got {self.slip!r}"
            )
        if self.fix_error not in FIX_ERROR_MODES:
            raise ValueError(
                f"joint.fix_error must be one of {', '.join(FIX_ERROR_MODES)}, "
                f"got {self.fix_error!r}"
            )
        if not 0.0 < self.slip_alpha < 1.0:  # NaN fails too
            raise ValueError(f"joint.slip_alpha must be in (0, 1), got {self.slip_alpha!r}")
        means = (self.time_offset_mean, *self.time_offset_means)
        bad = [m for m in means if not abs(m) <= MAX_TIME_OFFSET_MEAN]  # NaN fails too
        if bad:
            raise ValueError(
                f"joint.time_offset_mean must be a number of seconds within "
                f"±{MAX_TIME_OFFSET_MEAN:g}, got {bad[0]!r}"
            )
        check_settings(
            "joint",
            positive_vectors={
                "theta_prior_sigmas": self.theta_prior_sigmas,
                "pose_weights": self.pose_weights,
                "continuity_sigmas": self.continuity_sigmas,
            },
            finite_vectors={"theta_initial": self.theta_initial},
            positive={
                "position_sigma": self.position_sigma,
                "wheel_noise": self.wheel_noise,
                "slip_time": self.slip_time,
                "fix_error_time": self.fix_error_time,
                "slip_sigma": self.slip_sigma,
                "slip_alpha": self.slip_alpha,
                "unseen_slip_time": self.unseen_slip_time,
                "max_sigma_ratio": self.max_sigma_ratio,
            },
            non_negative={
                "smoothness_weight": self.smoothness_weight,
                "unseen_slip_sigma": self.unseen_slip_sigma,
                "tick_quantization": self.tick_quantization,
                "time_offset_sigma": self.time_offset_sigma,
                "lever_arm_sigma": self.lever_arm_sigma,
                "heading_bias_sigma": self.heading_bias_sigma,
                "rear_slip_gain_sigma": self.rear_slip_gain_sigma,
                "fix_error_sigma": self.fix_error_sigma,
                "robust_threshold": self.robust_threshold,
            },
            at_least_one={"chunk_steps": self.chunk_steps, "max_iterations": self.max_iterations},
        )

    def graph_spec(self, theta_prior: bool = True, slip: bool | None = None) -> SegmentGraphSpec:
        """The joint segment graph; ``theta_prior=False`` leaves out the weak prior on theta
        (the measurements' information alone, as the Cramér–Rao bound needs); ``slip``
        includes the slip scales (default: only with ``slip = "on"``)."""
        if slip is None:
            slip = self.slip == "on"
        sigmas = pose_sigmas(self.pose_weights, self.position_sigma)
        smooth = self.smoothness_weight > 0
        return SegmentGraphSpec(
            theta=np.asarray(self.theta_initial, float),
            tracking_sigmas=sigmas,
            theta_prior_sigmas=self.solve_prior_sigmas() if theta_prior else None,
            start_prior_sigmas=sigmas,
            chunk_steps=self.chunk_steps,
            continuity_sigmas=np.asarray(self.continuity_sigmas, float),
            corrections=CorrectionPrior(
                sigma=self.wheel_noise,
                smoothness_sigma=1.0 / np.sqrt(self.smoothness_weight) if smooth else None,
                quantization=self.tick_quantization,
            ),
            slip_sigma=self.slip_sigma if slip else None,
            slip_time=self.slip_time,
            time_offset_sigma=_optional(self.time_offset_sigma),
            time_offset_mean=self.time_offset_means or self.time_offset_mean,
            lever_arm_sigma=_optional(self.lever_arm_sigma),
            heading_bias_sigma=_optional(self.heading_bias_sigma),
            rear_slip_gain_sigma=(
                _optional(self.rear_slip_gain_sigma) if self.rear_slip_modelled else None
            ),
            fix_error_sigma=_optional(self.fix_error_sigma) if self.fix_error != "off" else None,
            fix_error_time=self.fix_error_time,
            tie_segments=self.tie_segments,
        )


def without_sensor_terms(settings: JointSettings) -> JointSettings:
    """``settings`` without the defect model's sensor terms: no time offset, lever arm,
    heading biases, rear slip gain or slip (the noise levels and robust weights stay)."""
    return dataclasses.replace(
        settings,
        time_offset_sigma=0.0,
        lever_arm_sigma=0.0,
        heading_bias_sigma=0.0,
        rear_slip_gain_sigma=0.0,
        slip="off",
    )


def without_defect_model(settings: JointSettings) -> JointSettings:
    """``settings`` estimating theta alone: no sensor terms (:func:`without_sensor_terms`),
    shared fix error or robust weights (the model of a clean log)."""
    return dataclasses.replace(
        without_sensor_terms(settings),
        robust_threshold=0.0,
        fix_error="off",
        heading_noise_from_log=False,
        wheel_noise_from_log=False,
    )


def _optional(sigma: float) -> float | None:
    """A prior sigma, or ``None`` for 0 (the variable left out)."""
    return float(sigma) if sigma > 0 else None
