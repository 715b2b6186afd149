"""Wheel rotations counted in encoder ticks: the resolution read from the log itself.

An encoder with ``T`` ticks per revolution reports each interval's rotation as a whole number
of ticks, ``n = m / T`` (plus, at most, a little noise of its own). Its rounding error
(``1 / (T √12)`` rev on the cumulative count) dwarfs the white noise of a smooth wheel-speed
signal, and it is not white per interval: the joint solve models it
(``[joint] tick_quantization``, :func:`graphcal.factors.chunk_correction_prior`). Logs rarely
say their encoder's resolution, so :func:`ticks_per_revolution` finds it: the smallest ``T``
for which the rotations in ticks, ``n T``, lie close to whole numbers — the mean resultant
length ``|mean(exp(2πi n T))|``, 1 for exact counts and about ``1/√N`` for a continuous
signal — if they do so at every speed, whatever a few samples off the tick grid say.
"""

from __future__ import annotations

import math

import numpy as np

#: Resolutions tried [ticks/rev] (wheel encoders and ABS tone rings: tens to a few thousand).
TICK_RANGE = (4, 4096)
#: Rotations the search looks at (evenly spaced through the log).
SAMPLES = 2000
#: Only resolutions that spread the rotations over at least this many ticks (standard
#: deviation of the rotations inside their 1st–99th percentiles, so that one huge interval
#: does not count) are tried: a continuous signal in a narrower range has a high resultant too.
MIN_SPREAD_TICKS = 2.0
#: Share of intervals whose count differs from the previous one's, at least, for a counter
#: (measured 0.36–0.52 on counted drives, 0.008–0.02 on continuous ones).
MIN_COUNT_CHANGES = 0.15
#: Robust σ [ticks] of the second differences of the counts, at least, for a counter (about
#: 1.3 for rounded counts; a continuous signal's, at the found resolution, is far smaller).
MIN_DITHER_TICKS = 0.5
#: The best resolution must put the counts this close to whole numbers (mean resultant
#: length; ``exp(−2π² (σ T)²)`` for white noise σ on top of the counts: 0.5 at σ = 0.19 tick).
MIN_RESULTANT = 0.5
#: A sample farther than this [ticks] from a resolution's grid is off that grid (halfway to
#: the half-tick grid of twice the resolution).
OFF_GRID_TICKS = 0.25
#: Share of samples off the grid (glitches, a first reading from another epoch, a counter
#: reset) a resolution may leave and still be preferred to its multiples. Were a multiple
#: ``k T`` the resolution, a share ``1 − 1/k`` or so of its counts, ≥ 40 %, would be off
#: ``T``'s grid.
MAX_OFF_GRID = 0.05
#: Standard errors by which a multiple must fit the on-grid samples better than the
#: resolution to be taken instead of it.
MULTIPLE_Z = 3.0


def ticks_per_revolution(rotations: np.ndarray) -> int | None:
    """The encoder resolution [ticks/rev] of rotations ``(N, ...)`` [rev per interval], or
    ``None`` if they are not counts of one tick size.

    1. The resultant ``R(T) = |mean(exp(2πi n T))|`` of every candidate ``T`` on
       :data:`SAMPLES` positive rotations; the best ``T``. ``R`` is a mean of unit vectors,
       so one sample moves it by at most ``2/N`` whatever its size: a reset or wrap (one huge
       or negative interval; negative ones are left out anyway) or a glitch cannot move it
       far, but it can decide between candidates that fit the counts equally well.
    2. Robust refinement: the samples more than :data:`OFF_GRID_TICKS` from the best ``T``'s
       grid are trimmed and the best ``T`` is chosen again among its neighbours ``T ± 2`` on
       the rest (a neighbour ``T ± j`` fits worse by only ``2π² j² var(n)``, ``n`` in rev:
       under 1 % for a car at 100 Hz, a margin a few percent of off-grid samples could
       cross). The best ``T`` must reach :data:`MIN_RESULTANT`.
    3. The smallest resolution that fits. Every multiple ``k T`` of the resolution ``T``
       puts the counts on its grid too: ``R(kT) = R(T) = 1`` for exact counts, and with
       white noise σ on the counts ``R(kT) = exp(−2π² (σ k T)²) = R(T)^(k²) ≤ R(T)``. A
       multiple can fit better only through samples off ``T``'s grid (each moves
       ``R(kT) − R(T)`` by up to ``2/N``: the first sample off the grid made the old
       largest-within-10⁻⁹ rule pick 1056 = 11 × 96). So a divisor ``T`` of the best ``kT``
       is taken instead if (a) at most :data:`MAX_OFF_GRID` of the samples are off its grid
       — were ``kT`` the resolution, about half of them would be — and (b) on the samples on
       its grid, ``R(kT) − R(T)`` is at most :data:`MULTIPLE_Z` standard errors of the
       per-sample differences (of ``cos`` of the residual phases) above zero, where white
       noise would put it below.
       Divisors are tried even where they spread the rotations over fewer than
       :data:`MIN_SPREAD_TICKS` (a 64-tick car at 100 Hz, 0–20 m/s, 1.4 ticks): that bound
       keeps a continuous signal's narrow range from fitting a small ``T``, but a divisor is
       only tried for a best ``kT`` that fits, and only taken if it fits the same samples.
    4. The counts change between intervals and dither as rounded counts do
       (:data:`MIN_DITHER_TICKS`).
    """
    n = np.asarray(rotations, float).reshape(-1)
    n = n[np.isfinite(n) & (n > 0)]
    if len(n) < 200:
        return None
    n = n[np.linspace(0, len(n) - 1, min(SAMPLES, len(n))).astype(int)]
    candidates = np.arange(TICK_RANGE[0], TICK_RANGE[1] + 1)
    spread = np.std(np.clip(n, *np.percentile(n, [1.0, 99.0])))
    candidates = candidates[candidates * spread >= MIN_SPREAD_TICKS]
    if not len(candidates):
        return None
    resultant = _resultants(n, candidates)
    best = int(candidates[np.argmax(resultant)])
    best = _refined(n, best, candidates)
    if resultant[best - candidates[0]] < MIN_RESULTANT:
        return None
    ticks = _smallest_fitting(n, best)
    # A counter's rotation jumps between neighbouring counts from one interval to the next
    # even at a steady speed; a continuous signal that dwells at one speed (a cruise) can
    # look like whole counts there, but its rounded count hardly ever changes.
    first = np.asarray(rotations, float)[..., 0].reshape(-1)
    counts = np.round(first * ticks)
    if np.mean(np.diff(counts) != 0) < MIN_COUNT_CHANGES:
        return None
    # Rounding a cumulative count makes each interval's count dither: its second difference
    # is e_k+3 − 3 e_k+2 + 3 e_k+1 − e_k in ticks (e uniform in ±½: σ = 1.29 ticks). A
    # continuous signal that only looks counted — a cruise at a speed near a simple fraction
    # of a revolution per interval — is smooth from one interval to the next.
    second = np.diff(first[np.isfinite(first)], 2) * ticks
    if len(second) and 1.4826 * np.median(np.abs(second - np.median(second))) < MIN_DITHER_TICKS:
        return None
    return ticks


def _residuals(n: np.ndarray, ticks: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit phasors ``exp(2πi n T)`` and the residuals [ticks, −½…½] from their mean phase."""
    phasors = np.exp(2j * np.pi * n * ticks)
    mean = phasors.mean()
    centred = phasors * (np.conj(mean) / abs(mean) if abs(mean) > 0 else 1.0)
    return phasors, np.angle(centred) / (2 * np.pi)


def _refined(n: np.ndarray, best: int, candidates: np.ndarray, reach: int = 2) -> int:
    """The best of ``best`` and its neighbours on the samples on ``best``'s grid."""
    _, residual = _residuals(n, best)
    on_grid = n[np.abs(residual) < OFF_GRID_TICKS]
    near = candidates[np.abs(candidates - best) <= reach]
    if len(on_grid) < len(n) / 2 or len(near) < 2:
        return best
    return int(near[np.argmax(_resultants(on_grid, near))])


def _smallest_fitting(n: np.ndarray, best: int) -> int:
    """The smallest divisor ``T`` of ``best`` in :data:`TICK_RANGE` that fits nearly as well
    (step 3 of :func:`ticks_per_revolution`), else ``best``."""
    divisors = np.arange(TICK_RANGE[0], best)
    for ticks in divisors[best % divisors == 0]:
        phasors, residual = _residuals(n, int(ticks))
        on_grid = np.abs(residual) < OFF_GRID_TICKS
        if np.mean(~on_grid) > MAX_OFF_GRID:
            continue
        z = phasors[on_grid]
        zk = z ** (best // int(ticks))
        # Per-sample cos of the residual phase, whose mean is each one's resultant.
        fit = np.real(z * np.conj(z.mean())) / max(abs(z.mean()), 1e-300)
        fit_k = np.real(zk * np.conj(zk.mean())) / max(abs(zk.mean()), 1e-300)
        gain = fit_k - fit
        if gain.mean() <= MULTIPLE_Z * gain.std() / math.sqrt(len(gain)) + 1e-9:
            return int(ticks)
    return best


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
