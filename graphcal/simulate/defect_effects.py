"""How each defect of :mod:`graphcal.simulate.defects` acts on a synthetic drive's signals.

:func:`defective_wheels` and :func:`defective_pose` rebuild the measured rear-wheel rotations
and pose of a :class:`~graphcal.simulate.drive.SyntheticDrive` from its noise-free truth, its
own white noise and the defects, in the order of :mod:`graphcal.simulate.defects`' docstring,
each defect drawing from its own random stream; :func:`ar1` and :func:`gauss_markov` are the
correlated noise processes of the slip and the heading bias.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from graphcal.recording.stream_grid import fixes_on_grid

if TYPE_CHECKING:
    from graphcal.simulate.defect_settings import Defects
    from graphcal.simulate.drive import SyntheticDrive

#: Samples of one chunk of the exact AR(1) recursion (:func:`ar1`).
_AR1_CHUNK = 256
#: Nothing of an outage within this long [s] of the drive's start and end, nor between two.
_OUTAGE_MARGIN_S = 1.0
_OUTAGE_SPACING_S = 5.0
#: At most this share of the drive's time in outages.
_MAX_OUTAGE_SHARE = 0.4


def ar1(
    n: int, phi: float, innovation: float, start: float, rng: np.random.Generator, width: int
) -> np.ndarray:
    """``width`` independent AR(1) series of ``n`` samples, ``(n, width)``, exactly.

    ``x_0 ~ N(0, start²)``, ``x_k = phi·x_{k−1} + w_k`` with ``w_k ~ N(0, innovation²)``.
    Vectorized: within chunks of :data:`_AR1_CHUNK` samples the recursion is a product with
    the lower-triangular matrix ``phi^(i−j)`` (no negative powers, so stable for any
    ``0 <= phi <= 1``, a random walk included); only the carry from one chunk to the next is a
    loop, over chunks, not samples.
    """
    size = _AR1_CHUNK
    chunks = max(1, -(-n // size))
    w = rng.standard_normal((chunks * size, width))
    w[0] *= start
    w[1:] *= innovation
    w[n:] = 0.0
    i = np.arange(size)
    lag = i[:, None] - i[None, :]
    powers = np.where(lag >= 0, float(phi) ** np.maximum(lag, 0), 0.0)
    # local[c, i] = sum_{j <= i} phi^(i-j) w[c, j], per chunk c and series.
    local = np.einsum("ij,cjw->ciw", powers, w.reshape(chunks, size, width))
    ends = np.empty((chunks, width))
    carry = np.zeros(width)
    for c in range(chunks):  # the end of each chunk carries into the next
        carry = float(phi) ** size * carry + local[c, -1]
        ends[c] = carry
    previous = np.vstack([np.zeros((1, width)), ends[:-1]])
    x = local + (float(phi) ** (i + 1))[None, :, None] * previous[:, None, :]
    return x.reshape(chunks * size, width)[:n]


def gauss_markov(
    n: int, dt: float, sigma: float, time: float | None, rng: np.random.Generator, width: int = 1
) -> np.ndarray:
    """First-order Gauss–Markov series ``(n, width)`` sampled every ``dt`` [s], started in its
    stationary state: correlation time ``time`` [s], stationary σ ``sigma``; with ``time``
    ``None``, a random walk of rate ``sigma`` [unit/√s] starting at 0."""
    if time is None:
        return ar1(n, 1.0, sigma * np.sqrt(dt), 0.0, rng, width)
    phi = float(np.exp(-dt / time))
    return ar1(n, phi, sigma * np.sqrt(1.0 - phi**2), sigma, rng, width)


def _delayed(cumulative: np.ndarray, times: np.ndarray, delay: float) -> np.ndarray:
    """Cumulative signals ``(M, k)`` read at ``times − delay``: linear between the samples
    (the rate is constant within each step) and extended at the first/last rate outside."""
    query = times - delay
    out = np.empty_like(cumulative)
    for col in range(cumulative.shape[1]):
        c = cumulative[:, col]
        inside = np.interp(query, times, c)
        first = (c[1] - c[0]) / (times[1] - times[0])
        last = (c[-1] - c[-2]) / (times[-1] - times[-2])
        inside = np.where(query < times[0], c[0] + first * (query - times[0]), inside)
        out[:, col] = np.where(query > times[-1], c[-1] + last * (query - times[-1]), inside)
    return out


def defective_wheels(
    drive: SyntheticDrive, defects: Defects, rngs: dict[str, np.random.Generator]
) -> np.ndarray:
    """Measured rear-wheel rotations ``(N, 2)`` [rev per sample]: truth → slip → latency →
    quantization → the drive's own white noise."""
    truth, clean = drive.truth, drive.measured
    true = np.column_stack([truth.n_rl, truth.n_rr])
    n, dt = true, truth.dt
    if defects.slip_sigma > 0:
        slip = gauss_markov(len(n), dt, defects.slip_sigma, defects.slip_time, rngs["slip"], 2)
        n = n * (1.0 + slip)
    if defects.latency != 0 or defects.ticks_per_revolution > 0:
        # Cumulative rotation at t_0 … t_N (t_N one interval after the last sample).
        cumulative = np.vstack([np.zeros((1, 2)), np.cumsum(n, axis=0)])
        times = np.append(truth.t, truth.t[-1] + dt)
        if defects.latency != 0:
            cumulative = _delayed(cumulative, times, defects.latency)
        if defects.ticks_per_revolution > 0:
            ticks = defects.ticks_per_revolution
            phase = rngs["ticks"].uniform(0.0, 1.0, 2)
            cumulative = np.floor(cumulative * ticks + phase) / ticks
        n = np.diff(cumulative, axis=0)
    # The drive's own white noise on top: measured = clean + (defective − true rotation).
    return np.column_stack([clean.n_rl, clean.n_rr]) + (n - true)


def _outage_starts(t0: float, t_end: float, defects: Defects, rng: np.random.Generator):
    """Start times [s] of the outages: random, apart, within the drive (``ValueError`` if the
    drive is too short for them)."""
    count, duration = int(defects.outages), defects.outage_s
    span = t_end - t0
    free = span - 2 * _OUTAGE_MARGIN_S - count * duration - (count - 1) * _OUTAGE_SPACING_S
    if count * duration > _MAX_OUTAGE_SHARE * span or free < 0:
        raise ValueError(
            f"a drive of {span:.0f} s is too short for {count} outage(s) of {duration:g} s "
            f"(at most {_MAX_OUTAGE_SHARE:.0%} of its time); use a longer drive or fewer outages"
        )
    u = np.sort(rng.uniform(0.0, free, count))
    return t0 + _OUTAGE_MARGIN_S + u + np.arange(count) * (duration + _OUTAGE_SPACING_S)


def defective_pose(
    drive: SyntheticDrive, defects: Defects, rngs: dict[str, np.random.Generator]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, tuple[str, ...], dict]:
    """Measured ``px, py, psi``, the masked samples (dropouts), their notes and, for sparse
    fixes, the log's ``measured`` and ``fix_lag`` (else an empty dict)."""
    t = drive.truth.t
    psi = _heading(drive, defects, rngs["heading"])
    t_fix, fix = _fixes(drive, defects, rngs["gnss"])
    _add_outliers(fix, defects, rngs["outliers"])

    # Outages: fixes repeated (receiver holding its last fix) or missing (dropout).
    masked, notes = None, ()
    heading_gone = np.zeros(len(t), dtype=bool)  # a dropout's samples: no heading either
    if defects.outages > 0:
        starts = _outage_starts(t[0], t[-1], defects, rngs["outages"])
        which = np.searchsorted(starts, t_fix, side="right") - 1
        out = (which >= 0) & (t_fix < starts[np.maximum(which, 0)] + defects.outage_s)
        if defects.outage_hold:
            last = np.maximum.accumulate(np.where(out, 0, np.arange(len(t_fix))))
            fix = fix[last]
        else:
            t_fix, fix = t_fix[~out], fix[~out]
            before = np.searchsorted(t_fix, starts) - 1  # last fix before each dropout
            gap_a, gap_b = t_fix[before], t_fix[before + 1]
            masked, heading_gone = _dropout_samples(t, gap_a, gap_b)
            notes = tuple(
                f"t = {a:.1f}–{b:.1f} s: no pose (simulated dropout)"
                for a, b in zip(gap_a, gap_b, strict=True)
            )
            psi = np.where(heading_gone, np.interp(t, t[~heading_gone], psi[~heading_gone]), psi)
    px, py, sparse = _fixes_at_log_rate(t, t_fix, fix, defects, heading_gone)
    return px, py, psi, masked, notes, sparse


def _heading(drive: SyntheticDrive, defects: Defects, rng: np.random.Generator) -> np.ndarray:
    """Measured heading [rad]: truth + slow bias + white (the drive's own unless replaced)."""
    truth = drive.truth
    count = len(truth.t)
    psi = drive.measured.psi  # truth + the drive's own white noise
    if defects.heading_white is not None:
        psi = truth.psi + defects.heading_white * rng.standard_normal(count)
    if defects.heading_bias_rate > 0:
        time = defects.heading_bias_time
        sigma = defects.heading_bias_rate * (1.0 if time is None else np.sqrt(time / 2.0))
        psi = psi + gauss_markov(count, truth.dt, sigma, time, rng)[:, 0]
    return psi


def _fixes(
    drive: SyntheticDrive, defects: Defects, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """GNSS fixes of the antenna: their times [s] (the log's own ``t`` when every sample is a
    fix) and east, north [m] ``(n, 2)``: true antenna position + white noise."""
    truth, clean = drive.truth, drive.measured
    t = truth.t
    if defects.gnss_rate is None:  # every sample a fix, with the drive's own noise
        t_fix = t
        fix = np.column_stack([clean.px, clean.py])
        yaw = truth.psi
    else:
        period = 1.0 / defects.gnss_rate
        t_fix = t[0] + rng.uniform(0.0, period) + np.arange(0.0, t[-1] - t[0], period)
        t_fix = t_fix[t_fix <= t[-1]]
        if len(t_fix) < 2:
            raise ValueError(f"the drive is too short for fixes at {defects.gnss_rate:g} Hz")
        cg = np.column_stack([np.interp(t_fix, t, truth.px), np.interp(t_fix, t, truth.py)])
        yaw = np.interp(t_fix, t, truth.psi)
        fix = cg + drive.noise.position * rng.standard_normal((len(t_fix), 2))
    if defects.lever_arm is not None:
        along, across = defects.lever_arm
        c, s = np.cos(yaw), np.sin(yaw)
        fix = fix + np.column_stack([c * along - s * across, s * along + c * across])
    return t_fix, fix


def _add_outliers(fix: np.ndarray, defects: Defects, rng: np.random.Generator) -> None:
    """Move a share of the fixes ``(n, 2)`` [m] by multipath, in place."""
    n_fix = len(fix)
    chosen = rng.permutation(n_fix)[: round(defects.outlier_share * n_fix)]
    distance = rng.uniform(*defects.outlier_range, len(chosen))
    direction = rng.uniform(0.0, 2.0 * np.pi, len(chosen))
    fix[chosen] += distance[:, None] * np.column_stack([np.cos(direction), np.sin(direction)])


def _dropout_samples(
    t: np.ndarray, gap_a: np.ndarray, gap_b: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The log samples a dropout masks (from the last sample at or before the fix before it
    to the first at or after the fix after it) and those strictly inside its gap."""
    count = len(t)
    inside = np.zeros(count, dtype=bool)
    masked = np.zeros(count, dtype=bool)
    for a, b in zip(gap_a, gap_b, strict=True):  # one per outage, not per sample
        first = np.searchsorted(t, a, side="right") - 1
        last_sample = min(count - 1, np.searchsorted(t, b, side="left"))
        masked[first : last_sample + 1] = True
        inside[(t > a) & (t < b)] = True
    return masked, inside


def _fixes_at_log_rate(
    t: np.ndarray, t_fix: np.ndarray, fix: np.ndarray, defects: Defects, heading_gone: np.ndarray
) -> tuple[np.ndarray, np.ndarray, dict]:
    """The fixes at the log's times ``t``: as they are (a fix per sample), held, interpolated
    or each once at its own time (then with the log's ``measured`` and ``fix_lag``)."""
    count = len(t)
    sparse: dict = {}
    if t_fix is t:
        px, py = fix[:, 0], fix[:, 1]
    elif defects.gnss_hold:
        held = np.clip(np.searchsorted(t_fix, t, side="right") - 1, 0, len(t_fix) - 1)
        px, py = fix[held, 0], fix[held, 1]
    else:
        px, py = np.interp(t, t_fix, fix[:, 0]), np.interp(t, t_fix, fix[:, 1])
        if not defects.gnss_interpolate:  # each fix once, at its own time
            kept, rows, lag, _ = fixes_on_grid(t_fix, t)
            fix, t_fix = fix[kept], t_fix[kept]
            measured = np.zeros((count, 2), dtype=bool)
            measured[rows, 0] = True
            measured[:, 1] = True
            measured[rows[lag > 0], 1] = False  # a row's measurements share its fix's time
            measured[heading_gone, 1] = False
            px[rows], py[rows] = fix[:, 0], fix[:, 1]
            full_lag = np.zeros(count)
            full_lag[rows] = lag
            sparse = {"measured": measured, "fix_lag": full_lag if (lag > 0).any() else None}
    return px, py, sparse
