"""End-to-end calibration of one drive log: segments → selection → batch solve → validation."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import (
    SegmentData,
    Segments,
    YawRateStatistic,
    gather_segments,
    select_segments,
    split_segments,
    yaw_rate_statistic,
)
from graphcal.errors import GraphcalError
from graphcal.model import THETA_NOMINAL
from graphcal.pipeline.batch_calibration import BatchCalibration, BatchSettings, calibrate_batch
from graphcal.pipeline.validation import position_errors

Progress = Callable[[str], None]


class NoUsableSegments(GraphcalError, ValueError):
    """The log has no segment that passes the selection."""


@dataclass(frozen=True)
class RunSettings:
    """Settings of an end-to-end calibration (SI; paper defaults, §4.4 and §5.1).

    Attributes:
        segment_length: calibration segment length [m].
        segment_stride: distance between calibration segment starts [m]; ``None`` = disjoint.
        min_yaw_rate: selection threshold on the segment's yaw-rate statistic [rad/s].
        yaw_statistic: ``"mean"``, ``"median"`` or ``"rms"`` of the absolute yaw rate.
        yaw_window: heading-difference window for the yaw rate [s].
        validation_length: validation segment length [m] (disjoint).
        batch: settings of the graph solve.
    """

    segment_length: float = 150.0
    segment_stride: float | None = None
    min_yaw_rate: float = 0.15
    yaw_statistic: YawRateStatistic = "mean"
    yaw_window: float = 1.0
    validation_length: float = 300.0
    batch: BatchSettings = field(default_factory=BatchSettings)

    def __post_init__(self) -> None:
        for name in ("segment_length", "validation_length", "yaw_window"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name.replace('_', '-')} must be positive")
        if self.segment_stride is not None and not self.segment_stride > 0:
            raise ValueError("segment-stride must be positive")
        if not self.min_yaw_rate >= 0:
            raise ValueError("min-yaw-rate must be >= 0")


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration run produced (SI).

    Attributes:
        log: the drive log.
        settings: the settings used.
        segments: all calibration segments; ``selected`` those used.
        yaw_rate: the selection statistic of every calibration segment [rad/s].
        calibration: the batch solve over the selected segments.
        validation_segments: the validation segments; ``validation`` their data.
        validation_errors: per validation segment, mean position error [m] of odometry with
            ``{"nominal", "calibrated"}`` theta, and ``"true"`` when the truth is known.
        theta_true: true theta of a synthetic drive, else ``None``.
    """

    log: DriveLog
    settings: RunSettings
    segments: Segments
    selected: Segments
    yaw_rate: np.ndarray
    calibration: BatchCalibration
    validation_segments: Segments
    validation: SegmentData
    validation_errors: dict[str, np.ndarray]
    theta_true: np.ndarray | None = None

    @property
    def theta(self) -> np.ndarray:
        """The calibrated theta (SI)."""
        return self.calibration.theta


def run_calibration(
    log: DriveLog,
    settings: RunSettings | None = None,
    theta_true: np.ndarray | None = None,
    progress: Progress | None = None,
) -> CalibrationRun:
    """Calibrate theta from ``log``: select segments, solve one batch over all, validate.

    Args:
        log: a validated drive log.
        settings: run settings (paper defaults).
        theta_true: the true theta if known (synthetic drives); adds the reachable limit.
        progress: called with one line per stage.

    Raises:
        NoUsableSegments: no calibration segment passes the selection.
        CalibrationFailed: the solve failed.
    """
    settings = settings or RunSettings()
    say = progress or (lambda _line: None)
    segments = split_segments(log, settings.segment_length, settings.segment_stride)
    yaw = yaw_rate_statistic(log, segments, settings.yaw_statistic, settings.yaw_window)
    selected = select_segments(
        log, segments, settings.min_yaw_rate, settings.yaw_statistic, settings.yaw_window
    )
    say(
        f"segments: {len(selected)} of {len(segments)} {settings.segment_length:g} m segments have "
        f"{settings.yaw_statistic} |yaw rate| > {settings.min_yaw_rate:g} rad/s"
    )
    if len(selected) == 0:
        best = f"{yaw.max():.3f}" if len(yaw) else "n/a"
        raise NoUsableSegments(
            f"{log.source}: no {settings.segment_length:g} m segment has {settings.yaw_statistic} "
            f"|yaw rate| above {settings.min_yaw_rate:g} rad/s (highest: {best} rad/s); lower "
            "--min-yaw-rate, use overlapping segments (--segment-stride) or a drive with more bends"
        )
    validation_segments = split_segments(log, settings.validation_length)
    if len(validation_segments) == 0:
        raise NoUsableSegments(
            f"{log.source}: log is shorter than one {settings.validation_length:g} m validation "
            "segment; use a longer drive or a shorter --validation-length"
        )
    data = gather_segments(log, selected)
    mode = "estimated" if settings.batch.estimate_start_poses else "held at measurement"
    say(f"solving: one graph over {len(selected)} segments, start poses {mode}")
    calibration = calibrate_batch(data, settings.batch)
    say(f"solved in {calibration.iterations} Levenberg–Marquardt iterations")
    validation = gather_segments(log, validation_segments)
    errors = {
        "nominal": position_errors(validation, THETA_NOMINAL),
        "calibrated": position_errors(validation, calibration.theta),
    }
    if theta_true is not None:
        errors["true"] = position_errors(validation, theta_true)
    say(f"validated on {len(validation)} {settings.validation_length:g} m segments")
    return CalibrationRun(
        log,
        settings,
        segments,
        selected,
        yaw,
        calibration,
        validation_segments,
        validation,
        errors,
        None if theta_true is None else np.asarray(theta_true, dtype=float),
    )
