"""The segments a run calibrates and validates on: the log cut into calibration segments, those
that turn enough selected (§5.1), and the validation segments; a one-line error naming what
to change when the log has none."""

from __future__ import annotations

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import Segments, split_segments, yaw_rate_statistic
from graphcal.pipeline.configuration.settings import SegmentSettings, Settings
from graphcal.pipeline.configuration.vehicle_settings import (
    CAR_SEGMENT_LENGTH,
    CAR_VALIDATION_LENGTH,
    segment_lengths,
)
from graphcal.progress import say

#: With fewer selected segments than this, the joint and whole methods use every segment of
#: the log: so few carry little information, and the segments' agreement test needs this many
#: groups (:data:`graphcal.pipeline.methods.agreement.GROUPS`). A 373 m robot log kept 1 of 7 53 m
#: segments (mean |yaw rate| > 0.15 rad/s, a car's rule) and calibrated nothing from it.
MIN_SELECTED_SEGMENTS = 8


class NoUsableSegments(GraphcalError, ValueError):
    """The log has no segment that passes the selection."""


def select(
    log: DriveLog, settings: Settings, fall_back_to_all: bool = False
) -> tuple[Segments, np.ndarray, Segments, Segments]:
    """Calibration segments, their yaw statistic [rad/s], the selected ones, validation
    segments.

    With ``fall_back_to_all`` (for methods that judge observability themselves), a log where
    fewer than :data:`MIN_SELECTED_SEGMENTS` segments pass the yaw-rate selection uses all
    its segments (none passing is then no failure).

    Raises:
        NoUsableSegments: the log is too short, or no segment passes the selection.
    """
    s = settings.segments
    circumference = float(settings.vehicle.theta_nominal[0])
    if settings.vehicle.size_scale() != 1.0:
        say(_lengths_line(settings))
    for note in log.mask_notes:
        say(f"masked: {note}")
    segments = split_segments(log, s.length, s.stride, circumference)
    nominal = settings.vehicle.theta_nominal
    yaw = yaw_rate_statistic(log, segments, s.yaw_statistic, s.yaw_window, nominal)
    selected = segments.subset(yaw > s.min_yaw_rate)
    say(
        f"segments: {len(selected)} of {len(segments)} {s.length:g} m segments have "
        f"{s.yaw_statistic} |yaw rate| > {s.min_yaw_rate:g} rad/s"
    )
    if len(selected) < MIN_SELECTED_SEGMENTS and fall_back_to_all and len(segments) > len(selected):
        passing = "no segment passes" if len(selected) == 0 else f"only {len(selected)} pass"
        say(
            f"{passing} the yaw-rate selection: using all {len(segments)} segments; "
            "the observability check decides what they determine"
        )
        selected = segments
    if len(segments) == 0:
        raise _too_short(log, s, circumference)
    if len(selected) == 0:
        raise _none_selected(log, s, yaw, fall_back_to_all)
    validation = split_segments(log, s.validation_length, None, circumference)
    if len(validation) == 0:
        raise _no_validation(log, s, circumference)
    return segments, yaw, selected, validation


def _lengths_line(settings: Settings) -> str:
    """The progress line naming the segment lengths of a vehicle other than the car's size,
    and whether they follow its size."""
    s = settings.segments
    how = (
        f"the car's {CAR_SEGMENT_LENGTH:g} m and {CAR_VALIDATION_LENGTH:g} m scaled to the "
        f"vehicle's {settings.vehicle.theta_nominal[2]:g} m track"
        if (s.length, s.validation_length) == segment_lengths(settings.vehicle)
        else "as set"
    )
    return f"segments of {s.length:g} m, validation segments of {s.validation_length:g} m ({how})"


def _too_short(log: DriveLog, s: SegmentSettings, circumference: float) -> NoUsableSegments:
    """The error for a log without one calibration segment."""
    distance = log.travelled_distance(circumference)[-1]
    where = (
        f"the log's {distance:.1f} m"
        if log.masked is None
        else f"every stretch between masked samples ({log.masked.mean():.0%} of the log "
        f"masked; first: {log.mask_notes[0]})"
    )
    return NoUsableSegments(
        f"{log.source}: {where} is shorter than one {s.length:g} m segment; set a "
        "shorter --segment-length (or [segments] length), or give the vehicle's profile "
        "(--vehicle), whose size sets the lengths"
    )


def _none_selected(
    log: DriveLog, s: SegmentSettings, yaw: np.ndarray, fall_back_to_all: bool
) -> NoUsableSegments:
    """The error for a log whose segments all turn too little."""
    best = f"{yaw.max():.3f}" if len(yaw) else "n/a"
    return NoUsableSegments(
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


def _no_validation(log: DriveLog, s: SegmentSettings, circumference: float) -> NoUsableSegments:
    """The error for a log without one validation segment."""
    distance = log.travelled_distance(circumference)[-1]
    if log.masked is not None and distance >= s.validation_length:
        return NoUsableSegments(
            f"{log.source}: no {s.validation_length:g} m stretch of the log is free of "
            f"masked samples ({log.masked.mean():.0%} of the log masked in "
            f"{len(log.mask_notes)} span(s); first: {log.mask_notes[0]}); check the "
            "positions, or use a shorter --validation-length"
        )
    return NoUsableSegments(
        f"{log.source}: log ({distance:.1f} m) is shorter than one "
        f"{s.validation_length:g} m validation segment; use a longer drive, a shorter "
        "--validation-length (or [segments] validation_length), or give the vehicle's "
        "profile (--vehicle), whose size sets the lengths"
    )
