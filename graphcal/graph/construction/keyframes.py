"""Keyframes of a localization graph: the samples that get a Pose2 variable."""

from __future__ import annotations

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.log.drive_log import DriveLog


def gnss_keyframes(log: DriveLog, rate_hz: float) -> np.ndarray:
    """Sample indices of keyframes at ``rate_hz`` [Hz] (every ``1 / (rate_hz dt)``-th sample);
    in a log with sparse measurements, the rows that hold a position fix, every n-th if the
    fixes come faster than ``rate_hz``."""
    if log.measured is not None:
        rows = np.flatnonzero(log.position_measured)
        if len(rows) > 1:
            interval = float(np.median(np.diff(log.t[rows])))
            rows = rows[:: max(1, round(1.0 / (rate_hz * interval)))]
        return rows
    stride = round(1.0 / (rate_hz * log.dt))
    if stride < 1 or abs(stride * rate_hz * log.dt - 1.0) > 0.01:
        raise GraphcalError(
            f"GNSS rate {rate_hz:g} Hz does not divide the log's {1 / log.dt:g} Hz sampling; "
            "choose a rate that does (e.g. 5 or 10 Hz for 40 Hz logs)"
        )
    return np.arange(0, len(log), stride)


def fix_offsets(log: DriveLog, rows: np.ndarray, wheel_circumference: float) -> np.ndarray:
    """How far ahead [m] of each row's pose its fix was taken: minus the distance driven
    (nominal ``wheel_circumference``) in the fix's lag, as a body-frame offset along the
    heading, ``(len(rows),)`` (0 for a fix at its row, and in a uniform log)."""
    fraction = log.fix_fraction
    rows = np.asarray(rows, dtype=np.int64)
    if fraction is None:
        return np.zeros(len(rows))
    before = np.maximum(rows - 1, 0)
    step = 0.5 * (log.n_rl[before] + log.n_rr[before]) * wheel_circumference
    return -(1.0 - fraction[rows]) * step
