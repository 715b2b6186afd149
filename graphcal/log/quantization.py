"""Wheel rotations counted in encoder ticks: the resolution read from the log itself.

An encoder with ``T`` ticks per revolution reports each interval's rotation as a whole number
of ticks, ``n = m / T`` (plus, at most, a little noise of its own). Its rounding error
(``1 / (T √12)`` rev on the cumulative count) dwarfs the white noise of a smooth wheel-speed
signal, and it is not white per interval: the joint solve models it
(``[joint] tick_quantization``, :func:`graphcal.factors.chunk_correction_prior`). Logs rarely
say their encoder's resolution, so :func:`ticks_per_revolution` finds it: the smallest ``T``
for which the rotations in ticks, ``n T``, lie close to whole numbers — the resultant along
whole counts ``mean(cos(2π n T))``, 1 for exact counts and about ``1/√N`` for a continuous
signal — if they sit on its grid closer than a continuous signal's would by chance, whatever
a few samples off the grid say, and whether the counts dither or stay the same through a
cruise.
"""

from __future__ import annotations

import math

import numpy as np

#: Resolutions tried [ticks/rev] (wheel encoders and ABS tone rings: tens to a few thousand).
TICK_RANGE = (4, 4096)
#: Rotations the search looks at (evenly spaced through the log).
SAMPLES = 2000
#: Chance, at most, that the rotations of a continuous signal sit as close to the grid of the
#: resolution found as they do, over every resolution tried (step 4).
MAX_CHANCE = 1e-3
#: Closeness to the grid [ticks] below which a recorded rotation's own precision (its float
#: or CSV digits) makes chance no smaller.
GRID_PRECISION_TICKS = 1e-4
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

    1. The resultant ``R(T) = mean(cos(2π n T))`` of every candidate ``T`` on
       :data:`SAMPLES` positive rotations; the best ``T``, every ``T`` of :data:`TICK_RANGE`
       tried (a continuous signal in a narrow range may fit a small ``T``; step 4 refuses
       it, its values fill the tick). ``R`` is a mean of cosines, so one sample moves it by
       at most ``2/N`` whatever its size: a reset or wrap (one huge
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
    4. The rotations sit on the grid beyond chance (:func:`_on_grid_beyond_chance`): at
       most :data:`MAX_OFF_GRID` of them farther from it than a tolerance ``ε`` [ticks], and
       so many of their distinct values within ``ε`` of it that a continuous signal's would
       be there by chance at most :data:`MAX_CHANCE`, over every resolution tried. Counts
       that stay the same through a cruise are evidence too (17 ticks over and over sit on
       the grid to 10⁻¹² tick); a continuous signal's values fill the tick, and one that
       dwells at a simple fraction of a revolution per interval is one value on the grid
       among the many its other speeds take.
    """
    n = np.asarray(rotations, float).reshape(-1)
    n = n[np.isfinite(n) & (n > 0)]
    if len(n) < 200:
        return None
    n = n[np.linspace(0, len(n) - 1, min(SAMPLES, len(n))).astype(int)]
    candidates = np.arange(TICK_RANGE[0], TICK_RANGE[1] + 1)
    resultant = _resultants(n, candidates)
    best = int(candidates[np.argmax(resultant)])
    best = _refined(n, best, candidates)
    if resultant[best - candidates[0]] < MIN_RESULTANT:
        return None
    ticks = _smallest_fitting(n, best)
    if not _on_grid_beyond_chance(np.asarray(rotations, float), ticks, len(candidates)):
        return None
    return ticks


def _on_grid_beyond_chance(rotations: np.ndarray, ticks: int, tried: int) -> bool:
    """Whether the positive rotations [rev] sit on the grid of ``ticks`` per revolution
    closer than a continuous signal's would by chance, ``tried`` resolutions searched (step 4
    of :func:`ticks_per_revolution`).

    The tolerance ``ε`` [ticks] is the distance to the grid that all but
    :data:`MAX_OFF_GRID` of the rotations keep (at least :data:`GRID_PRECISION_TICKS`).
    Chance is judged on the distinct values at a resolution of ``ε/2``, not on samples: a
    continuous signal that dwells at one speed gives one value however long it dwells, and
    each of its values lands within ``ε`` of the grid with probability ``p = 2.5 ε`` (the
    share of such values in a tick). A dwell's noise scatters it over a few such values
    about one level, so where the values scatter (``ε`` above its floor) the grid levels
    occupied must be beyond chance too, ``p^L`` for ``L`` levels (a 1 km highway cruise's
    speeds, 1/3 rev per interval ± 0.0006, made 6 ticks "found" from one level); exact
    repeats of one count are a counter's where the intervals around them read none
    (:func:`_beside_standstills`: a 16-tick counter on a slow robot, 0 or 1 tick per
    interval). ``k`` of ``K`` values on the grid have chance at most
    ``exp(−K D(k/K ‖ p))`` (Chernoff; ``p^K`` when all are), times ``tried``."""
    # Each column's first interval may difference a reading from another epoch (a log
    # started mid-count): one value off the grid per wheel, which in a cruise of two counts
    # (a 1 km straight on 1849-tick wheels) halved the share on it, at chance 1.5·10⁻³.
    n = rotations.reshape(len(rotations), -1)[1:].reshape(-1)
    ticked = n[np.isfinite(n) & (n > 0)] * ticks
    if not len(ticked):
        return False
    off = np.abs(ticked - np.round(ticked))
    tolerance = max(float(np.quantile(off, 1.0 - MAX_OFF_GRID)), GRID_PRECISION_TICKS)
    values = np.unique(np.round(ticked / (0.5 * tolerance))) * (0.5 * tolerance)
    share = float(np.mean(np.abs(values - np.round(values)) <= tolerance))
    levels = len(np.unique(np.round(ticked[off <= tolerance])))  # grid levels occupied
    chance = 2.5 * tolerance
    scattered = tolerance > GRID_PRECISION_TICKS  # exact repeats are a counter's, not a dwell's
    if levels == 1 and not scattered and _beside_standstills(rotations):
        return True  # one count, and none in the intervals around it: a slow counter's
    if scattered and levels * math.log(chance) + math.log(tried) > math.log(MAX_CHANCE):
        return False  # too few levels: a dwell's scatter about one level is one value
    if share <= chance or chance >= 1.0:
        return False
    divergence = share * math.log(share / chance)
    if share < 1.0:
        divergence += (1.0 - share) * math.log((1.0 - share) / (1.0 - chance))
    return -len(values) * divergence + math.log(tried) <= math.log(MAX_CHANCE)


#: Positive rotations next to an interval of none that make a single count a counter's: a
#: share of them, and a number.
BESIDE_NONE_SHARE = 0.1
BESIDE_NONE_COUNT = 100


def _beside_standstills(rotations: np.ndarray) -> bool:
    """Whether many positive rotations ``(N, ...)`` lie next to an interval of exactly none
    (in the same column): a counter too coarse for the speed reads 0 or 1 tick in turn (a
    skid-steer robot's 16-tick wheels at 40 Hz: every positive rotation one tick, 10,269 of
    them), while a continuous signal reads exact zeros only at a standstill, whose ends are
    a few of its samples. One count alone sits on the grids of all its divisors' multiples
    by chance no less than a dwell's one value does: this is the evidence."""
    columns = np.asarray(rotations, float).reshape(len(rotations), -1)
    positive = np.isfinite(columns) & (columns > 0)
    none = columns == 0.0
    beside = np.zeros_like(none)
    beside[1:] |= none[:-1]
    beside[:-1] |= none[1:]
    count = int((positive & beside).sum())
    return count >= BESIDE_NONE_COUNT and count >= BESIDE_NONE_SHARE * int(positive.sum())


def _residuals(n: np.ndarray, ticks: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit phasors ``exp(2πi n T)`` and the residuals [ticks, −½…½] from whole counts (a
    counter's rotations are differences of whole readings: its grid has no offset, so values
    of one fraction of a tick, e.g. a divisor's, are off it)."""
    phasors = np.exp(2j * np.pi * n * ticks)
    return phasors, np.angle(phasors) / (2 * np.pi)


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
        fit, fit_k = np.real(z), np.real(zk)
        gain = fit_k - fit
        if gain.mean() <= MULTIPLE_Z * gain.std() / math.sqrt(len(gain)) + 1e-9:
            return int(ticks)
    return best


def _resultants(n: np.ndarray, candidates: np.ndarray, block: int = 256) -> np.ndarray:
    """``mean(cos(2π n T))``, the resultant along whole counts, for every ``T`` of
    ``candidates`` (consecutive integers); values bunched at one fraction of a tick (a narrow
    range of a continuous signal, or a divisor's grid) do not fit.

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
        out[start : start + size] = np.real(rows.mean(axis=1))
    return out


def quantization_sigma(ticks: int) -> float:
    """Rounding error sigma [rev] of a cumulative count in ``ticks`` per revolution."""
    return 1.0 / (ticks * math.sqrt(12.0))
