"""Time offsets between the streams of a drive log.

A wheel signal that arrives ``offset`` seconds late against the pose has measured rotation
over ``[t_k, t_k+1]`` equal to the true rotation over ``[t_k − offset, t_k+1 − offset]``.
:func:`shift_wheel_rotations` undoes that by interpolating the cumulative rotation at the
shifted times and differencing — never by moving samples.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.data.drive_log import DriveLog


def shift_wheel_rotations(log: DriveLog, offset: float) -> DriveLog:
    """``log`` with its wheel rotations taken ``offset`` seconds later (SI).

    ``offset`` > 0 corrects wheels that are late against the pose: the rotation of interval
    ``k`` becomes the measured rotation over ``[t_k + offset, t_k+1 + offset]``. The ends,
    where the shifted interval leaves the log, repeat the nearest measured rate.
    """
    if offset == 0.0:
        return log
    t = log.t
    step = np.append(np.diff(t), np.diff(t)[-1])  # row k's interval (the last repeats)
    ends = np.append(t, t[-1] + step[-1])
    shifted = {}
    for name in ("n_rl", "n_rr"):
        cumulative = np.concatenate([[0.0], np.cumsum(getattr(log, name))])
        at = np.interp(ends + offset, ends, cumulative)
        # Beyond the log, continue at the first / last interval's rate.
        before, after = ends + offset < ends[0], ends + offset > ends[-1]
        rate_first = getattr(log, name)[0] / step[0]
        rate_last = getattr(log, name)[-1] / step[-1]
        at[before] = (ends[before] + offset - ends[0]) * rate_first
        at[after] = cumulative[-1] + (ends[after] + offset - ends[-1]) * rate_last
        shifted[name] = np.diff(at)
    return dataclasses.replace(log, **shifted)
