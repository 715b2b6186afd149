"""Validation on data the calibration did not see: another log, or time windows of the same
log held apart from the calibration.

A calibration's own validation (eq. 16 on the log it calibrated from) shows how well theta
fits that log; a user judges a calibration by how well it predicts driving it never saw.
:func:`validation_errors` dead-reckons the validation segments of any log with a theta (the
same segments and errors as a run's validation, :mod:`graphcal.pipeline.methods.validation`).
:func:`time_windows`, :func:`holding_apart` and :func:`time_window` cut one log into a part to
calibrate from (the windows masked: no segment spans them, so none of their measurements is
used) and the windows to validate on.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import Segments, gather_segments, split_segments
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.methods.validation import position_errors


@dataclass(frozen=True)
class HeldApartErrors:
    """Position errors [m] of dead reckoning on a log's validation segments (eq. 16 / K).

    Attributes:
        segments: the validation segments of the log.
        nominal: per segment, the error with the vehicle's nominal theta.
        calibrated: per segment, the error with the calibrated theta.
    """

    segments: Segments
    nominal: np.ndarray
    calibrated: np.ndarray

    @property
    def improvement(self) -> float:
        """How much lower the calibrated mean error is than the nominal one (0.6: 60 %)."""
        return 1.0 - float(np.mean(self.calibrated)) / float(np.mean(self.nominal))


def validation_errors(log: DriveLog, theta: np.ndarray, settings: Settings) -> HeldApartErrors:
    """The errors of the nominal theta and of ``theta`` (SI) on ``log``'s validation
    segments (``settings.segments.validation_length``, cut as a calibration cuts them: a run
    between gaps shorter than that length is a segment of its own).

    Raises:
        GraphcalError: ``log`` has no validation segment.
    """
    circumference = float(settings.vehicle.theta_nominal[0])
    length = settings.segments.validation_length
    segments = split_segments(log, length, None, circumference)
    if len(segments) == 0:
        distance = float(log.travelled_distance(circumference)[-1])
        raise GraphcalError(
            f"{log.source}: no validation segment ({distance:.1f} m of driving, segments of "
            f"{length:g} m); use a longer log or a shorter --validation-length"
        )
    data = gather_segments(log, segments)
    return HeldApartErrors(
        segments,
        position_errors(data, settings.vehicle.theta_nominal),
        position_errors(data, np.asarray(theta, float)),
    )


def time_windows(log: DriveLog, count: int) -> np.ndarray:
    """``(count, 2)`` equal time windows ``[start, end)`` [s] covering ``log``."""
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    edges = np.linspace(log.t[0], log.t[-1], count + 1)
    edges[-1] = np.nextafter(log.t[-1], np.inf)
    return np.column_stack([edges[:-1], edges[1:]])


def in_windows(log: DriveLog, windows: np.ndarray) -> np.ndarray:
    """``(N,)``: the samples inside any of ``windows`` ``(W, 2)`` ``[start, end)`` [s]."""
    inside = np.zeros(len(log.t), bool)
    for start, end in np.atleast_2d(windows):
        inside |= (log.t >= start) & (log.t < end)
    return inside


def holding_apart(log: DriveLog, windows: np.ndarray) -> DriveLog:
    """``log`` with ``windows`` ``(W, 2)`` [s] masked: a calibration from it uses no
    measurement inside them (no segment spans a masked sample)."""
    held = in_windows(log, windows)
    masked = held if log.masked is None else (np.asarray(log.masked, bool) | held)
    notes = (*log.mask_notes, f"{held.sum() * log.dt:.1f} s held apart for validation")
    return dataclasses.replace(log, masked=masked, mask_notes=notes)


def time_window(log: DriveLog, start: float, end: float) -> DriveLog:
    """The samples of ``log`` in ``[start, end)`` [s], as a log of their own."""
    rows = np.flatnonzero((log.t >= start) & (log.t < end))
    if len(rows) < 2:
        raise GraphcalError(f"{log.source}: fewer than 2 samples in t = {start:g}–{end:g} s")
    cut = slice(int(rows[0]), int(rows[-1]) + 1)
    per_sample = {
        f.name: getattr(log, f.name)[cut]
        for f in dataclasses.fields(log)
        if isinstance(getattr(log, f.name), np.ndarray) and len(getattr(log, f.name)) == len(log.t)
    }
    if log.fix_lag is not None:  # the first row's fix lies before the window
        lag = per_sample["fix_lag"].copy()
        lag[0] = 0.0
        per_sample["fix_lag"] = lag
        measured = per_sample["measured"].copy() if log.measured is not None else None
        if measured is not None and log.fix_lag[cut][0] > 0:
            measured[0] = False
            per_sample["measured"] = measured
    return dataclasses.replace(log, **per_sample, source=f"{log.source} [{start:g}, {end:g}) s")
