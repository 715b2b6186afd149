"""All settings of a calibration run, with the paper's values as defaults (§4.4, §5.1).

One schema: TOML sections and keys are the dataclass field names, recursively. Load a file
with :func:`~graphcal.pipeline.configuration.settings_file.load_settings`; :func:`settings_to_dict`
(or :meth:`Settings.to_dict`) gives the plain-data view written into ``calibration.json``. A file
may set any subset; a missing key keeps the default of the enclosing setting.

The ``[vehicle]`` section (:class:`graphcal.vehicle.VehicleProfile`; also a file of its own,
:func:`~graphcal.pipeline.configuration.settings_file.load_vehicle`) describes the vehicle: its
nominal theta, the poses' and wheels' noise. It supplies the defaults of the settings that depend on
the vehicle — ``theta_initial``, ``theta_prior_sigmas``, ``pose_weights`` and ``position_sigma`` of
``[calibration]`` and ``[joint]``, ``[joint] wheel_noise``, and the segment lengths of
``[segments]``: the car's 150 m and 300 m scaled by the vehicle's track over the car's 1.55 m
(19.4 m and 38.7 m for a 0.2 m robot)
(:func:`~graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`); a key given in
``[calibration]``, ``[joint]`` or ``[segments]`` of the same file overrides it. Without
``[vehicle]`` the vehicle is the paper's car. The yaw-rate threshold (0.15 rad/s) stays: a robot
turns faster than a car.

Every section and key, with the defaults::

    [segments]                  # the paper's car defaults
    length = 150.0              # (v) m, × track / 1.55 m; at least 5 tracks
    # stride = 50.0             # m; omit for disjoint segments
    min_yaw_rate = 0.15         # rad/s
    yaw_statistic = "mean"      # mean | median | rms
    yaw_window = 1.0            # s, window of the yaw-rate difference
    validation_length = 300.0   # (v) m, × track / 1.55 m

    [batches]
    size = 9                    # segments per batch
    count = 100                 # the paper's study (§5.1) draws 1000: --batches 1000
    seed = 0
    joint_solve = "linearized"  # joint batches from one linearization; "exact": a solve each

    [calibration]               # batch solves of Steps 1, 3 and 5
    theta_initial = [2.0, 0.0, 1.55, 0.0]           # (v) c_e m, c_d m, t_r m, d s²
    theta_prior_sigmas = [0.1, 0.01, 0.2, 0.01]     # (v) same units
    pose_weights = [1.0, 1.0, 50.0]                 # (v) the paper's W on x, y, heading
    position_sigma = 0.2        # (v) m
    estimate_start_poses = false  # Step 1 holds the start; [staged] frees it in Steps 3, 5
    max_iterations = 5

    [staged]                    # --method staged: Steps 2 and 4
    heading_correction_step = 10  # k of eq. (15)
    heading_correction = "start"  # start | paper (eq. 15 verbatim)
    estimations = 12            # input estimations per segment in Step 4
    trim_fraction = 0.1         # dropped at each end before averaging
    estimate_start_poses = true # in Steps 3 and 5; false = the paper's held start

    [staged.step2]              # input estimation of Step 2
    tracking_weights = [1.0, 1.0, 1.0]              # Q on x, y, heading
    smoothness_weight = 1000.0  # R on the change of the corrected rotations
    input_bound = 0.05          # relative bound on the corrections
    chunk_steps = 50
    continuity_sigmas = [0.01, 0.01, 0.001]         # m, m, rad
    max_iterations = 10

    [staged.step4]              # input estimation of Step 4
    tracking_weights = [1.0, 1.0, 10.0]
    smoothness_weight = 1000.0
    input_bound = 0.05
    chunk_steps = 50
    continuity_sigmas = [0.01, 0.01, 0.001]         # m, m, rad
    max_iterations = 10

    [joint]                     # --method joint and whole
    theta_initial = [2.0, 0.0, 1.55, 0.0]           # (v) c_e m, c_d m, t_r m, d s²
    theta_prior_sigmas = [0.1, 0.01, 0.2, 0.01]     # (v) what "not observable" leaves
    pose_weights = [1.0, 1.0, 50.0]                 # (v)
    position_sigma = 0.2        # (v) m
    wheel_noise = 0.0005        # (v) rev, sigma of the corrections' prior
    tick_quantization = 0.0     # (v) rev, encoder count rounding (detected in the log if 0)
    smoothness_weight = 0.0     # R on the change of the corrections; 0 = off
    chunk_steps = 50
    continuity_sigmas = [0.001, 0.001, 0.0001]      # m, m, rad
    max_iterations = 50
    max_sigma_ratio = 0.1       # calibrated = σ at most this share of its reference sigma
    slip = "auto"               # slow wheel slip modelled: auto (when the log shows it) | on | off
    slip_sigma = 0.0015         # its relative scale per wheel and chunk (0.15 %)
    slip_time = 5.0             # s, its correlation time from chunk to chunk
    slip_alpha = 0.001          # auto: false-alarm rate of the test that decides it
    unseen_slip_sigma = 0.002   # slow slip no test can show (0.2 %), in theta's σ; 0 = off
    unseen_slip_time = 120.0    # s, its correlation time
    time_offset_sigma = 0.5     # s, prior of the wheels' time offset (estimated); 0 = off
    time_offset_mean = 0.0      # s, its prior mean (the offset known to remain in the log)
    lever_arm_sigma = 2.0       # m, prior of the GNSS antenna's lever arm (estimated); 0 = off
    heading_bias_sigma = 0.02   # rad, prior of a per-segment heading bias; 0 = off
    rear_slip_gain_sigma = 0.01 # rad per m/s², prior of the rear tyres' slip gain (a log
                                # without sideslip, with the lever arm estimated); 0 = off
    fix_error = "auto"          # the fixes' slowly varying shared error (Gauss–Markov):
                                # auto (when the residuals show it) | off
    fix_error_sigma = 0.0       # m per axis, when known; 0 = from the residuals
    fix_error_time = 60.0       # s, its correlation time
    robust_threshold = 5.0      # fixes beyond this many residual sigmas down-weighted; 0 = off
    heading_noise_from_log = true  # heading weight from the log's own heading noise
    wheel_noise_from_log = true    # wheel_noise raised to the recording's wheel rates' noise
    fix_d = false               # (v) d held at theta_initial (the vehicle's fix_d)
    tie_segments = true         # consecutive segments of a continuous stretch: one trajectory
    model_check = true          # a time offset, lever arm or slip found: checked against
                                # theta alone on held-apart segments; the better one is used

    [lever_arm]                 # GNSS antenna ahead of / left of the centre of gravity
                                # (of the rear axle in a log without sideslip)
    longitudinal = 0.0          # m, when known; the positions are moved by it (the
    lateral = 0.0               # m   estimated arm is then what remains)

    [vehicle]                   # the paper's car; defaults of the keys marked (v) above
    name = "paper car"
    theta_nominal = [2.0, 0.0, 1.55, 0.0]           # c_e m, c_d m, t_r m, d s² -> theta_initial
    theta_prior_sigmas = [0.1, 0.01, 0.2, 0.01]     # same units -> theta_prior_sigmas
    position_sigma = 0.2        # m -> position_sigma
    heading_sigma = 0.0282842712474619  # rad -> pose_weights [1, 1, (0.2 / it)²] = [1, 1, 50]
    wheel_noise = 0.0005        # rev per sample interval -> [joint] wheel_noise
    # ticks_per_revolution = 64 # encoder resolution -> [joint] tick_quantization 1/(ticks √12)
    reverses = false            # true: backwards wheels are motion (spins, reversing)
    fix_d = false               # true: d held at its nominal (no load transfer)
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from graphcal.log.segments import YawRateStatistic
from graphcal.pipeline.solvers.batch_calibration import BatchSettings
from graphcal.pipeline.solvers.input_estimation import InputEstimationSettings
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.vehicle import VehicleProfile

#: Shortest segment, in tracks of the vehicle (7.75 m for the car, 1 m for a 0.2 m robot):
#: a shorter one turns through too little for its own start pose and heading.
MIN_SEGMENT_TRACKS = 5.0
#: Upper limit [rad/s] of the yaw-rate selection threshold: no road vehicle keeps a mean yaw
#: rate near it over a calibration segment, so a larger value is a unit or typing mistake.
MAX_MIN_YAW_RATE = 1.0


@dataclass(frozen=True)
class SegmentSettings:
    """How the log is cut and which segments calibrate (§5.1); lengths in m, rates in rad/s.

    The defaults are the paper's car (150 m calibration and 300 m validation segments, a mean
    yaw rate above 0.15 rad/s). With a vehicle profile the lengths follow its size
    (:func:`~graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`: scaled by its track
    over the car's), unless set; a segment should hold a few bends and last some tens of seconds.
    The yaw-rate threshold stays, since a small vehicle turns tighter than a car. A length must be
    at least :data:`MIN_SEGMENT_TRACKS` tracks of the vehicle (checked by :class:`Settings`).
    """

    length: float = 150.0
    stride: float | None = None
    min_yaw_rate: float = 0.15
    yaw_statistic: YawRateStatistic = "mean"
    yaw_window: float = 1.0
    validation_length: float = 300.0

    def __post_init__(self) -> None:
        for name in ("length", "validation_length"):
            if not getattr(self, name) > 0:
                raise ValueError(f"segments.{name} must be a positive length in m")
        if not self.yaw_window > 0:
            raise ValueError("segments.yaw_window must be positive")
        if self.stride is not None and not self.stride >= 1.0:
            raise ValueError("segments.stride must be at least 1 m")
        if not 0 <= self.min_yaw_rate < MAX_MIN_YAW_RATE:
            raise ValueError(
                f"segments.min_yaw_rate must be >= 0 and below {MAX_MIN_YAW_RATE:g} rad/s "
                f"({np.degrees(MAX_MIN_YAW_RATE):.0f}°/s; a car's mean yaw rate over a segment "
                f"stays far below it), got {self.min_yaw_rate:g}"
            )
        if self.yaw_statistic not in ("mean", "median", "rms"):
            raise ValueError("segments.yaw_statistic must be mean, median or rms")


@dataclass(frozen=True)
class BatchingSettings:
    """Batches of distinct segments (§4.3: N = 9).

    The paper's study (§5.1) draws 1000 batches; the default draws 100, enough for the
    spreads, NEES and the spread-versus-σ check (their sampling error is about 10 %), at a
    tenth of the time (``--batches 1000`` restores the study). The recommended theta is the
    whole-log solve and does not depend on the count.

    ``joint_solve`` is how the joint method solves its batches
    (:mod:`graphcal.pipeline.methods.joint_batches`): ``"linearized"`` (every segment's system at
    the whole-log solution, summed per batch: the study costs about one whole-log iteration) or
    ``"exact"`` (one Levenberg–Marquardt solve per batch, 1–2 s each).
    """

    size: int = 9
    count: int = 100
    seed: int = 0
    joint_solve: str = "linearized"

    def __post_init__(self) -> None:
        if self.size < 1 or self.count < 0:
            raise ValueError(
                "batches.size must be at least 1 and batches.count at least 0 (0: no batch "
                "study, one solve over the whole log, as --batches 0)"
            )
        if self.seed < 0:
            raise ValueError("batches.seed must be >= 0")
        if self.joint_solve not in ("linearized", "exact"):
            raise ValueError(
                f"batches.joint_solve must be linearized or exact, got {self.joint_solve!r}"
            )


@dataclass(frozen=True)
class StagedSettings:
    """Steps 2 and 4 of the paper (§4.3, §4.4).

    Attributes:
        step2, step4: input-estimation settings; they differ in the heading weight q_psi.
        heading_correction_step: k of eq. (15) (paper: 10).
        heading_correction: how Step 2 corrects the heading.
            ``"paper"`` is eq. (15) verbatim: Δψ = ψ̂_k − ψ̃_k added to every measured heading
            of the segment; right when the heading error is a slowly varying bias (a
            Kalman-filtered heading, as on the paper's vehicle).
            ``"start"`` (default) corrects only the held initial heading, by the yaw the
            estimated inputs add over the first k steps: Δψ = ψ̂_k − ψ_k(measured inputs).
            With white heading noise (the paper's simulation model) eq. (15) swaps the start's
            noise for the noise at sample k: measured on 30 synthetic segments at 1.5°
            noise, the start heading error was 1.38° uncorrected, 2.36° after eq. (15) and
            0.95° after ``"start"``.
        estimations: input estimations per segment in Step 4 (paper: 12).
        trim_fraction: fraction dropped at each end before averaging the estimations
            (paper: mean of the middle 80 %, i.e. 0.1).
        estimate_start_poses: in Steps 3 and 5, estimate each segment's start pose under its
            (heading-corrected) measurement prior instead of holding it. The paper holds it;
            with noisy wheel rotations a held start biases d and t_r even when the start
            heading is exact (measured with the true start heading on 40 batches of a 24 km
            synthetic drive: d +0.08 mm·s²/m, t_r −7.6 mm), and d dominates the validation
            error. Estimating it brought the median validation error of Step 5 from 0.27 m to
            0.07 m above the reachable limit. ``False`` reproduces the paper.
    """

    step2: InputEstimationSettings = field(default_factory=InputEstimationSettings)
    step4: InputEstimationSettings = field(
        default_factory=lambda: InputEstimationSettings(tracking_weights=(1.0, 1.0, 10.0))
    )
    heading_correction_step: int = 10
    heading_correction: str = "start"
    estimations: int = 12
    trim_fraction: float = 0.1
    estimate_start_poses: bool = True

    def __post_init__(self) -> None:
        if self.heading_correction_step < 1 or self.estimations < 1:
            raise ValueError("heading_correction_step and estimations must be at least 1")
        if not 0 <= self.trim_fraction < 0.5:
            raise ValueError("trim_fraction must be in [0, 0.5)")
        if self.heading_correction not in ("start", "paper"):
            raise ValueError("heading_correction must be 'start' or 'paper'")


@dataclass(frozen=True)
class LeverArmSettings:
    """The GNSS antenna's lever arm (:mod:`graphcal.log.antenna`), ahead of and left of the
    centre of gravity [m] — of the rear axle in a log without sideslip
    (:meth:`~graphcal.log.drive_log.DriveLog.position_reference`).

    Attributes:
        longitudinal, lateral: the arm, when known (from the vehicle's drawings); the
            positions are moved to that point by it before calibrating. The
            joint solve estimates what remains (``[joint] lever_arm_sigma``).
    """

    longitudinal: float = 0.0
    lateral: float = 0.0

    def __post_init__(self) -> None:
        for name in ("longitudinal", "lateral"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"lever_arm.{name} must be a finite number of metres")


@dataclass(frozen=True)
class Settings:
    """Everything that shapes a calibration run. Defaults are the paper's (and its car)."""

    segments: SegmentSettings = field(default_factory=SegmentSettings)
    batches: BatchingSettings = field(default_factory=BatchingSettings)
    calibration: BatchSettings = field(
        default_factory=lambda: BatchSettings(estimate_start_poses=False, max_iterations=5)
    )
    staged: StagedSettings = field(default_factory=StagedSettings)
    joint: JointSettings = field(default_factory=JointSettings)
    #: The vehicle: nominal theta for the log's checks, segment distances and the report.
    #: Changing it alone leaves the other sections as they are;
    #: :func:`~graphcal.pipeline.configuration.vehicle_settings.apply_vehicle` makes the settings
    #: that depend on it follow.
    vehicle: VehicleProfile = field(default_factory=VehicleProfile)
    lever_arm: LeverArmSettings = field(default_factory=LeverArmSettings)

    def __post_init__(self) -> None:
        track = float(self.vehicle.theta_nominal[2])
        shortest = MIN_SEGMENT_TRACKS * track
        options = (("length", "segment-length"), ("validation_length", "validation-length"))
        for name, option in options:
            if getattr(self.segments, name) < shortest:
                raise ValueError(
                    f"segments.{name} {getattr(self.segments, name):g} m is shorter than "
                    f"{MIN_SEGMENT_TRACKS:g} tracks of the vehicle ({shortest:g} m for its "
                    f"{track:g} m track); set --{option} or [segments] {name} to at least "
                    f"{shortest:g} m, or give the vehicle (--vehicle) it belongs to"
                )

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view (lists instead of arrays), as written into ``calibration.json``."""
        return settings_to_dict(self)


def settings_to_dict(settings: Any) -> dict[str, Any]:
    """Plain data of a settings dataclass: sub-tables for dataclasses, lists for vectors.

    An unset optional value stays ``None`` (JSON ``null``); a TOML writer leaves it out. A
    field a run sets for itself (metadata ``run_state``) is not a setting and is left out.
    """
    return {f.name: _plain(getattr(settings, f.name)) for f in setting_fields(settings)}


def setting_fields(settings: Any) -> list[dataclasses.Field]:
    """The fields of a settings dataclass a user sets (not the ``run_state`` ones)."""
    return [f for f in dataclasses.fields(settings) if not f.metadata.get("run_state")]


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return settings_to_dict(value)
    if isinstance(value, np.ndarray | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
