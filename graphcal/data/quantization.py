"""Wheel rotations counted in encoder ticks: the resolution read from the log itself.

An encoder with ``T`` ticks per revolution reports each interval's rotation as a whole number
of ticks, ``n = m / T`` (plus, at most, a little noise of its own). Its rounding error
(``1 / (T √12)`` rev on the cumulative count) dwarfs the white noise of a smooth wheel-speed
signal, and it is not white per interval: the joint solve models it
(``[joint] tick_quantization``, :func:`graphcal.factors.chunk_correction_prior`). Logs rarely
say their encoder's resolution, so :func:`ticks_per_revolution` finds it: the ``T`` for which
the rotations in ticks, ``n T``, lie closest to whole numbers — the mean resultant length
``|mean(exp(2πi n T))|``, 1 for exact counts and about ``1/√N`` for a continuous signal —
if they do so at every speed.
"""

from __future__ import annotations

import math

import numpy as np

#: Resolutions tried [ticks/rev] (wheel encoders and ABS tone rings: tens to a few thousand).
TICK_RANGE = (4, 4096)
#: Rotations the search looks at (evenly spaced through the log).
SAMPLES = 2000
#: Only resolutions that spread the rotations over at least this many ticks (standard
#: deviation) are tried: a continuous signal in a narrower range has a high resultant too.
MIN_SPREAD_TICKS = 2.0
#: Share of intervals whose count differs from the previous one's, at least, for a counter
#: (measured 0.36–0.52 on counted drives, 0.008–0.02 on continuous ones).
MIN_COUNT_CHANGES = 0.15
#: The best resolution must put the counts this close to whole numbers (mean resultant
#: length; ``exp(−2π² (σ T)²)`` for white noise σ on top of the counts: 0.5 at σ = 0.19 tick).
MIN_RESULTANT = 0.5


def ticks_per_revolution(rotations: np.ndarray) -> int | None:
    """The encoder resolution [ticks/rev] of rotations ``(N, ...)`` [rev per interval], or
    ``None`` if they are not counts of one tick size."""
    n = np.asarray(rotations, float).reshape(-1)
    n = n[np.isfinite(n) & (n > 0)]
    if len(n) < 200:
        return None
    n = n[np.linspace(0, len(n) - 1, min(SAMPLES, len(n))).astype(int)]
    candidates = np.arange(TICK_RANGE[0], TICK_RANGE[1] + 1)
    candidates = candidates[candidates * np.std(n) >= MIN_SPREAD_TICKS]
    if not len(candidates):
        return None
    resultant = _resultants(n, candidates)
    # Multiples of the resolution fit exact counts as well as it does: take the smallest.
    best = int(np.argmax(resultant >= resultant.max() - 1e-9))
    if resultant[best] < MIN_RESULTANT:
        return None
    ticks = int(candidates[best])
    # A counter's rotation jumps between neighbouring counts from one interval to the next
    # even at a steady speed; a continuous signal that dwells at one speed (a cruise) can
    # look like whole counts there, but its rounded count hardly ever changes.
    counts = np.round(np.asarray(rotations, float)[..., 0].reshape(-1) * ticks)
    if np.mean(np.diff(counts) != 0) < MIN_COUNT_CHANGES:
        return None
    return ticks


def _resultants(n: np.ndarray, candidates: np.ndarray, block: int = 256) -> np.ndarray:
    """``|mean(exp(2πi n T))|`` for every ``T`` of ``candidates`` (consecutive integers).

    Per block of candidates, the first row is ``exp(2πi n T₀)`` and each next one the row
    before times ``exp(2πi n)`` (a running product instead of a sine and cosine per
    element: a tenth of the time; its rounding error after a block, ~10⁻¹⁴, is far below
    the resultants' differences)."""
    step = np.exp(2j * np.pi * n)
    out = np.empty(len(candidates))
    for start in range(0, len(candidates), block):
        size = min(block, len(candidates) - start)
        rows = np.empty((size, len(n)), complex)
        rows[0] = np.exp(2j * np.pi * n * candidates[start])
        rows[1:] = step
        np.cumprod(rows, axis=0, out=rows)
        out[start : start + size] = np.abs(rows.mean(axis=1))
    return out


def quantization_sigma(ticks: int) -> float:
    """Rounding error sigma [rev] of a cumulative count in ``ticks`` per revolution."""
    return 1.0 / (ticks * math.sqrt(12.0))
