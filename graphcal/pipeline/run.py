"""End-to-end calibration of one drive log: segments → selection → method → validation.

Methods:

* ``"staged"`` — the paper's five steps over batches (:mod:`graphcal.pipeline.staged`); the
  recommended theta is the median of Step 5 over the batches.
* ``"joint"`` — one joint graph per batch (:mod:`graphcal.pipeline.joint`): start poses,
  wheel-rotation corrections and theta solved together; the median over the batches.
* ``"whole"`` — one batch solve over all selected segments at once, start poses estimated: a
  quick calibration from a short log.

Validation (§5.2): every theta is judged by its position error E_p (eq. 16 / K, averaged over
the 300 m validation segments), next to nominal theta and, on synthetic data, the reachable
limit (the true theta).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import (
    SegmentData,
    Segments,
    gather_segments,
    make_batches,
    split_segments,
    yaw_rate_statistic,
)
from graphcal.errors import GraphcalError
from graphcal.model import THETA_NOMINAL
from graphcal.pipeline.batch_calibration import calibrate_batch
from graphcal.pipeline.joint import JointSettings, calibrate_joint
from graphcal.pipeline.parallel import map_tasks
from graphcal.pipeline.staged import StagedResult, run_staged
from graphcal.pipeline.validation import position_errors
from graphcal.settings import Settings

Progress = Callable[[str], None]
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
        staged: the five steps' results (``method == "staged"``).
        validation_segments, validation: the validation segments and their signals.
        segment_errors: per validation segment, mean position error [m] of odometry with
            ``"nominal"``, ``"calibrated"`` and, when known, ``"true"`` theta.
        batch_errors: per step, E_p [m] of each batch's theta, ``(B,)``; NaN where the batch
            failed (never written to a file).
        theta_true: the truth of a synthetic drive, else ``None``.
        warnings: what a user must know before trusting the result.
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
    theta_true: np.ndarray | None = None
    warnings: tuple[str, ...] = ()

    def validation_error(self, name: str) -> float:
        """E_p [m] of ``"nominal"``, ``"calibrated"`` or ``"true"`` theta."""
        return float(np.mean(self.segment_errors[name]))


def mean_validation_error(validation: SegmentData, theta: np.ndarray) -> float:
    """E_p [m]: the position error of eq. (16) / K averaged over the validation segments."""
    if not np.all(np.isfinite(theta)):
        return float("nan")
    return float(np.mean(position_errors(validation, theta)))


def _joint_task(data: SegmentData, settings: JointSettings) -> tuple[np.ndarray, np.ndarray] | None:
    try:
        result = calibrate_joint(data, settings)
    except GraphcalError:
        return None
    return result.theta, result.covariance


def select(
    log: DriveLog, settings: Settings, progress: Progress
) -> tuple[Segments, np.ndarray, Segments, Segments]:
    """Calibration segments, their yaw statistic, the selected ones, validation segments."""
    s = settings.segments
    segments = split_segments(log, s.length, s.stride)
    yaw = yaw_rate_statistic(log, segments, s.yaw_statistic, s.yaw_window)
    selected = segments.subset(yaw > s.min_yaw_rate)
    progress(
        f"segments: {len(selected)} of {len(segments)} {s.length:g} m segments have "
        f"{s.yaw_statistic} |yaw rate| > {s.min_yaw_rate:g} rad/s"
    )
    if len(selected) == 0:
        best = f"{yaw.max():.3f}" if len(yaw) else "n/a"
        raise NoUsableSegments(
            f"{log.source}: no {s.length:g} m segment has {s.yaw_statistic} |yaw rate| above "
            f"{s.min_yaw_rate:g} rad/s (highest: {best} rad/s); lower --min-yaw-rate, use "
            "overlapping segments (--segment-stride) or a drive with more bends"
        )
    validation = split_segments(log, s.validation_length)
    if len(validation) == 0:
        raise NoUsableSegments(
            f"{log.source}: log is shorter than one {s.validation_length:g} m validation "
            "segment; use a longer drive or a shorter --validation-length"
        )
    return segments, yaw, selected, validation


def run_calibration(
    log: DriveLog,
    settings: Settings | None = None,
    method: Method = "staged",
    theta_true: np.ndarray | None = None,
    progress: Progress | None = None,
    workers: int = 1,
) -> CalibrationRun:
    """Calibrate theta from ``log``.

    Args:
        log: a validated drive log.
        settings: run settings (the paper's by default).
        method: ``"staged"`` (the paper's five steps over batches), ``"joint"`` (one joint
            graph per batch) or ``"whole"`` (one solve over all selected segments).
        theta_true: the true theta if known (synthetic drives); adds the reachable limit.
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
    segments, yaw, selected, validation_segments = select(log, settings, say)
    data = gather_segments(log, selected)
    validation = gather_segments(log, validation_segments)
    staged = None
    batches = None
    batch_theta: dict[str, np.ndarray] = {}
    batch_covariance: dict[str, np.ndarray] = {}
    if method in ("staged", "joint"):
        b = settings.batches
        size = min(b.size, len(selected))
        if size < b.size:
            say(f"only {len(selected)} segments: batches of {size} instead of {b.size}")
        batches = make_batches(len(selected), size, b.count, b.seed)
        say(f"{method}: {len(batches)} batches of {size} segments, {workers} worker(s)")
    if method == "staged":
        staged = run_staged(data, batches, settings, workers, say)
        theta = staged.final_theta
        batch_theta = dict(staged.theta)
    elif method == "joint":
        tasks = [(data.take(batch), settings.joint) for batch in batches]
        results = map_tasks(_joint_task, tasks, workers, say, "joint batch solves")
        batch_theta["joint"] = np.array(
            [np.full(4, np.nan) if r is None else r[0] for r in results]
        )
        batch_covariance["joint"] = np.array(
            [np.full((4, 4), np.nan) if r is None else r[1] for r in results]
        )
        good = batch_theta["joint"][np.all(np.isfinite(batch_theta["joint"]), axis=1)]
        if len(good) == 0:
            raise GraphcalError("every joint batch solve failed; no calibration to report")
        if len(good) < len(batches):
            say(f"warning: {len(batches) - len(good)} of {len(batches)} joint solves failed")
        theta = np.median(good, axis=0)
    else:
        solve = dataclasses.replace(
            settings.calibration,
            estimate_start_poses=True,
            max_iterations=max(settings.calibration.max_iterations, 20),
        )
        say(f"whole: one graph over {len(selected)} segments, start poses estimated")
        theta = calibrate_batch(data, solve).theta
        batch_theta["whole"] = theta[None]
    batch_errors = {
        name: np.array([mean_validation_error(validation, t) for t in thetas])
        for name, thetas in batch_theta.items()
    }
    segment_errors = {
        "nominal": position_errors(validation, THETA_NOMINAL),
        "calibrated": position_errors(validation, theta),
    }
    if theta_true is not None:
        segment_errors["true"] = position_errors(validation, theta_true)
    warnings = list(staged.warnings) if staged is not None else []
    if method != "whole" and len(selected) < settings.batches.size:
        warnings.append(
            f"only {len(selected)} selected segments for batches of {settings.batches.size}: "
            "every batch shares most segments, so spreads understate the uncertainty"
        )
    calibrated, nominal = np.mean(segment_errors["calibrated"]), np.mean(segment_errors["nominal"])
    if calibrated > nominal:
        warnings.append(
            f"the calibrated theta validates worse than the nominal one ({calibrated:.2f} m vs "
            f"{nominal:.2f} m): check the log (units, a faulty wheel sensor) before using it"
        )
    solved = {k: e[np.isfinite(e)] for k, e in batch_errors.items()}
    if staged is not None and len(solved["step1"]) and len(solved["step5"]):
        first, last = np.median(solved["step1"]), np.median(solved["step5"])
        if last > first:
            warnings.append(
                f"Step 5 validates worse than Step 1 (median {last:.2f} m vs {first:.2f} m): "
                "too little data for the compensation; try --method joint or a longer drive"
            )
    for line in warnings:
        say(f"warning: {line}")
    say(f"validated on {len(validation)} {settings.segments.validation_length:g} m segments")
    return CalibrationRun(
        log,
        settings,
        method,
        segments,
        selected,
        yaw,
        data,
        theta,
        batches,
        batch_theta,
        batch_covariance,
        staged,
        validation_segments,
        validation,
        segment_errors,
        batch_errors,
        None if theta_true is None else np.asarray(theta_true, dtype=float),
        tuple(warnings),
    )
