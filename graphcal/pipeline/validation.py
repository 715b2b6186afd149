"""Validation error of a calibration (paper §5.2, eq. 16).

Each validation segment is dead-reckoned with the odometry model from its measured first pose
with the measured inputs; the error is the distance between odometry and measured positions.
Eq. (16) sums over the K samples; graphcal reports the mean over the samples (the sum divided
by K), which is what the paper's figures in metres (e.g. the 2.42 m reachable limit) show.
"""

from __future__ import annotations

import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.model import integrate


def position_errors(data: SegmentData, theta: np.ndarray) -> np.ndarray:
    """Mean position error [m] per segment of odometry with ``theta`` (eq. 16 / K), ``(S,)``."""
    states = integrate(data.poses[:, 0], data.inputs, theta)
    distance = np.hypot(*(states[..., :2] - data.poses[..., :2]).transpose(2, 0, 1))
    valid = data.valid.copy()
    valid[:, 0] = False  # the start is the measured pose itself
    return (distance * valid).sum(axis=1) / data.n_steps
