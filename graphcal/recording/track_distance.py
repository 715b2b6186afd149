"""The wheels' distance over the GNSS track's, unbiased by the fixes' noise.

A chord between two noisy fixes is too long on average: ``E|chord|² = L² + N`` with ``N``
the noise of the difference of two fixes (``4σ²`` for white noise of σ per axis, less for
noise correlated over longer than the chord). Over chords of a few metres — a robot's, or
fixes close together — ``N`` is as large as ``L²``, and a sum of chords reads the wheels as
travelling half the track's distance. Here the fixes are averaged in blocks of
:data:`BLOCK_S` (white noise shrinks with the fixes in a block) and every two neighbouring
blocks in which the wheels roll straight on give a pair: wheel distance ``w`` and chord
``g`` between the blocks' means. ``g² = w² / r² + N`` is fitted over the pairs: ``r``, the
wheels' distance over the track's, from the slope, ``N`` from the intercept, whatever the
noise's size or correlation.
"""

from __future__ import annotations

import numpy as np

#: Duration [s] of a block of fixes (one fix, for fixes this far apart or farther).
BLOCK_S = 1.0
#: Blocks from one end of a pair to the other (neighbours: longer spans take turns in and
#: gain less than they lose; measured on the skid-steer robot's own simulation at 2–50 Hz).
SPAN_BLOCKS = 1
#: Largest yaw [rad] the wheels (nominal θ) show within a pair for it to count as straight:
#: its chord is then its arc within 0.4 % (1 − sinc of the yaw), 2.3 % for an effective track
#: 2.5× the nominal one (a skid-steer robot's).
STRAIGHT_YAW = 0.3
#: Share of a pair's rolling that must be in one direction (a robot reversing inside it
#: rolls along a chord shorter than its distance).
ONE_WAY = 0.95
#: Least wheel distance of a pair [revolutions of the nominal c_e] (a standstill's chord is
#: all noise, and a fused pose may hold still there).
MIN_WINDOW_REVS = 0.5
#: Pairs needed for the fit, and the spread of their ``w²`` (coefficient of variation) below
#: which the intercept is not fitted (pairs all alike: long ones, whose ``N`` is small beside
#: ``w²``, or no way to tell ``N`` from the slope).
MIN_WINDOWS = 8
MIN_SPREAD = 0.2
#: Chord noise below this share of the pairs' mean w² does not matter: a fit of it below 0
#: whose upper bound (2 standard errors) stays under that says none.
NEGLIGIBLE_NOISE = 0.1
#: Residuals beyond this many robust σ (an outlying fix) leave the fit, once.
TRIM_SIGMAS = 4.0


def wheel_track_ratio(
    c: dict[str, np.ndarray],
    fixed: np.ndarray,
    usable: np.ndarray,
    nominal: np.ndarray,
) -> tuple[float, float, bool] | None:
    """``(ratio, σ, at_least)``: the wheels' distance (nominal θ) over the GNSS track's, the
    standard error of its logarithm (from the fit's residuals), and whether the ratio is
    only a lower bound — where the pairs are too alike to fit the fixes' noise out
    (:data:`MIN_SPREAD`), a chord's noise can only have lengthened it (a skid-steer robot's
    5 Hz fixes of 1.4 m: chord² 1.5 m² against wheel distance² 0.36 m², "the wheels travel
    0.49x", campaign seed 30's shape 83); ``None`` with fewer than :data:`MIN_WINDOWS`
    straight pairs of blocks.

    Args:
        c: drive-log columns on the grid (``t`` [s], ``px``, ``py`` [m], ``n_rl``, ``n_rr``
            [rev]).
        fixed: rows holding a fix (``px``, ``py`` measured there).
        usable: rows not masked.
        nominal: θ whose ``c_e`` and ``t_r`` turn the rotations into distance and yaw.
    """
    rows = np.flatnonzero(fixed & np.isfinite(c["px"]) & np.isfinite(c["py"]))
    if len(rows) < 2:
        return None
    block = np.floor((c["t"][rows] - c["t"][rows[0]]) / BLOCK_S).astype(int)
    first = np.flatnonzero(np.diff(block, prepend=-1))  # each block's first fix
    if len(first) < 2 * MIN_WINDOWS:
        return None
    size = np.diff(np.append(first, len(rows)))
    step = 0.5 * (c["n_rl"] + c["n_rr"]) * nominal[0]
    yaw = (c["n_rr"] - c["n_rl"]) * nominal[0] / nominal[2]
    rolled, rolled_abs, heading = (
        np.concatenate([[0.0], np.cumsum(v[:-1])]) for v in (step, np.abs(step), yaw)
    )
    x, y, r = (np.add.reduceat(v[rows], first) / size for v in (c["px"], c["py"], rolled))
    # Pairs of blocks (j, j + k), k = SPAN_BLOCKS, one after the other (j = 0, k, 2k, ...),
    # each over the grid rows from the first fix of one to the last fix of the other.
    k = SPAN_BLOCKS
    pair = np.arange(0, len(first) - k, k)
    pair = pair[rows[first[pair + k] + size[pair + k] - 1] + 1 < len(c["t"])]  # reduceat's
    start = rows[first[pair]]
    stop = rows[first[pair + k] + size[pair + k] - 1] + 1
    bounds = np.column_stack([start, stop]).reshape(-1)
    span = slice(None, None, 2)
    turned = (np.maximum.reduceat(heading, bounds) - np.minimum.reduceat(heading, bounds))[span]
    clean = (np.add.reduceat((~usable).astype(int), bounds) == 0)[span]
    w = np.abs(r[pair + k] - r[pair])
    one_way = np.abs(rolled[stop - 1] - rolled[start]) >= ONE_WAY * (
        rolled_abs[stop - 1] - rolled_abs[start]
    )
    chord2 = (x[pair + k] - x[pair]) ** 2 + (y[pair + k] - y[pair]) ** 2
    keep = clean & one_way & (turned <= STRAIGHT_YAW) & (w >= MIN_WINDOW_REVS * nominal[0])
    if keep.sum() < MIN_WINDOWS:
        return None
    w2, g2 = w[keep] ** 2, chord2[keep]
    fit = _fit(w2, g2)
    residual = g2 - fit[0] * w2 - fit[1]
    spread = 1.4826 * np.median(np.abs(residual - np.median(residual)))
    inside = np.abs(residual - np.median(residual)) <= TRIM_SIGMAS * max(spread, 1e-12)
    if inside.sum() >= MIN_WINDOWS:
        w2, g2 = w2[inside], g2[inside]
        fit = _fit(w2, g2)
    slope, _, sigma, noise_fitted = fit
    if slope <= 0:
        return None
    return float(1.0 / np.sqrt(slope)), float(0.5 * sigma / slope), not noise_fitted


def _fit(w2: np.ndarray, g2: np.ndarray) -> tuple[float, float, float, bool]:
    """``(a, N, σ_a, fitted)`` of ``g² = a w² + N`` by least squares, ``N ≥ 0`` (noise adds
    to chords); ``N = 0`` where the ``w²`` are too alike to tell it from ``a``
    (:data:`MIN_SPREAD`) or fitted below 0 without ruling out noise that matters
    (:data:`NEGLIGIBLE_NOISE`; ``fitted`` false: ``a`` then is an upper bound). ``σ_a`` is the
    sandwich (heteroscedasticity-consistent) standard error: the scatter of a chord² grows
    with its length."""
    fitted = bool(np.std(w2) >= MIN_SPREAD * np.mean(w2))
    if fitted:
        a, noise = np.polyfit(w2, g2, 1)
        lever = w2 - w2.mean()
        if noise >= 0:
            return float(a), float(noise), _sandwich(lever, g2 - a * w2 - noise, 2), True
        # Fitted below 0: none, if the fit rules out noise that matters beside the chords;
        # else noise the pairs could not tell apart, and a an upper bound (a skid-steer
        # robot's 10 Hz fixes of 1.9 m, 31 pairs of 0.75 m: N fitted below 0, the wheels
        # read as travelling 0.553x the track, refused).
        residual = g2 - a * w2 - noise
        spread = np.sqrt(np.sum(residual**2) / max(len(w2) - 2, 1))
        error = spread * np.sqrt(1.0 / len(w2) + w2.mean() ** 2 / np.sum(lever**2))
        fitted = noise + 2.0 * error < NEGLIGIBLE_NOISE * np.mean(w2)
    # through the origin: N too alike to tell from a (not fitted), or fitted below 0
    a = float(np.sum(w2 * g2) / np.sum(w2 * w2))
    return a, 0.0, _sandwich(w2, g2 - a * w2, 1), bool(fitted)


def _sandwich(lever: np.ndarray, residual: np.ndarray, parameters: int) -> float:
    """HC1 standard error of a slope whose regressor (centred, if an intercept was fitted)
    is ``lever``."""
    n = len(residual)
    scale = n / max(n - parameters, 1)
    return float(np.sqrt(scale * np.sum(lever**2 * residual**2)) / np.sum(lever**2))
