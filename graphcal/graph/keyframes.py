"""Keyframes of a localization graph: the samples that get a Pose2 variable."""

from __future__ import annotations

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.errors import GraphcalError


def gnss_keyframes(log: DriveLog, rate_hz: float) -> np.ndarray:
    """Sample indices of keyframes at ``rate_hz`` [Hz] (every ``1 / (rate_hz dt)``-th sample)."""
    stride = round(1.0 / (rate_hz * log.dt))
    if stride < 1 or abs(stride * rate_hz * log.dt - 1.0) > 0.01:
        raise GraphcalError(
            f"GNSS rate {rate_hz:g} Hz does not divide the log's {1 / log.dt:g} Hz sampling; "
            "choose a rate that does (e.g. 5 or 10 Hz for 40 Hz logs)"
        )
    return np.arange(0, len(log), stride)
