"""Validation error of a calibration (paper §5.2, eq. 16).

Each validation segment is dead-reckoned with the odometry model from its measured first pose
with the measured inputs; the error is the distance between odometry and measured positions.
Eq. (16) sums over the K samples; graphcal reports the mean over the samples (the sum divided
by K), which is what the paper's figures in metres (e.g. the 2.42 m reachable limit) show.

In a log with sparse fixes the error is the mean over the segment's fixes, each compared with
the odometry at its own time (:func:`graphcal.model.partial_steps`); a segment whose first
sample has no measured pose starts where its dead-reckoned path fits the fixes best (rigidly,
:func:`graphcal.model.aligned_trajectory`), since the track there is no measurement.
"""

from __future__ import annotations

import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.model import aligned_trajectory, integrate, partial_steps


def odometry_paths(data: SegmentData, theta: np.ndarray) -> np.ndarray:
    """The dead-reckoned states ``(S, K+1, 3)`` the validation compares: from each
    segment's measured start pose, or, where its first sample measured no pose there,
    moved rigidly to fit its fixes."""
    states = integrate(data.poses[:, 0], data.inputs, theta)
    if data.measured is None and data.fix_fraction is None:
        return states
    fixes = data.position_fixes()
    for s in np.flatnonzero(~data.start_measured().all(axis=1)):
        k = int(data.n_steps[s])
        states[s, : k + 1] = aligned_trajectory(
            states[s, : k + 1], data.poses[s, : k + 1], fixes[s, : k + 1].astype(float)
        )
    return states


def position_errors(data: SegmentData, theta: np.ndarray) -> np.ndarray:
    """Mean position error [m] per segment of odometry with ``theta`` (eq. 16 / K), ``(S,)``."""
    states = odometry_paths(data, theta)
    if data.measured is None and data.fix_fraction is None:
        distance = np.hypot(*(states[..., :2] - data.poses[..., :2]).transpose(2, 0, 1))
        valid = data.valid.copy()
        valid[:, 0] = False  # the start is the measured pose itself
        return (distance * valid).sum(axis=1) / data.n_steps
    return _errors_at_fixes(data, states, theta)


def _errors_at_fixes(data: SegmentData, states: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """:func:`position_errors` of a log with sparse fixes, from :func:`odometry_paths`
    ``states``: the mean over each segment's fixes after its start."""
    fixes = data.position_fixes()
    predicted = states
    if data.fix_fraction is not None:
        predicted = states.copy()
        predicted[:, 1:] = partial_steps(states, data.inputs, theta, data.fix_fraction[:, 1:])[0]
    distance = np.hypot(*(predicted[..., :2] - data.poses[..., :2]).transpose(2, 0, 1))
    used = fixes.copy()
    used[:, 0] = False
    return (distance * used).sum(axis=1) / np.maximum(used.sum(axis=1), 1)
