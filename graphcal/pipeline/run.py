"""End-to-end calibration of one drive log: segments → selection → method → validation.

Methods:

* ``"staged"`` — the paper's five steps over batches (:mod:`graphcal.pipeline.staged`); the
  recommended theta is the median of Step 5 over the batches.
* ``"joint"`` — one joint graph per batch (:mod:`graphcal.pipeline.joint`): start poses,
  wheel-rotation corrections and theta solved together, each with its marginal covariance and
  observability verdict; the recommended theta is the joint solve over *all* selected
  segments at once (the maximum-likelihood estimate from all the data, with its covariance).
  The batches show the spread and check the covariance; batches where a parameter is not
  observable are left out of the batch statistics, with the reason. By default the batches
  are solved from each segment's system at the whole-log solution
  (:mod:`graphcal.pipeline.joint_batches`), at the cost of one whole-log iteration.
* ``"whole"`` — only the joint solve over all selected segments: quick, no batches.

With the joint and whole methods, parameters the data do not determine
(:mod:`graphcal.graph.observability`) stay at their prior (the nominal value) and are
reported as not calibrated. If no segment passes the yaw-rate selection they use all
segments: the observability check, not the selection, then decides what the drive determines.

Validation (§5.2): every theta is judged by its position error E_p (eq. 16 / K, averaged over
the 300 m validation segments), next to the nominal theta of ``settings.vehicle``, whose c_e
also turns wheel rotations into the distances segments are cut by. Comparison with a known truth
(synthetic drives) is :func:`graphcal.evaluation.evaluate`, apart from calibration.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import gtsam
import numpy as np

from graphcal.data.antenna import move_to_centre
from graphcal.data.drive_log import DriveLog
from graphcal.data.noise import heading_noise
from graphcal.data.quantization import quantization_sigma, ticks_per_revolution
from graphcal.data.segments import (
    SegmentData,
    Segments,
    gather_segments,
    make_batches,
    split_segments,
    yaw_rate_statistic,
)
from graphcal.data.timing import shift_wheel_rotations, whole_samples
from graphcal.errors import GraphcalError
from graphcal.factors import pose_sigmas
from graphcal.graph.observability import Observability, condition_on_prior
from graphcal.model import PARAMETER_NAMES, step_increments, wheel_lateral_acceleration
from graphcal.pipeline.joint import JointCalibration, JointSettings, solve_joint
from graphcal.pipeline.joint_batches import BatchEstimate, solve_joint_batches
from graphcal.pipeline.sensor_estimates import (
    DownWeightedFixes,
    SensorEstimate,
    correct_log,
    log_weights,
    sensor_estimates,
)
from graphcal.pipeline.settings import (
    CAR_SEGMENT_LENGTH,
    CAR_VALIDATION_LENGTH,
    Settings,
    segment_lengths,
)
from graphcal.pipeline.staged import StagedResult, run_staged, step1_thetas
from graphcal.pipeline.trust import TrustAssessment, assess_trust, circumference_warning
from graphcal.pipeline.validation import position_errors

Progress = Callable[[str], None]
#: Weight of a fix the loader flagged as an isolated spike (its sigma ×100).
FLAGGED_WEIGHT = 1e-4
Method = Literal["staged", "joint", "whole"]
METHODS = ("staged", "joint", "whole")


class NoUsableSegments(GraphcalError, ValueError):
    """The log has no segment that passes the selection."""


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration run produced (SI).

    Attributes:
        log, settings, method: what was run.
        segments: all calibration segments; ``selected`` those passing the selection.
        yaw_rate: the selection statistic of every calibration segment [rad/s].
        data: the selected segments' signals.
        theta: the recommended theta.
        batches: ``(B, N)`` segment indices of the batches (``None`` for ``"whole"``).
        batch_theta: per step or method (``"step1"``, ``"step3"``, ``"step5"``; ``"joint"``;
            ``"whole"``), theta of each batch ``(B, 4)``; NaN rows for failed solves.
        batch_covariance: per method that reports one (``"joint"``), the marginal covariance
            of each batch's theta ``(B, 4, 4)``; NaN for failed solves.
        batch_excluded: per method, why each batch is left out of the statistics (``""``
            if it is not): a failed solve or parameters the batch does not determine.
        covariance: covariance of the recommended theta (joint and whole methods), ``(4, 4)``.
        observability: what the data determined about the recommended theta (joint, whole).
        staged: the five steps' results (``method == "staged"``).
        validation_segments, validation: the validation segments and their signals.
        segment_errors: per validation segment, mean position error [m] of odometry with
            ``"nominal"`` and ``"calibrated"`` theta.
        batch_errors: per step, E_p [m] of each batch's theta, ``(B,)``; NaN where the batch
            failed (never written to a file).
        warnings: what a user must know before trusting the result.
        trust: the checks that need no truth (:mod:`graphcal.pipeline.trust`).
        estimated: sensor quantities the whole-log solve estimated with theta
            (``"time_offset"`` [s], ``"lever_arm_longitudinal"``, ``"lever_arm_lateral"``
            [m]; :mod:`graphcal.pipeline.sensor_estimates`); observable ones are corrected
            in ``log`` for the batches and the validation.
        down_weighted: the fixes the robust whole-log solve down-weighted as outliers.
        whole: the whole-log joint solve (joint and whole methods, and staged when it
            estimates sensor quantities or outliers), ``None`` otherwise.
    """

    log: DriveLog
    settings: Settings
    method: Method
    segments: Segments
    selected: Segments
    yaw_rate: np.ndarray
    data: SegmentData
    theta: np.ndarray
    batches: np.ndarray | None
    batch_theta: dict[str, np.ndarray]
    batch_covariance: dict[str, np.ndarray]
    staged: StagedResult | None
    validation_segments: Segments
    validation: SegmentData
    segment_errors: dict[str, np.ndarray]
    batch_errors: dict[str, np.ndarray]
    batch_excluded: dict[str, np.ndarray]
    warnings: tuple[str, ...] = ()
    covariance: np.ndarray | None = None
    observability: Observability | None = None
    trust: TrustAssessment | None = None
    estimated: dict[str, SensorEstimate] = field(default_factory=dict)
    down_weighted: DownWeightedFixes | None = None
    whole: JointCalibration | None = None

    def verdicts(self) -> dict[str, str]:
        """Per parameter: the observability verdict, or why it is not to be trusted
        (:mod:`graphcal.pipeline.trust`)."""
        out = self.observability.verdicts() if self.observability is not None else {}
        doubts = self.trust.parameter_doubts if self.trust is not None else {}
        for name in PARAMETER_NAMES:
            if name in doubts and out.get(name, "calibrated").startswith("calibrated"):
                out[name] = f"not trusted: {doubts[name]}"
            out.setdefault(name, "calibrated")
        return out

    def batch_estimates(self, name: str) -> np.ndarray:
        """Per-batch thetas ``(B, 4)`` of step or method ``name`` with failed and excluded
        batches as NaN rows: what statistics and figures summarize."""
        return without_excluded(self.batch_theta[name], self.batch_excluded.get(name))

    def validation_error(self, name: str) -> float:
        """E_p [m] of ``"nominal"`` or ``"calibrated"`` theta."""
        return float(np.mean(self.segment_errors[name]))


def without_excluded(thetas: np.ndarray, reasons: np.ndarray | None) -> np.ndarray:
    """``thetas`` ``(B, 4)`` with the rows of excluded batches (a non-empty reason) as NaN."""
    out = np.array(thetas, dtype=float)
    if reasons is not None:
        out[np.asarray(reasons) != ""] = np.nan
    return out


def mean_validation_error(validation: SegmentData, theta: np.ndarray) -> float:
    """E_p [m]: the position error of eq. (16) / K averaged over the validation segments."""
    if not np.all(np.isfinite(theta)):
        return float("nan")
    return float(np.mean(position_errors(validation, theta)))


def exclusion_reason(result: BatchEstimate | None) -> str:
    """Why a batch's joint solve is left out of the batch statistics (``""``: it is not)."""
    if result is None:
        return "solve failed"
    if result.observability.degenerate:
        return "not observable: " + ", ".join(result.observability.not_calibrated)
    return ""


def select(
    log: DriveLog, settings: Settings, progress: Progress, fall_back_to_all: bool = False
) -> tuple[Segments, np.ndarray, Segments, Segments]:
    """Calibration segments, their yaw statistic, the selected ones, validation segments.

    With ``fall_back_to_all``, a log where no segment passes the yaw-rate selection uses all
    its segments instead of failing (for methods that judge observability themselves).
    """
    s = settings.segments
    circumference = float(settings.vehicle.theta_nominal[0])
    if settings.vehicle.size_scale() != 1.0:
        derived = segment_lengths(settings.vehicle)
        how = (
            f"the car's {CAR_SEGMENT_LENGTH:g} m and {CAR_VALIDATION_LENGTH:g} m scaled to the "
            f"vehicle's {settings.vehicle.theta_nominal[2]:g} m track"
            if (s.length, s.validation_length) == derived
            else "as set"
        )
        progress(
            f"segments of {s.length:g} m, validation segments of {s.validation_length:g} m ({how})"
        )
    for note in log.mask_notes:
        progress(f"masked: {note}")
    segments = split_segments(log, s.length, s.stride, circumference)
    yaw = yaw_rate_statistic(log, segments, s.yaw_statistic, s.yaw_window)
    selected = segments.subset(yaw > s.min_yaw_rate)
    progress(
        f"segments: {len(selected)} of {len(segments)} {s.length:g} m segments have "
        f"{s.yaw_statistic} |yaw rate| > {s.min_yaw_rate:g} rad/s"
    )
    if len(selected) == 0 and fall_back_to_all and len(segments) > 0:
        progress(
            f"no segment passes the yaw-rate selection: using all {len(segments)} segments; "
            "the observability check decides what they determine"
        )
        selected = segments
    if len(segments) == 0:
        distance = log.travelled_distance(circumference)[-1]
        where = (
            f"the log's {distance:.1f} m"
            if log.masked is None
            else f"every stretch between masked samples ({log.masked.mean():.0%} of the log "
            f"masked; first: {log.mask_notes[0]})"
        )
        raise NoUsableSegments(
            f"{log.source}: {where} is shorter than one {s.length:g} m segment; set a "
            "shorter --segment-length (or [segments] length), or give the vehicle's profile "
            "(--vehicle), whose size sets the lengths"
        )
    if len(selected) == 0:
        best = f"{yaw.max():.3f}" if len(yaw) else "n/a"
        raise NoUsableSegments(
            f"{log.source}: no {s.length:g} m segment has {s.yaw_statistic} |yaw rate| above "
            f"{s.min_yaw_rate:g} rad/s (highest: {best} rad/s); "
            + (
                ""
                if fall_back_to_all
                else "use --method joint (it uses all segments and reports what they determine), "
            )
            + "lower --min-yaw-rate, use overlapping segments (--segment-stride) or a drive "
            "with more bends"
        )
    validation = split_segments(log, s.validation_length, None, circumference)
    if len(validation) == 0:
        distance = log.travelled_distance(circumference)[-1]
        if log.masked is not None and distance >= s.validation_length:
            raise NoUsableSegments(
                f"{log.source}: no {s.validation_length:g} m stretch of the log is free of "
                f"masked samples ({log.masked.mean():.0%} of the log masked in "
                f"{len(log.mask_notes)} span(s); first: {log.mask_notes[0]}); check the "
                "positions, or use a shorter --validation-length"
            )
        raise NoUsableSegments(
            f"{log.source}: log ({distance:.1f} m) is shorter than one "
            f"{s.validation_length:g} m validation segment; use a longer drive, a shorter "
            "--validation-length (or [segments] validation_length), or give the vehicle's "
            "profile (--vehicle), whose size sets the lengths"
        )
    return segments, yaw, selected, validation


def run_calibration(
    log: DriveLog,
    settings: Settings | None = None,
    method: Method = "joint",
    *,
    progress: Progress | None = None,
    workers: int = 1,
) -> CalibrationRun:
    """Calibrate theta from ``log``.

    Args:
        log: a validated drive log.
        settings: run settings (the paper's by default); ``settings.vehicle`` gives the
            nominal theta for cutting segments and for the "nominal" validation errors
            (apply a vehicle with :func:`graphcal.pipeline.settings.apply_vehicle`).
        method: ``"staged"`` (the paper's five steps over batches), ``"joint"`` (one joint
            graph per batch, then one over all selected segments) or ``"whole"`` (only the
            joint solve over all selected segments).
        progress: called with one line per stage.
        workers: worker processes for batches and segments (results do not depend on it).

    Raises:
        NoUsableSegments: no segment passes the selection, or the log is too short.
        GraphcalError: the calibration failed.
    """
    settings = settings or Settings()
    say = progress or (lambda _line: None)
    if method not in METHODS:
        raise GraphcalError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    segments, yaw, selected, validation_segments = select(
        log, settings, say, fall_back_to_all=method != "staged"
    )
    settings = _with_detected_ticks(log, settings, say)
    settings = _with_heading_noise(log, settings, say)
    arm = settings.lever_arm
    log = move_to_centre(log, (arm.longitudinal, arm.lateral))  # a known arm
    flagged = None  # spikes the loader flagged get (almost) no weight
    if log.outlying is not None:
        flagged = np.where(log.outlying, FLAGGED_WEIGHT, 1.0)
    data = gather_segments(log, selected, flagged)
    validation = gather_segments(log, validation_segments)
    staged = None
    batches = None
    batch_theta: dict[str, np.ndarray] = {}
    batch_covariance: dict[str, np.ndarray] = {}
    batch_excluded: dict[str, np.ndarray] = {}
    batch_data = data
    covariance = observability = whole = whole_values = None
    estimated: dict[str, SensorEstimate] = {}
    down_weighted = None
    warnings: list[str] = []
    if log.masked is not None:
        seconds = float(log.masked.sum() * log.dt)
        warnings.append(
            f"{seconds:.1f} s of the log masked where the positions disagree with the wheels "
            f"({len(log.mask_notes)} span(s); first: {log.mask_notes[0]}); no segment spans them"
        )
    if method != "staged" or _models_sensors(settings.joint):
        # The recommended theta (joint, whole) first; it also finds the time offset, the
        # lever arm and the outliers, corrected for everything after it.
        gathered = data
        whole, whole_values, data, offset = _solve_with_time_offset(
            log, data, selected, flagged, settings.joint, say, workers
        )
        joint = _with_position_noise(whole, settings.joint, say)
        if log.ay_from_wheels:  # derived with the nominal theta: again with the solved one
            log = dataclasses.replace(
                log, ay=wheel_lateral_acceleration(log.n_rl, log.n_rr, whole.theta, log.dt)
            )
            gathered = gather_segments(log, selected, flagged)
            validation = gather_segments(log, validation_segments)
            say("lateral acceleration of the wheels derived again with the solved theta")
        if joint is not settings.joint or log.ay_from_wheels:
            settings = dataclasses.replace(settings, joint=joint)  # the fixes' own noise
            whole, whole_values, data, offset = _solve_with_time_offset(
                log, gathered, selected, flagged, settings.joint, say, workers
            )
        if method != "joint":  # only the joint batches linearize at the solution
            whole_values = None
        if log.ay_from_wheels:
            whole = _d_on_a_straight_drive(whole, data, say)
        if method != "staged":
            theta, covariance, observability = _conditioned(whole, settings.joint)
            if observability.degenerate:
                warnings.append(
                    f"{', '.join(observability.not_calibrated)} not calibrated: "
                    f"{observability.message()}; kept at the prior (nominal) value"
                )
        estimated = _with_total_offset(
            sensor_estimates(whole.nuisance, settings.joint.max_sigma_ratio), offset
        )
        for line in _estimate_lines(estimated):
            say(line)
        down_weighted = DownWeightedFixes.from_solve(data, whole.fix_weights, log.t)
        if whole.fix_weights is not None:
            say(down_weighted.summary())
        if whole.slip_statistic is not None:
            say(slip_line(whole, settings.joint))
        weights = flagged
        if whole.fix_weights is not None:
            weights = log_weights(data, whole.fix_weights, len(log.t))
        # Validation, the staged steps and Step 1 (no time-offset or lever-arm variable) get
        # the exact correction; the joint batches the whole-sample shift, with the rest as
        # their offset's prior, and the antenna where it is, the lever arm a variable.
        exact = correct_log(log, estimated)
        data = gather_segments(exact, selected, weights)
        if method == "joint":
            batch_log = correct_log(log, estimated, in_whole_samples=True, move_antenna=False)
            batch_data = gather_segments(batch_log, selected, weights)
        if exact is not log:
            validation = gather_segments(exact, validation_segments)
        log = exact
    if method in ("staged", "joint"):
        b = settings.batches
        size = min(b.size, len(selected))
        if size < b.size:
            say(f"only {len(selected)} segments: batches of {size} instead of {b.size}")
        batches = make_batches(len(selected), size, b.count, b.seed)
        say(
            f"{method}: {_plural(len(batches), 'batch', 'batches')} of {size} segments, "
            f"{_plural(workers, 'worker', 'workers')}"
        )
    if method == "staged":
        staged = run_staged(data, batches, settings, workers, say)
        theta = staged.final_theta
        batch_theta = dict(staged.theta)
        warnings += staged.warnings
    elif method == "joint":
        # The fixes weighted as the whole-log solve found: batches solve without robust rounds.
        batch_settings = dataclasses.replace(
            settings.joint,
            **_batch_time_offset(estimated, log.dt),
            robust_threshold=0.0,
            slip="on" if whole is not None and whole.slip_modelled else "off",
        )
        batch_theta["step1"] = step1_thetas(data, batches, settings, workers, say)
        step1_failed = int((~np.all(np.isfinite(batch_theta["step1"]), axis=1)).sum())
        if step1_failed:
            warnings.append(
                f"step1: {step1_failed} of {len(batches)} batch solves of the Step 1 "
                "baseline failed and are left out of its statistics"
            )
        solved = solve_joint_batches(
            batch_data,
            batches,
            batch_settings,
            settings.batches.joint_solve,
            whole_values,
            workers,
            say,
        )
        whole_values = None
        nan_theta, nan_matrix = np.full(4, np.nan), np.full((4, 4), np.nan)
        batch_theta["joint"] = np.array([nan_theta if r is None else r.theta for r in solved])
        batch_covariance["joint"] = np.array(
            [nan_matrix if r is None else r.covariance for r in solved]
        )
        reasons = np.array([exclusion_reason(r) for r in solved], dtype=object)
        # Step 1 is the baseline of the same batches: compare both on the batches kept.
        batch_excluded["joint"] = batch_excluded["step1"] = reasons
        warnings += _exclusion_warnings(reasons)
    batch_errors = {
        name: np.array(
            [
                mean_validation_error(validation, t)
                for t in without_excluded(thetas, batch_excluded.get(name))
            ]
        )
        for name, thetas in batch_theta.items()
    }
    segment_errors = {
        "nominal": position_errors(validation, settings.vehicle.theta_nominal),
        "calibrated": position_errors(validation, theta),
    }
    if batches is not None and len(selected) < settings.batches.size:
        count, size = batches.shape
        warnings.append(
            f"only {len(selected)} selected segments: {_plural(count, 'batch', 'batches')} of "
            f"{size} instead of {settings.batches.size}"
            + (
                "; every batch shares most segments, so spreads understate the uncertainty"
                if count > 1
                else "; one batch has no spread to report"
            )
        )
    calibrated, nominal = np.mean(segment_errors["calibrated"]), np.mean(segment_errors["nominal"])
    trust = assess_trust(
        iterations=whole.iterations if whole is not None else 0,
        max_iterations=settings.joint.max_iterations if whole is not None else 1,
        chi2_per_dof=whole.chi2_per_dof if whole is not None else None,
        batch_theta=without_excluded(batch_theta["joint"], batch_excluded.get("joint"))
        if "joint" in batch_covariance
        else None,
        batch_covariance=batch_covariance.get("joint"),
        calibrated=observability.calibrated if observability is not None else np.ones(4, bool),
        validation_calibrated=float(calibrated),
        validation_nominal=float(nominal),
    )
    warnings += [f"not to be trusted: {doubt}" for doubt in trust.doubts]
    scale = circumference_warning(float(theta[0]), float(settings.vehicle.theta_nominal[0]))
    if scale is not None:
        warnings.append(scale)
    solved_errors = {k: e[np.isfinite(e)] for k, e in batch_errors.items()}
    if staged is not None and len(solved_errors["step1"]) and len(solved_errors["step5"]):
        first, last = np.median(solved_errors["step1"]), np.median(solved_errors["step5"])
        if last > first:
            warnings.append(
                f"Step 5 validates worse than Step 1 (median {last:.2f} m vs {first:.2f} m): "
                "too little data for the compensation; try --method joint or a longer drive"
            )
    for line in warnings:
        say(f"warning: {line}")
    say(f"validated on {len(validation)} {settings.segments.validation_length:g} m segments")
    return CalibrationRun(
        log=log,
        settings=settings,
        method=method,
        segments=segments,
        selected=selected,
        yaw_rate=yaw,
        data=data,
        theta=theta,
        batches=batches,
        batch_theta=batch_theta,
        batch_covariance=batch_covariance,
        staged=staged,
        validation_segments=validation_segments,
        validation=validation,
        segment_errors=segment_errors,
        batch_errors=batch_errors,
        batch_excluded=batch_excluded,
        warnings=tuple(warnings),
        trust=trust,
        estimated=estimated,
        down_weighted=down_weighted,
        whole=whole,
        covariance=covariance,
        observability=observability,
    )


def _exclusion_warnings(reasons: np.ndarray) -> list[str]:
    """One warning per distinct reason for leaving batches out of the statistics."""
    out = []
    for reason in sorted(set(reasons) - {""}):
        count = int((reasons == reason).sum())
        out.append(
            f"{count} of {len(reasons)} joint batches left out of the batch statistics: {reason}"
        )
    if len(reasons) and all(reasons != ""):
        out.append("no joint batch determines every parameter; see the recommended theta's verdict")
    return out


def _whole_log_solve(
    data: SegmentData, settings: JointSettings, say: Progress, workers: int
) -> tuple[JointCalibration, gtsam.Values]:
    """The joint solve over all ``data`` (its segments shared out among ``workers``
    processes), with the progress lines a user waits for, and the solution's values."""
    say(f"joint solve over all {len(data)} selected segments")
    result, values = solve_joint(data, settings, workers, say)
    chi2 = result.chi2_per_dof
    fit = "" if chi2 is None else f", χ²/dof {chi2:.2f}"
    say(f"  {result.iterations} iterations{fit}")
    return result, values


#: Whole-log solves at most, each after shifting the wheels by the offset found so far.
OFFSET_ROUNDS = 4


def _solve_with_time_offset(
    log: DriveLog,
    data: SegmentData,
    selected: Segments,
    flagged: np.ndarray | None,
    settings: JointSettings,
    say: Progress,
    workers: int = 1,
) -> tuple[JointCalibration, gtsam.Values, SegmentData, float]:
    """The whole-log solve; while it detects a wheel time offset, the wheels are shifted by
    the offset found so far, rounded to whole samples, and the solve repeated, so that the
    graph's first-order shift only covers the rest (at most about half a sample).

    Whole samples because a shift is exact only for them: between samples it averages
    neighbouring rotations, which smooths their noise (tick quantization above all) away
    from what the correction prior assumes. On a 24 km drive with 96-tick encoders, slow slip
    and 62.5 ms latency, fractional shifting moved t_r by 4.3σ (``docs/defects.md``).

    ``data`` are ``selected`` gathered from ``log`` with the ``flagged`` fix weights. Returns
    the last solve, its values, the segments it solved and the shift [s] of their wheels."""
    whole, values = _whole_log_solve(data, settings, say, workers)
    shift = 0.0
    for _ in range(OFFSET_ROUNDS - 1):
        found = sensor_estimates(whole.nuisance, settings.max_sigma_ratio).get("time_offset")
        if found is None or not found.detected:
            break
        rounded = whole_samples(shift + found.value, log.dt)
        if rounded == shift:
            break  # what is left is less than a sample: the graph's first order covers it
        shift = rounded
        say(f"wheels shifted by {shift * 1e3:+.1f} ms; solved again from the shifted log")
        data = gather_segments(shift_wheel_rotations(log, shift), selected, flagged)
        whole, values = _whole_log_solve(data, settings, say, workers)
    return whole, values, data, shift


def _batch_time_offset(estimated: dict[str, SensorEstimate], dt: float) -> dict[str, float]:
    """The joint batches' time-offset prior: what the whole-log estimate leaves beyond the
    whole-sample shift of their log, with its σ (no variable if the whole-log solve had
    none)."""
    found = estimated.get("time_offset")
    if found is None:
        return {"time_offset_sigma": 0.0}
    rest = found.value - (whole_samples(found.value, dt) if found.detected else 0.0)
    return {"time_offset_sigma": found.sigma, "time_offset_mean": rest}


def _with_total_offset(
    estimates: dict[str, SensorEstimate], offset: float
) -> dict[str, SensorEstimate]:
    """``estimates`` with the time offset's value the total: ``offset`` the log was shifted
    by, plus what the last solve found."""
    found = estimates.get("time_offset")
    if found is None or offset == 0.0:
        return estimates
    total = dataclasses.replace(found, value=found.value + offset)
    return {**estimates, "time_offset": total}


def _conditioned(
    whole: JointCalibration, settings: JointSettings
) -> tuple[np.ndarray, np.ndarray, Observability]:
    """The whole-log theta with unobservable parameters at their prior, its covariance and
    observability."""
    theta, covariance = condition_on_prior(
        whole.theta,
        whole.covariance,
        whole.observability.calibrated,
        settings.theta_initial,
        settings.theta_prior_sigmas,
    )
    return theta, covariance, whole.observability


def wheel_model(run: CalibrationRun) -> dict[str, float]:
    """The wheel noise a localization graph should carry after this calibration: the tick
    rounding it used (given or detected) and, if it found slow slip, the slip scales' prior.

    The keys are fields of :class:`~graphcal.localization.SmoothingSettings` and
    :class:`~graphcal.localization.OnlineSettings`:
    ``SmoothingSettings(**wheel_model(run))``.
    """
    joint = run.settings.joint
    slip = run.whole is not None and run.whole.slip_modelled
    return {
        "tick_quantization": float(joint.tick_quantization),
        "slip_sigma": float(joint.slip_sigma) if slip else 0.0,
        "slip_time": float(joint.slip_time),
    }


def prepare_localization(
    log: DriveLog, settings: Settings | None = None
) -> tuple[DriveLog, dict[str, Any], str]:
    """What a localization graph takes from an offline calibration of ``log``: the log
    corrected by the estimated time offset and lever arm, the settings that
    :class:`~graphcal.localization.SmoothingSettings` and
    :class:`~graphcal.localization.OnlineSettings` accept (:func:`wheel_model`, and the
    calibrated theta as ``theta_initial``), and a one-line summary of what was found.

    Runs the whole-log calibration (``settings``, default :class:`Settings`).
    """
    run = run_calibration(log, settings or Settings(), "whole")
    wheels: dict[str, Any] = {**wheel_model(run), "theta_initial": run.theta}
    found = ", ".join(f"{n} {e.value:+.3f} ({e.verdict})" for n, e in run.estimated.items())
    summary = (
        f"calibration: {found}; tick rounding σ {wheels['tick_quantization']:.2e} rev, "
        f"slip σ {wheels['slip_sigma']:g}"
    )
    return correct_log(log, run.estimated), wheels, summary


def slip_line(whole: JointCalibration, settings: JointSettings) -> str:
    """One line: whether the whole-log solve found slow wheel slip and modelled it."""
    statistic = f"χ² lower by {whole.slip_statistic:.2f} per chunk with slip scales"
    if whole.slip_modelled:
        return (
            f"slow wheel slip found ({statistic} > {settings.slip_detection:g}): modelled; "
            "σ includes it"
        )
    return f"no slow wheel slip ({statistic} ≤ {settings.slip_detection:g})"


def _with_detected_ticks(log: DriveLog, settings: Settings, say: Progress) -> Settings:
    """``settings`` with the joint solve's tick quantization from the resolution the
    recording stated (``DriveLog.tick_resolution``) or the log's rotations show
    (:mod:`graphcal.data.quantization`), unless the settings (or vehicle) give one."""
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


def _with_heading_noise(log: DriveLog, settings: Settings, say: Progress) -> Settings:
    """``settings`` whose joint heading weight follows the log's own heading noise
    (:mod:`graphcal.data.noise`), if ``heading_noise_from_log``."""
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
    say(f"heading noise {np.degrees(sigma):.2f}° (from the log): heading weight {weight:g}")
    joint = dataclasses.replace(joint, pose_weights=(x, y, weight))
    return dataclasses.replace(settings, joint=joint)


#: Mean |yaw rate| [rad/s] of the wheels (over 1 s) below which a drive whose lateral
#: acceleration comes from the wheels does not determine d (straight roads: 0.00–0.01; a
#: city drive's selected segments 0.25).
D_FROM_WHEELS_MIN_YAW_RATE = 0.05


def _d_on_a_straight_drive(
    whole: JointCalibration, data: SegmentData, say: Progress
) -> JointCalibration:
    """``whole`` with d not calibrated when its lateral acceleration came from the wheels
    (no IMU, no heading) and the drive barely turns: d · a_y then fits mostly the noise of
    the wheels' own left/right difference (a_y is taken from it), not a load transfer."""
    window = max(1, round(1.0 / data.dt))
    _, omega = step_increments(data.inputs, whole.theta)
    turned = np.cumsum(omega, axis=1)[:, window - 1 :: window]
    rates = np.abs(np.diff(turned, axis=1)) / (window * data.dt)
    rate = float(rates.mean()) if rates.size else 0.0
    if rate >= D_FROM_WHEELS_MIN_YAW_RATE or not whole.observability.calibrated[3]:
        return whole
    reason = (
        f"its lateral acceleration comes from the wheels, on a drive that barely turns "
        f"(mean |yaw rate| {rate:.3f} rad/s): log an IMU"
    )
    say(f"d not calibrated: {reason}")
    return dataclasses.replace(whole, observability=whole.observability.without("d", reason))


#: The fixes' noise from the solve replaces the settings' when they differ by more than this
#: share (a variance component; one more solve).
POSITION_NOISE_TOLERANCE = 0.25


def _with_position_noise(
    whole: JointCalibration, settings: JointSettings, say: Progress
) -> JointSettings:
    """``settings`` with the position sigma the whole-log solve found in its residuals
    (:attr:`JointCalibration.position_noise`) when it differs from theirs by more than
    :data:`POSITION_NOISE_TOLERANCE`, the heading sigma kept; else ``settings`` itself."""
    found = whole.position_noise
    if found is None:
        return settings
    x, y, heading = settings.pose_weights
    configured = float(pose_sigmas(settings.pose_weights, settings.position_sigma)[0])
    say(f"position noise {found:.3f} m per axis (the fixes' residuals)")
    if abs(found / configured - 1.0) <= POSITION_NOISE_TOLERANCE:
        return settings
    sigma = found * np.sqrt(x)
    weight = float(f"{heading * (sigma / settings.position_sigma) ** 2:.6g}")
    say(
        f"  not the {configured:g} m the settings assume: solved again with it (heading "
        f"weight {weight:g}, the heading's sigma kept)"
    )
    return dataclasses.replace(settings, position_sigma=sigma, pose_weights=(x, y, weight))


def _models_sensors(settings: JointSettings) -> bool:
    """The joint settings estimate a time offset or lever arm, or weight outliers."""
    return max(settings.time_offset_sigma, settings.lever_arm_sigma, settings.robust_threshold) > 0


#: How each sensor estimate is shown: label, unit, scale from SI, digits.
_ESTIMATE_FORMAT = {
    "time_offset": ("time offset: wheels late against the pose", "ms", 1e3, 1),
    "lever_arm_longitudinal": ("GNSS antenna ahead of the centre of gravity", "m", 1.0, 3),
    "lever_arm_lateral": ("GNSS antenna left of the centre of gravity", "m", 1.0, 3),
}


def _estimate_lines(estimated: dict[str, SensorEstimate]) -> list[str]:
    """One progress line per sensor estimate."""
    lines = []
    for name, e in estimated.items():
        label, unit, scale, digits = _ESTIMATE_FORMAT[name]
        if e.observable:
            lines.append(
                f"{label}: {e.value * scale:+.{digits}f} ± {e.sigma * scale:.{digits}f} {unit}; "
                f"{e.verdict}"
            )
        else:
            lines.append(f"{label}: not observable from this drive")
    return lines


def _plural(count: int, one: str, many: str) -> str:
    """``"1 batch"``, ``"3 batches"``."""
    return f"{count} {one if count == 1 else many}"
