"""Time offsets between the streams of a drive log.

A wheel signal that arrives ``offset`` seconds late against the pose has measured rotation
over ``[t_k, t_k+1]`` equal to the true rotation over ``[t_k − offset, t_k+1 − offset]``.
:func:`shift_wheel_rotations` undoes that by interpolating the cumulative rotation at the
shifted times and differencing — never by moving samples.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.log.drive_log import DriveLog
from graphcal.model import step_increments, wrap_angle


def shift_wheel_rotations(log: DriveLog, offset: float | np.ndarray) -> DriveLog:
    """``log`` with its wheel rotations taken ``offset`` seconds later (SI): one offset, or
    one per run of the log (``DriveLog.run``), each run shifted within itself.

    ``offset`` > 0 corrects wheels that are late against the pose: the rotation of interval
    ``k`` becomes the measured rotation over ``[t_k + offset, t_k+1 + offset]``. The ends
    (of the log, or of a run), where the shifted interval leaves them, repeat the nearest
    measured rate.
    """
    offsets = np.atleast_1d(np.asarray(offset, float))
    if not offsets.any():
        return log
    if len(offsets) not in (1, log.runs):
        raise ValueError(f"{len(offsets)} time offsets for a log of {log.runs} runs")
    if log.run is None:
        spans = [(0, len(log.t), float(offsets[0]))]
    else:
        offsets = np.broadcast_to(offsets, (log.runs,))
        starts = np.searchsorted(log.run, np.arange(log.runs))
        ends = np.append(starts[1:], len(log.t))
        spans = [(int(a), int(b), float(o)) for a, b, o in zip(starts, ends, offsets, strict=True)]
    shifted = {}
    for name in ("n_rl", "n_rr"):
        rotations = np.array(getattr(log, name), dtype=float)
        for a, b, value in spans:
            if value != 0.0 and b - a > 1:
                rotations[a:b] = _shifted(log.t[a:b], rotations[a:b], value)
        shifted[name] = rotations
    return dataclasses.replace(log, **shifted)


def _shifted(t: np.ndarray, rotations: np.ndarray, offset: float) -> np.ndarray:
    """The rotations per interval of samples at ``t`` taken ``offset`` [s] later
    (:func:`shift_wheel_rotations` of one span)."""
    step = np.append(np.diff(t), np.diff(t)[-1])  # row k's interval (the last repeats)
    ends = np.append(t, t[-1] + step[-1])
    cumulative = np.concatenate([[0.0], np.cumsum(rotations)])
    at = np.interp(ends + offset, ends, cumulative)
    # Beyond the span, continue at the first / last interval's rate.
    before, after = ends + offset < ends[0], ends + offset > ends[-1]
    rate_first, rate_last = rotations[0] / step[0], rotations[-1] / step[-1]
    at[before] = (ends[before] + offset - ends[0]) * rate_first
    at[after] = cumulative[-1] + (ends[after] + offset - ends[-1]) * rate_last
    return np.diff(at)


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


#: Widest wheel time offset [s] :func:`wheel_lag_from_turns` looks for.
MAX_LAG_S = 1.0
#: Time [s] over which the measured heading's change is compared with the wheels' turn.
TURN_WINDOW_S = 0.5
#: The fit of the heading's changes by the wheels' turns (a correlation) at the lag found must
#: reach this: the recording turns clearly enough for its timing to show.
MIN_TURN_CORRELATION = 0.9
#: Windows at least, for a run's lag to be looked for.
MIN_TURN_WINDOWS = 20
#: A lag is taken only where it fits this many standard errors better than none
#: (:func:`lag_is_shown`).
LAG_SIGNIFICANCE = 3.0


def wheel_lag_from_turns(
    log: DriveLog, theta: np.ndarray, max_lag: float = MAX_LAG_S
) -> np.ndarray:
    """How late each run's wheels are against the measured heading, in whole samples [s]
    ``(runs,)``, before any solve: the lag at which the wheels' turn (eq. 2b with ``theta``;
    only its shape matters) over :data:`TURN_WINDOW_S` windows best fits the measured
    heading's change over the same windows (their correlation, largest), within
    ±``max_lag``.

    0 for a run whose heading is not measured, that turns too little to tell
    (correlation under :data:`MIN_TURN_CORRELATION`, fewer than :data:`MIN_TURN_WINDOWS`
    windows), whose best lag is the search's edge, or whose turns fit at it no better than
    at none beyond chance (:func:`lag_is_shown`). A shift by the lag found is exact (whole
    samples): the joint solve's time offset covers what is left, under a sample."""
    lags = np.zeros(log.runs)
    dt = log.dt
    reach = int(np.floor(max_lag / dt))
    usable = np.isfinite(log.psi) if log.masked is None else np.isfinite(log.psi) & ~log.masked
    heading = log.heading_measured & usable
    if reach < 1 or heading.sum() < MIN_TURN_WINDOWS:
        return lags
    _, turn = step_increments(log.inputs, theta)
    turn = np.nan_to_num(turn)
    turned = np.concatenate([[0.0], np.cumsum(turn)])  # the wheels' heading at each sample
    masked = np.zeros(len(log.t) + 1)
    if log.masked is not None:
        masked[1:] = np.cumsum(log.masked)
    run = log.run_of(np.arange(len(log.t)))
    for r in range(log.runs):
        rows = np.flatnonzero(run == r)
        first, last = int(rows[0]), int(rows[-1])
        fixes = np.flatnonzero(heading[first : last + 1]) + first
        if len(fixes) < 2:
            continue
        spacing = max(1, round(TURN_WINDOW_S / (dt * max(np.median(np.diff(fixes)), 1))))
        a, b = fixes[:-spacing], fixes[spacing:]
        # Windows whose every shifted span stays in the run and clear of masked samples.
        keep = (a - reach >= first) & (b + reach <= last)
        keep &= masked[np.minimum(b + reach, len(log.t))] - masked[a - reach] == 0
        a, b = a[keep], b[keep]
        if len(a) < MIN_TURN_WINDOWS:
            continue
        measured = wrap_angle(log.psi[b] - log.psi[a])
        # A clock off by seconds (GPS time against UTC: 18 s) is found on coarse bins first.
        centre = coarse_wheel_lag(turned, log.psi, usable, dt, first, last, max_lag)
        if centre:
            keep = (a + centre - reach >= first) & (b + centre + reach <= last)
            a, b, measured = a[keep], b[keep], measured[keep]
            clear = masked[b + centre + reach] - masked[a + centre - reach] == 0
            a, b, measured = a[clear], b[clear], measured[clear]
            if len(a) < MIN_TURN_WINDOWS:
                continue
        shifts = centre + np.arange(-reach, reach + 1)
        correlation = np.zeros(len(shifts))
        measured_norm = float(np.sqrt(measured @ measured))
        for i, shift in enumerate(shifts):  # one pass per shift: a 200 km log's windows
            wheels = turned[b + shift] - turned[a + shift]  # at once would take 0.5 GB
            norm = float(np.sqrt(wheels @ wheels)) * measured_norm
            correlation[i] = float(wheels @ measured) / norm if norm > 0 else 0.0
        best = int(np.argmax(np.abs(correlation)))
        if abs(correlation[best]) < MIN_TURN_CORRELATION or best in (0, len(shifts) - 1):
            continue
        # The peak between samples (a parabola through it and its neighbours), rounded.
        below, at, above = correlation[best - 1 : best + 2] * np.sign(correlation[best])
        curvature = below - 2.0 * at + above
        between = 0.5 * (below - above) / curvature if curvature < 0 else 0.0
        lag = np.round(shifts[best] + between) * dt + 0.0  # never -0.0
        if centre or lag_is_shown(
            measured,
            *(turned[b + shifts[i]] - turned[a + shifts[i]] for i in (reach, best)),
            spacing,
        ):
            lags[r] = lag
    return lags


def lag_is_shown(
    measured: np.ndarray, unshifted: np.ndarray, shifted: np.ndarray, overlap: int = 1
) -> bool:
    """Whether the wheels' turns ``shifted`` by a lag fit the heading's changes ``measured``
    (per window, [rad]) better than ``unshifted`` by more than chance: each window's squared
    residual of the fit (a scale fitted to each) at no lag less at the lag, summed, at least
    :data:`LAG_SIGNIFICANCE` standard errors of the sum above none (batch means: the
    differences summed over blocks of twice the ``overlap``, the windows that share a fix
    interval, and the blocks' scatter).

    The turns carry noise of their own (a wheel's ticks), and each shift draws it anew: a
    difference of fits taken as the heading's noise alone, a car's 0.5 Hz heading over 2 s
    windows and its wheels of 16 ticks claimed −100 ms, from a correlation 0.992–0.993 from
    −150 to +100 ms, and the solve from there kept −95 ± 5 ms against the truth's 0
    (campaign seed 56's shape 67). A lag left unshown costs a time-offset round instead: the
    real robot's run 2, +52 ms (z 1.5 here, ±0.7 ms from the solve), is found by the solve
    and shifted in its second round."""

    def squares(turns: np.ndarray) -> np.ndarray:
        scale = float(turns @ measured) / max(float(turns @ turns), np.finfo(float).tiny)
        return (measured - scale * turns) ** 2

    gain = squares(unshifted) - squares(shifted)
    block = 2 * max(overlap, 1)  # batch means: blocks longer than the windows' overlap
    sums = np.add.reduceat(gain, np.arange(0, len(gain), block))
    spread = float(np.sqrt(len(sums)) * np.std(sums))
    return float(gain.sum()) > LAG_SIGNIFICANCE * spread


#: Bins [s] over which :func:`coarse_wheel_lag` compares turns, the widest lag [s] it looks
#: for, and by how much the correlation at its lag must exceed that at every lag more than
#: two bins away (a robot circling at a steady rate turns alike at every lag).
COARSE_BIN_S = 0.5
MAX_COARSE_LAG_S = 30.0
COARSE_DISTINCT = 0.1


def coarse_wheel_lag(
    turned: np.ndarray,
    psi: np.ndarray,
    usable: np.ndarray,
    dt: float,
    first: int,
    last: int,
    fine_lag: float = MAX_LAG_S,
) -> int:
    """How late the wheels are [samples], by whole bins of :data:`COARSE_BIN_S` within
    ±:data:`MAX_COARSE_LAG_S`, when it is more than ``fine_lag`` [s] (else 0): the lag at
    which the wheels' heading ``turned`` ``(N+1,)`` [rad] turns as the heading ``psi`` did
    (the grid's, filled between sparse measured ones; bins with a row not ``usable`` left
    out), over rows ``first``–``last`` — a
    distinct peak of the correlation (:data:`MIN_TURN_CORRELATION`,
    :data:`COARSE_DISTINCT`)."""
    width = max(1, round(COARSE_BIN_S / dt))
    edges = np.arange(first, last + 1, width)
    reach = int(MAX_COARSE_LAG_S / (width * dt))
    if len(edges) < 2 * reach + MIN_TURN_WINDOWS:
        return 0
    gaps = np.concatenate([[0], np.cumsum(~usable)])
    clean = gaps[edges[1:] + 1] - gaps[edges[:-1]] == 0
    measured = np.where(clean, wrap_angle(np.diff(psi[edges])), 0.0)
    wheels = np.where(clean, np.diff(turned[edges]), 0.0)
    n = len(measured)
    lags = np.arange(-reach, reach + 1)
    correlation = np.zeros(len(lags))
    for i, lag in enumerate(lags):  # the wheels' bin j + lag against the heading's bin j
        m = measured[max(0, -lag) : n - max(0, lag)]
        w = wheels[max(0, lag) : n - max(0, -lag)]
        norm = float(np.sqrt((m @ m) * (w @ w)))
        correlation[i] = float(m @ w) / norm if norm > 0 else 0.0
    best = int(np.argmax(correlation))
    others = np.abs(lags - lags[best]) > 2
    distinct = correlation[best] - np.max(correlation[others], initial=-1.0) >= COARSE_DISTINCT
    if correlation[best] < MIN_TURN_CORRELATION or not distinct:
        return 0
    if abs(lags[best]) * width * dt <= fine_lag:
        return 0
    return int(lags[best] * width)


def masked_for_the_clock_lag(log: DriveLog, lag: np.ndarray) -> DriveLog:
    """``log`` with the rows masked that a shift of its wheels by each run's ``lag`` [s]
    ``(runs,)`` (:func:`wheel_lag_from_turns`) leaves without wheel data, where the lag is
    more than :data:`MAX_LAG_S` (clocks apart): the run's last rows for late wheels, its
    first for early ones, so that no segment spans them. The wheels are not shifted here:
    the whole-log solve shifts them by the lag, as any, and reports it."""
    lag = np.where(np.abs(lag) > MAX_LAG_S, lag, 0.0)
    if not lag.any():
        return log
    masked = np.zeros(len(log.t), bool) if log.masked is None else log.masked.copy()
    run = log.run_of(np.arange(len(log.t)))
    notes = list(log.mask_notes)
    for r in np.flatnonzero(lag):
        rows = np.flatnonzero(run == r)
        count = min(len(rows), int(np.ceil(abs(lag[r]) / log.dt - 1e-9)))
        left = rows[-count:] if lag[r] > 0 else rows[:count]
        masked[left] = True
        notes.append(
            f"t = {log.t[left[0]]:.1f}–{log.t[left[-1]]:.1f} s: no wheel data once the wheels "
            f"are shifted by their clock's lag of {lag[r]:+.1f} s"
        )
    return dataclasses.replace(log, masked=masked, mask_notes=tuple(notes))
