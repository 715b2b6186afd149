"""What every method calibrates from: the segments selected, the settings the log itself
completes (tick rounding, heading noise), the positions moved by the known lever arm, the
fixes the loader flagged weighted down, and the segments' signals gathered."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.factors import pose_sigmas
from graphcal.log.antenna import move_to_centre
from graphcal.log.drive_log import DriveLog
from graphcal.log.excitation import lever_arm_sigma
from graphcal.log.noise import heading_noise, position_noise
from graphcal.log.quantization import quantization_sigma, ticks_per_revolution
from graphcal.log.segments import SegmentData, Segments, gather_segments
from graphcal.log.timing import MAX_LAG_S, masked_for_the_clock_lag, wheel_lag_from_turns
from graphcal.model import step_increments
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.methods.noise_levels import REWEIGHTED
from graphcal.pipeline.methods.selection import select
from graphcal.progress import say
from graphcal.units import length_unit

#: Weight of a fix the loader flagged as an isolated spike (its sigma ×100).
FLAGGED_WEIGHT = 1e-4


@dataclass(frozen=True)
class PreparedLog:
    """A log ready to calibrate (SI).

    Attributes:
        log: the drive log, positions moved to the centre of gravity by the known lever arm.
        settings: the run's settings, completed from the log (tick rounding, heading noise).
        segments: all calibration segments; ``selected`` those passing the selection.
        yaw_rate: the selection statistic of every calibration segment [rad/s].
        validation_segments: the validation segments.
        fix_weights: per sample of ``log``, the weight of its fix (``None``: all 1).
        data, validation: the selected and the validation segments' signals.
        warnings: what a user must know about the log (masked samples).
        left_out: sensor quantities the settings estimate but the drive cannot show, left
            out of the graph (:func:`_with_observable_lever_arm`): name → prior sigma.
        held: parameters of theta the settings hold at their prior because the recording
            cannot show them (:func:`_with_d_the_drive_can_show`): name → why.
    """

    log: DriveLog
    settings: Settings
    segments: Segments
    yaw_rate: np.ndarray
    selected: Segments
    validation_segments: Segments
    fix_weights: np.ndarray | None
    data: SegmentData
    validation: SegmentData
    warnings: tuple[str, ...]
    left_out: dict[str, float] = dataclasses.field(default_factory=dict)
    held: dict[str, str] = dataclasses.field(default_factory=dict)
    wheel_lag: np.ndarray | None = None


def prepare_log(log: DriveLog, settings: Settings, fall_back_to_all: bool) -> PreparedLog:
    """``log`` cut, selected (:func:`~graphcal.pipeline.methods.selection.select`, with
    ``fall_back_to_all``) and gathered, with the settings it completes.

    Raises:
        NoUsableSegments: no segment passes the selection, or the log is too short.
    """
    wheel_lag = _wheel_lag(log, settings)
    log = masked_for_the_clock_lag(log, wheel_lag)
    segments, yaw, selected, validation_segments = select(log, settings, fall_back_to_all)
    settings = _with_detected_ticks(log, settings)
    settings = _with_wheel_noise(log, settings)
    settings = _with_position_noise(log, settings)
    settings = _with_heading_noise(log, settings)
    arm = settings.lever_arm
    log = move_to_centre(log, (arm.longitudinal, arm.lateral))  # a known arm
    flagged = None  # spikes the loader flagged get (almost) no weight
    if log.outlying is not None:
        flagged = np.where(log.outlying, FLAGGED_WEIGHT, 1.0)
    data = gather_segments(log, selected, flagged)
    settings, left_out = _with_observable_lever_arm(data, settings, log.position_sensor())
    turning = mean_wheel_yaw_rate(data, settings.joint.theta_initial)
    settings, held = _with_d_the_drive_can_show(log, turning, settings)
    settings, held = _with_t_r_the_drive_can_show(data, turning, settings, held)
    settings = _with_rear_slip_gain_where_it_shows(log, settings)
    return PreparedLog(
        log=log,
        settings=settings,
        segments=segments,
        yaw_rate=yaw,
        selected=selected,
        validation_segments=validation_segments,
        fix_weights=flagged,
        data=data,
        validation=gather_segments(log, validation_segments),
        warnings=_mask_warnings(log),
        left_out=left_out,
        held=held,
        wheel_lag=wheel_lag,
    )


def runs_label(runs: int) -> str:
    """`` (runs 0–3)`` after a list of one value per run; empty for one run."""
    return "" if runs == 1 else f" (runs 0–{runs - 1})"


def _wheel_lag(log: DriveLog, settings: Settings) -> np.ndarray:
    """Each run's lag [s] of the wheels behind the measured heading's turns, in whole samples
    (:func:`~graphcal.log.timing.wheel_lag_from_turns`), where the wheels' time offset is
    estimated; else none. Seconds of it (clocks apart, such as GPS time and UTC by 18 s)
    are said here: the log is masked for them before it is cut."""
    if not settings.joint.time_offset_sigma:
        return np.zeros(log.runs)
    lag = wheel_lag_from_turns(log, settings.vehicle.theta_nominal)
    if np.any(np.abs(lag) > MAX_LAG_S):
        shown = ", ".join(f"{s:+.1f}" for s in lag)
        say(
            f"wheels {shown} s late against the pose{runs_label(log.runs)} (their turns match "
            "the heading's that much later: clocks apart, such as GPS time and UTC by 18 s)"
        )
    return lag


def _with_observable_lever_arm(
    data: SegmentData, settings: Settings, sensor: str = "position source"
) -> tuple[Settings, dict[str, float]]:
    """``settings`` without the lever arm as a variable when the selected segments cannot
    show it even at best (:func:`~graphcal.log.excitation.lever_arm_sigma` above the
    observability threshold, ``max_sigma_ratio`` × its prior sigma: a drive that barely
    turns), and what was left out (name → prior sigma)."""
    joint = settings.joint
    if joint.lever_arm_sigma <= 0:
        return settings, {}
    sigmas = pose_sigmas(joint.pose_weights, joint.position_sigma)
    best = lever_arm_sigma(data, sigmas[0], sigmas[2], joint.lever_arm_sigma, joint.theta_initial)
    if best.min() <= joint.max_sigma_ratio * joint.lever_arm_sigma:
        return settings, {}
    unit = length_unit(settings.vehicle.theta_nominal[2])
    say(
        f"lever arm of the {sensor} not estimated: this drive turns too little to show it "
        f"(at best ±{unit.format(best.max(), figure=True)} {unit.name} from these segments)"
    )
    joint = dataclasses.replace(joint, lever_arm_sigma=0.0)
    return dataclasses.replace(settings, joint=joint), {"lever_arm": settings.joint.lever_arm_sigma}


#: Mean |yaw rate| [rad/s] of the wheels (over 1 s, nominal theta) below which a drive "barely
#: turns": one whose lateral acceleration comes from the wheels or the heading cannot show d,
#: one of positions only cannot show t_r (straight roads: 0.00–0.01; a city drive's selected
#: segments 0.25).
D_FROM_WHEELS_MIN_YAW_RATE = 0.05


def _with_rear_slip_gain_where_it_shows(log: DriveLog, settings: Settings) -> Settings:
    """``settings`` with the rear tyres' slip gain as a variable (``rear_slip_modelled``)
    where its prior is set, the log has no sideslip, the lever arm is estimated and d is: the
    gain moves the model's point, the rear axle, sideways by ``−gain · a_y`` — in a log of
    the centre of gravity's sideslip that motion is logged already, and where d is held the
    drive's lateral acceleration is too little or not measured to show it. Without it a 4 km
    city drive's antenna, at the centre of gravity 1.35 m ahead of the rear axle, came out
    +1.177 ± 0.021 m ahead (the rear tyres' slip at city speeds, 4.7 ms²/m × v², read as the
    arm); with it, both paths of the drive agree (docs/defects.md)."""
    joint = settings.joint
    keep = (
        joint.rear_slip_gain_sigma > 0
        and not np.any(log.beta != 0)
        and joint.lever_arm_sigma > 0
        and not joint.fix_d
        and "d" not in joint.held_at_prior
    )
    if not keep:
        return settings
    joint = dataclasses.replace(joint, rear_slip_modelled=True)
    return dataclasses.replace(settings, joint=joint)


def _with_d_the_drive_can_show(
    log: DriveLog, rate: float, settings: Settings
) -> tuple[Settings, dict[str, str]]:
    """``settings`` holding d at its prior when its lateral acceleration comes from the
    wheels (no IMU, no heading) or the heading (no IMU) and the drive barely turns, and why
    (name → reason; else ``settings`` and nothing). d · a_y then fits the noise of the signal
    a_y is taken from — the wheels' own left/right difference, or the heading the graph also
    tracks — not a load transfer: on a straight road it is one weak direction with c_d, and
    a weak prior let d drift along it (2–3 mm·s²/m on the real highway minute) with c_d
    following, which predicted held-apart road worse (73 → 60 %). From the heading, on the
    twin's straight roads with a fused heading and no IMU: d −7.6σ and −9.6σ, c_d −3.1σ
    "calibrated" (held: c_d −0.9σ and +0.1σ). Its prior's uncertainty stays in every other
    parameter's σ. ``rate``: the segments' mean |yaw rate| [rad/s] of the wheels
    (:func:`mean_wheel_yaw_rate`)."""
    source = "wheels" if log.ay_from_wheels else "heading" if log.ay_from_heading else None
    if source is None or settings.joint.fix_d or rate >= D_FROM_WHEELS_MIN_YAW_RATE:
        return settings, {}
    reason = (
        f"its lateral acceleration comes from the {source}, on a drive that barely turns "
        f"(mean |yaw rate| {rate:.3f} rad/s): held at its nominal; log an IMU"
    )
    say(f"d not estimated: {reason}")
    joint = settings.joint.holding(("d",))
    return dataclasses.replace(settings, joint=joint), {"d": reason}


def _with_t_r_the_drive_can_show(
    data: SegmentData, rate: float, settings: Settings, held: dict[str, str]
) -> tuple[Settings, dict[str, str]]:
    """``settings`` holding t_r at its prior when only positions are measured and the drive
    barely turns (mean |yaw rate| of the wheels under :data:`D_FROM_WHEELS_MIN_YAW_RATE`),
    and ``held`` with why. t_r scales every yaw the wheels' difference makes; with no turn
    to pin it and no heading to measure the yaw, a smaller t_r lets corrections far inside
    the wheels' noise bend each segment's path after its fixes' noise, and the solve runs
    t_r towards 0 (the twin's 9 km of straight road from 5 Hz fixes without heading: the
    warm start to t_r = 0.0017 m in 25 s, the joint solve from the nominal 50 iterations
    into the same runaway, then held: 130 s). Held from the start, the same result in one
    solve. Its prior's uncertainty stays in every other parameter's σ. ``rate``: as
    :func:`_with_d_the_drive_can_show`'s."""
    if data.has_heading() or "t_r" in settings.joint.held_at_prior:
        return settings, held
    if rate >= D_FROM_WHEELS_MIN_YAW_RATE:
        return settings, held
    reason = (
        f"positions only, on a drive that barely turns (mean |yaw rate| {rate:.3f} rad/s): "
        "held at its nominal; a drive with turns or a measured heading determines it"
    )
    say(f"t_r not estimated: {reason}")
    joint = settings.joint.holding(("t_r",))
    return dataclasses.replace(settings, joint=joint), {**held, "t_r": reason}


def mean_wheel_yaw_rate(data: SegmentData, theta: np.ndarray) -> float:
    """Mean |yaw rate| [rad/s] of ``data``'s segments from their wheels with ``theta``, over
    1 s windows (0 for segments shorter than that)."""
    window = max(1, round(1.0 / data.dt))
    _, omega = step_increments(data.inputs, theta)
    turned = np.cumsum(omega, axis=1)[:, window - 1 :: window]
    rates = np.abs(np.diff(turned, axis=1)) / (window * data.dt)
    return float(rates.mean()) if rates.size else 0.0


def _mask_warnings(log: DriveLog) -> tuple[str, ...]:
    """The warning about the samples masked in ``log``, if any."""
    if log.masked is None:
        return ()
    seconds = float(log.masked.sum() * log.dt)
    return (
        f"{seconds:.1f} s of the log masked where the positions disagree with the wheels "
        f"({len(log.mask_notes)} span(s); first: {log.mask_notes[0]}); no segment spans them",
    )


def _with_detected_ticks(log: DriveLog, settings: Settings) -> Settings:
    """``settings`` with the joint solve's tick quantization from the resolution the
    recording stated (``DriveLog.tick_resolution``) or the log's rotations show
    (:mod:`graphcal.log.quantization`), unless the settings (or vehicle) give one."""
    if settings.joint.tick_quantization > 0:
        return settings
    source = "the recording says"
    if log.tick_resolution is not None:
        ticks = round(1.0 / log.tick_resolution)
    else:
        ticks = ticks_per_revolution(np.column_stack([log.n_rl, log.n_rr]))
        source = "found in the rotations"
    if ticks is None:
        return settings
    say(
        f"wheel rotations are counts of {ticks} ticks per revolution ({source}): "
        "quantization modelled"
    )
    joint = dataclasses.replace(settings.joint, tick_quantization=quantization_sigma(ticks))
    return dataclasses.replace(settings, joint=joint)


def _with_wheel_noise(log: DriveLog, settings: Settings) -> Settings:
    """``settings`` whose ``wheel_noise`` is the white noise the recording's own wheel rates
    show (``DriveLog.wheel_noise``: :func:`graphcal.log.noise.rate_wheel_noise`) where that
    is larger than the profile's, if ``wheel_noise_from_log``: the profile's is a floor (its
    slip and timing jitter the rates do not show)."""
    joint = settings.joint
    found = log.wheel_noise
    if not joint.wheel_noise_from_log or found is None or not found > joint.wheel_noise:
        return settings
    say(
        f"wheel noise {found:.2g} rev per step (the wheel rates' own noise), not the "
        f"{joint.wheel_noise:g} of the settings"
    )
    return dataclasses.replace(settings, joint=dataclasses.replace(joint, wheel_noise=found))


def _with_position_noise(log: DriveLog, settings: Settings) -> Settings:
    """``settings`` weighting the fixes with the white noise their second differences show
    (:func:`~graphcal.log.noise.position_noise`) where it is :data:`REWEIGHTED
    <graphcal.pipeline.methods.noise_levels.REWEIGHTED>` times what the settings assume
    (their white and shared error together), the heading's σ kept. A first solve under fixes
    weighted ten times too tight creeps: a car's 10 Hz fixes of 2 m weighted as 0.2 m took
    41 iterations at χ²/dof 95 before its residuals set the noise. Only raised: less noise
    than assumed, and an error the fixes share, the solve's residuals judge."""
    joint = settings.joint
    found = position_noise(log, settings.vehicle.theta_nominal)
    x, y, _ = joint.pose_weights
    sigmas = pose_sigmas(joint.pose_weights, joint.position_sigma)
    assumed = float(np.hypot(sigmas[0], joint.fix_error_sigma))
    if found is None or found <= REWEIGHTED * assumed:
        return settings
    say(
        f"position noise {found:#.3g} m per axis (the fixes' second differences), not the "
        f"{assumed:g} m the settings assume: the first solve weights them so"
    )
    weight = float(f"{(found / sigmas[2]) ** 2:.6g}")
    joint = dataclasses.replace(
        joint, position_sigma=found * np.sqrt(x), pose_weights=(x, y, weight)
    )
    return dataclasses.replace(settings, joint=joint)


def _with_heading_noise(log: DriveLog, settings: Settings) -> Settings:
    """``settings`` whose joint heading weight follows the log's own heading noise
    (:mod:`graphcal.log.noise`), if ``heading_noise_from_log``."""
    joint = settings.joint
    if not joint.heading_noise_from_log:
        return settings
    sigma = heading_noise(
        log, settings.vehicle.theta_nominal, joint.wheel_noise, joint.tick_quantization
    )
    if sigma is None:
        return settings
    x, y, _ = joint.pose_weights
    weight = float(f"{(joint.position_sigma / sigma) ** 2:.6g}")
    say(f"heading noise {np.degrees(sigma):.2f}° (from the log): heading weight {weight:.3g}")
    joint = dataclasses.replace(joint, pose_weights=(x, y, weight))
    return dataclasses.replace(settings, joint=joint)
