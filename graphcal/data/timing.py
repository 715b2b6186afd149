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


def whole_samples(offset: float, dt: float) -> float:
    """``offset`` [s] rounded to a whole number of sample intervals ``dt`` [s]: the shifts
    :func:`shift_wheel_rotations` makes without averaging neighbouring rotations."""
    return float(np.round(offset / dt)) * dt


#: Half-width [s] of the moving mean that smooths the wheel speeds of
#: :func:`rotation_rate_changes`: the speed changes over ~1 s, the rotation noise per step.
RATE_SMOOTHING_S = 0.25


def rotation_rate_changes(rotations: np.ndarray, dt: float) -> np.ndarray:
    """How each step's rotation changes per second of wheel time offset, ``(K, W)`` [rev/s].

    The rotation over ``[t_k + τ, t_k+1 + τ]`` is ``n_k + τ · (ṅ(t_k+1) − ṅ(t_k))`` to first
    order, with ``ṅ`` the wheel speed [rev/s] at the step boundaries: here from the rotations
    ``(K, W)`` per step averaged over a centred window of :data:`RATE_SMOOTHING_S` on each
    side (narrower near the ends), so that the rotation noise is not differenced.
    """
    rotations = np.asarray(rotations, float)
    k = len(rotations)
    if k < 2:
        return np.zeros_like(rotations)
    half = max(1, round(RATE_SMOOTHING_S / dt))
    total = np.concatenate([np.zeros((1, *rotations.shape[1:])), np.cumsum(rotations, axis=0)])
    steps = np.arange(k)
    width = np.minimum(np.minimum(steps, k - 1 - steps), half)
    speed = (total[steps + width + 1] - total[steps - width]) / ((2 * width + 1)[:, None] * dt)
    # At the boundaries: between step centres, extrapolated linearly at the two ends.
    inner = 0.5 * (speed[1:] + speed[:-1])
    first = 1.5 * speed[0] - 0.5 * speed[1]
    last = 1.5 * speed[-1] - 0.5 * speed[-2]
    boundary = np.concatenate([first[None], inner, last[None]])
    return np.diff(boundary, axis=0)
