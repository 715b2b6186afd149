"""Noise levels read from the log itself, so that the σ graphcal reports matches the error.

A fused heading's white noise varies by an order of magnitude between systems (the paper's
1.5°, a good INS's 0.1–0.3°); weighting it wrongly leaves the heading's slow bias and the
wheels' tick quantization to bias t_r and d (``docs/defects.md``). At 40 Hz the motion
changes the heading smoothly (a yaw acceleration of 0.5 rad/s² moves a second difference by
0.02°), so the second differences of the measured heading are its white noise:
``Δ²ψ_k = ε_k+1 − 2 ε_k + ε_k−1``, variance ``6 σ²``.

The wheels' noise the same way, on the wheel rates a recording gives at their own times
(:func:`rate_wheel_noise`): a profile's ``wheel_noise`` is a guess, and wheels noisier than
it leave the paper's bias partly uncompensated (a delivery robot's 0.02 m/s wheel speeds at
100 Hz, 26 % noisier per step than its profile's 0.0005 rev: t_r +2.9σ "calibrated", and
the spare noise found as "slow wheel slip"; with the wheels' own noise: +0.3σ, no slip).
"""

from __future__ import annotations

import numpy as np

from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL, step_increments

#: White noise has second differences of the same spread over one and over two steps; a
#: heading interpolated or held from a slower stream has much wider ones over two steps. Above
#: this ratio the log's heading noise is not estimated.
MAX_WIDE_RATIO = 1.5
#: Smallest heading noise [rad] reported (a heading smoother than this is weighted as this).
MIN_HEADING_SIGMA = np.deg2rad(0.01)


def heading_noise(
    log: DriveLog,
    nominal: np.ndarray | None = None,
    wheel_noise: float = 0.0,
    quantization: float = 0.0,
) -> float | None:
    """Robust sigma [rad] of the measured heading's white noise, from its second differences
    away from masked samples (``1.4826 · MAD / √6``), or ``None`` for a log too short or
    a heading interpolated or held from a slower stream (its noise is not white per sample;
    the configured heading weight stays). A log whose headings are not at every sample
    (sparse measurements) is measured on its own heading samples only
    (:func:`sparse_heading_noise`; ``nominal``: the vehicle's theta, ``wheel_noise`` [rev]
    per step and the tick ``quantization`` [rev] of the wheels)."""
    if log.sparse:
        if not log.heading_measured.any():
            return None
        nominal = THETA_NOMINAL if nominal is None else nominal
        return sparse_heading_noise(log, nominal, wheel_noise, quantization)
    return _uniform_heading_noise(log.psi, log.masked)


def _uniform_heading_noise(
    psi: np.ndarray, masked: np.ndarray | None, check_wide: bool = True
) -> float | None:
    """:func:`heading_noise` of headings at consecutive samples (``check_wide``: refuse
    headings interpolated or held from a slower stream, which a uniform log may hold)."""
    second = np.diff(psi, 2)
    usable = np.ones(len(second), dtype=bool)
    if masked is not None:
        bad = np.asarray(masked)
        usable &= ~(bad[:-2] | bad[1:-1] | bad[2:])
    second = second[usable]
    if len(second) < 100:
        return None
    wide = psi[4:] - 2.0 * psi[2:-2] + psi[:-4]  # over two steps each side
    if check_wide and _mad(wide) > MAX_WIDE_RATIO * _mad(second):
        return None  # interpolated or held from a slower stream: not white per sample
    return max(1.4826 * _mad(second) / np.sqrt(6.0), float(MIN_HEADING_SIGMA))


def _mad(values: np.ndarray) -> float:
    """Median absolute deviation."""
    return float(np.median(np.abs(values - np.median(values))))


#: Heading samples at most this far apart [s] are measured on their own second differences:
#: a yaw acceleration of 0.5 rad/s² moves one by 0.02° at 40 Hz and 0.3° at 4 Hz, the
#: median far less; slower headings are measured against the wheels' yaw.
MAX_PLAIN_SPACING_S = 0.25
#: Variance of a cumulative count's rounding at a time between two counter samples, as a
#: share of a count's (``(1 − a)² + a²``, averaged over the position ``a``).
INTERPOLATED_ROUNDING_SHARE = 2.0 / 3.0


def sparse_heading_noise(
    log: DriveLog, nominal: np.ndarray, wheel_noise: float = 0.0, quantization: float = 0.0
) -> float | None:
    """Heading noise [rad] of a log with heading samples at their own times.

    * Headings at most :data:`MAX_PLAIN_SPACING_S` apart (median): the uniform estimator
      on runs of headings at consecutive rows (evenly spaced), else on consecutive heading
      samples (the motion between them is far below the noise).
    * Slower headings: the second differences of ``measured heading − wheel yaw`` (the
      wheels' yaw, nominal theta, at each sample's own time, removes the motion), less what
      the wheels add to them. For tick counts (``quantization`` [rev] > 0), the rounding
      of each wheel's cumulative count, 12 (c/t_r)² q² per second difference, times
      :data:`INTERPOLATED_ROUNDING_SHARE` for counts the recording gave at other instants
      (``DriveLog.tick_resolution``); else the white noise per step (``wheel_noise``
      [rev]), (m₁ + m₂) 2 (c/t_r)² σ² over m₁ + m₂ steps. An estimate that subtracts too
      much overweights the heading, and a heading weighted by an understated noise biases
      t_r and d further than an overstated one: the discount is the smallest that holds.

    ``None`` for fewer than 100 usable samples."""
    rows = np.flatnonzero(log.heading_measured)
    if len(rows) < 3:
        return None
    times = log.t[rows] if log.fix_lag is None else (log.t - log.fix_lag)[rows]
    psi = log.psi[rows]
    masked = None if log.masked is None else np.asarray(log.masked)[rows]
    if float(np.median(np.diff(times))) <= MAX_PLAIN_SPACING_S:
        # Second differences need even spacing (uneven, a steady yaw rate leaks in: 0.4° at
        # 0.3 rad/s over 25 and 50 ms): runs of headings at consecutive rows, if enough.
        runs = rows[:-2][rows[2:] - rows[:-2] == 2]
        if len(runs) >= 100:
            second = log.psi[runs] - 2.0 * log.psi[runs + 1] + log.psi[runs + 2]
            if log.masked is not None:
                bad = np.asarray(log.masked)
                second = second[~(bad[runs] | bad[runs + 1] | bad[runs + 2])]
            if len(second) >= 100:
                return max(1.4826 * _mad(second) / np.sqrt(6.0), float(MIN_HEADING_SIGMA))
        return _uniform_heading_noise(psi, masked, check_wide=False)
    yaw_per_rev = nominal[0] / nominal[2]
    step_yaw = (log.n_rr[:-1] - log.n_rl[:-1]) * yaw_per_rev
    wheel_yaw = np.concatenate([[0.0], np.cumsum(step_yaw)])
    at_fix = wheel_yaw[rows]
    fraction = log.fix_fraction
    if fraction is not None:  # back to the sample's own time within the step before
        before = np.maximum(rows - 1, 0)
        at_fix = at_fix - (1.0 - fraction[rows]) * step_yaw[before]
    second = np.diff(psi - at_fix, 2)
    if masked is not None:
        second = second[~(masked[:-2] | masked[1:-1] | masked[2:])]
    if len(second) < 100:
        return None
    if quantization > 0:
        share = INTERPOLATED_ROUNDING_SHARE if log.tick_resolution is not None else 1.0
        from_wheels = 12.0 * share * quantization**2
    else:
        steps = float(np.median(rows[2:] - rows[:-2]))
        from_wheels = 2.0 * steps * wheel_noise**2
    variance = max((1.4826 * _mad(second)) ** 2 - yaw_per_rev**2 * from_wheels, 0.0) / 6.0
    return max(float(np.sqrt(variance)), float(MIN_HEADING_SIGMA))


#: Wheel-rate samples an estimate needs at least.
MIN_WHEEL_RATE_SAMPLES = 100
#: Wheel-rate samples further apart than this many median intervals are a gap: no second
#: difference spans one.
GAP_INTERVALS = 3.0


def rate_wheel_noise(
    t: np.ndarray, left: np.ndarray, right: np.ndarray, step: float
) -> float | None:
    """White noise [rev] per drive-log step of ``step`` [s] that wheel rates [rev/s] sampled
    at times ``t`` [s] carry, or ``None`` (fewer than :data:`MIN_WHEEL_RATE_SAMPLES` usable
    samples, or rates interpolated or held from a slower signal: not white per sample).

    A rate's white noise σ_r [rev/s] is ``1.4826 · MAD / √6`` of its second differences
    (the motion moves them far less at a wheel stream's rates, evenly spaced or not); a
    log step integrates ``step / Δt`` samples of it, so its rotation errs by
    ``σ_r · √(Δt · step)`` with ``Δt = mean(dt²) / mean(dt)`` (the median interval for even
    samples; CAN frames arrive unevenly): over many steps the same random walk as the
    samples' own, whatever ``step`` is. Differences touching an exact 0 (a wheel at rest:
    sensors report 0, not noise) or spanning a gap are left out; the two wheels' variances
    are averaged."""
    t = np.asarray(t, float)
    if len(t) < MIN_WHEEL_RATE_SAMPLES + 4:
        return None
    dt = np.diff(t)
    spacing = float(np.median(dt))
    if not spacing > 0:
        return None
    joined = dt <= GAP_INTERVALS * spacing
    spacing = float(np.mean(dt[joined] ** 2) / np.mean(dt[joined]))
    variances = []
    for rates in (np.asarray(left, float), np.asarray(right, float)):
        moving = rates != 0.0
        usable = joined[:-1] & joined[1:] & moving[:-2] & moving[1:-1] & moving[2:]
        second = (rates[2:] - 2.0 * rates[1:-1] + rates[:-2])[usable]
        if len(second) < MIN_WHEEL_RATE_SAMPLES:
            return None
        wide_usable = usable[1:-1] & usable[:-2] & usable[2:]
        wide = (rates[4:] - 2.0 * rates[2:-2] + rates[:-4])[wide_usable]
        if len(wide) < MIN_WHEEL_RATE_SAMPLES or _mad(wide) > MAX_WIDE_RATIO * _mad(second):
            return None  # interpolated, held or smoothed: not white per sample
        variances.append((1.4826 * _mad(second)) ** 2 / 6.0)
    return float(np.sqrt(np.mean(variances) * spacing * step))


#: Fix triples a position-noise estimate needs at least.
MIN_FIX_TRIPLES = 100
#: A fix triple counts only where the wheels' odometry moves its second difference by less
#: than this share of the fixes' median one: there the noise, not the motion, makes it.
MOTION_SHARE = 0.5
#: A fix triple counts only where its longer interval is at most this many times its shorter
#: one (a fix left out between them, a 50 Hz receiver's on a 40 Hz log, is still a triple).
MAX_INTERVAL_RATIO = 2.5


def position_noise(log: DriveLog, nominal: np.ndarray) -> float | None:
    """White noise σ [m] per axis of the measured positions, from the second differences of
    consecutive usable fixes (not masked, not flagged) of one run, less the motion the
    wheels' odometry (``nominal`` theta) puts in them, or ``None`` for fewer than
    :data:`MIN_FIX_TRIPLES` triples.

    Fixes need not be evenly spaced (a 50 Hz receiver on a 40 Hz log, a 0.5 Hz one whose
    fixes arrive ±25 ms about their grid): a triple at times ``t0 < t1 < t2`` is combined as
    ``h2 p0 − (h1 + h2) p1 + h1 p2`` (``h1 = t1 − t0``, ``h2 = t2 − t1``: zero for any motion
    at constant velocity), scaled to the ``6 σ²`` per axis of ``[1, −2, 1]``; triples whose
    two intervals differ more than :data:`MAX_INTERVAL_RATIO` times, or either spans a gap,
    are left out.

    Without a heading the motion's direction in the fixes' frame is unknown, its size is not:
    ``|Δ²p|² − |Δ²q|²`` (``q`` the odometry's positions at the fixes' times) has median about
    ``12 ln 2 · σ²`` (the squared norm of a 2-D Gaussian of ``6 σ²`` per axis). Triples whose
    motion is at least :data:`MOTION_SHARE` of the fixes' median second difference are left
    out. Only the white part shows: an error the fixes share over seconds barely moves a
    second difference (the solve's residuals judge it); so does tick rounding of the wheels,
    which this subtracts as motion — both make the estimate low, never high. The import's
    checks use :func:`graphcal.log.turns.fix_noise` instead, which keeps the motion in and so
    errs high, the safe side for a chord's length; a weight that errs high at 1 Hz (a car's
    2 m/s² is 2 m of second difference) would loosen fixes that are right."""
    usable = log.position_measured.copy()
    for flags in (log.masked, log.outlying):
        if flags is not None:
            usable &= ~np.asarray(flags)
    rows = np.flatnonzero(usable)
    if len(rows) < MIN_FIX_TRIPLES + 2:
        return None
    times = log.t[rows] if log.fix_lag is None else (log.t - log.fix_lag)[rows]
    v, omega = step_increments(log.inputs[:-1], nominal)
    course = np.concatenate([[0.0], np.cumsum(omega)])[:-1] + 0.5 * omega
    odometry = [
        np.interp(times, log.t, np.concatenate([[0.0], np.cumsum(v * f(course))]))
        for f in (np.cos, np.sin)
    ]
    spacing = np.diff(times)
    before, after = spacing[:-1], spacing[1:]
    gap = GAP_INTERVALS * float(np.median(spacing))
    kept = (before > 0) & (after > 0) & (before <= gap) & (after <= gap)
    kept &= np.maximum(before, after) <= MAX_INTERVAL_RATIO * np.minimum(before, after)
    if log.run is not None:
        run = np.asarray(log.run)[rows]
        kept &= run[:-2] == run[2:]
    before, after = before[kept], after[kept]
    # h2 p0 − (h1 + h2) p1 + h1 p2, scaled so that its coefficients' squares sum to 6
    scale = np.sqrt(6.0 / (after**2 + (before + after) ** 2 + before**2))
    coefficients = scale * np.stack([after, -(before + after), before])

    def second(values: np.ndarray) -> np.ndarray:
        triples = np.stack([values[:-2], values[1:-1], values[2:]])[:, kept]
        return np.sum(coefficients * triples, axis=0)

    fix_second = np.hypot(second(log.px[rows]), second(log.py[rows]))
    motion = np.hypot(second(odometry[0]), second(odometry[1]))
    if len(fix_second) < MIN_FIX_TRIPLES:
        return None
    quiet = motion < MOTION_SHARE * float(np.median(fix_second))
    if quiet.sum() < MIN_FIX_TRIPLES:
        return None
    excess = np.median(fix_second[quiet] ** 2 - motion[quiet] ** 2)
    return float(np.sqrt(max(excess, 0.0) / (12.0 * np.log(2.0))))
