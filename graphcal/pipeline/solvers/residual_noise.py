"""The noise a solve's residuals show, per kind of measurement: variance components.

A real recording's noise is rarely what a profile says, and rarely white: a u-blox
receiver's fixes at 10 Hz err alike for about a second, a fused pose's for many. After the
whole-log solve (:mod:`graphcal.pipeline.methods.whole_log`) the fixes' position residuals, the
headings' and the wheel corrections' priors say how noisy each kind of measurement was
(:func:`residual_noise`); the fixes are then weighted by :func:`honest_sigma`, their RMS
inflated by how much their errors are alike (:func:`error_correlation`): n fixes whose
errors are alike carry the information of fewer independent ones.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from graphcal.graph.solution.estimates import SolvedGraph
from graphcal.log.segments import SegmentData

#: Fixes a position-noise estimate needs at least (a variance from n of them is good to
#: about √(2/n) of itself per axis: 18 % from 30 fixes' 60 coordinates). At 100, a delivery
#: robot's 120 m with 78 fixes at 0.5 Hz, 0.36 m noisy, stayed weighted as its profile's
#: RTK 0.05 m: χ²/dof 26, "not trusted".
MIN_NOISE_FIXES = 30
#: Fewer fixes than :data:`MIN_NOISE_FIXES` but at least this many still show how noisy
#: they are at least (their RMS, :attr:`ResidualNoise.few_fixes`), not whether their errors
#: are alike from fix to fix.
MIN_FEW_FIXES = 10
#: The fixes count as correlated (weighted by :func:`honest_sigma`)
#: when their residuals' variance of a mean exceeds white noise's by this factor (white
#: simulated fixes: 1.00–1.02; a real u-blox receiver at 10 Hz: 3.0; a fused pose at 20 Hz:
#: 45, its errors alike for seconds).
CORRELATED_ERRORS = 1.5
#: Largest lag [fixes] :func:`error_correlation` sums over.
MAX_CORRELATION_LAG = 400
#: Longest lag [s] of the fixes' error variogram (:func:`error_variogram`).
MAX_VARIOGRAM_LAG = 120.0
#: The variogram's drift is fitted over this many fix intervals (:func:`drift_fit`), at least
#: MIN_DRIFT_LAG and at most MAX_DRIFT_LAG [s]: beyond a few seconds a fit's trajectory bends
#: with a slow error (the wheels' noise, a segment's heading bias) and hides it. A 4 km
#: drive's fixes with 1 m of error over 30 s showed their residuals' variogram flat beyond
#: 6 s, its slope below 1 s the error's own (0.034 m²/s; 1/30 true).
DRIFT_LAGS = 4
MIN_DRIFT_LAG = 1.0
MAX_DRIFT_LAG = 8.0
#: Time [s] over which the track's chord gives a sample's direction of travel
#: (:func:`travel_directions`).
TRAVEL_SPAN = 2.0
#: Speed [m/s] from which a fix's residual is read along the direction of travel alone
#: (:func:`travel_directions`): across it the wheels' corrections turn the trajectory
#: towards slow errors, the more the faster it goes (a car at 25 m/s: 0.08 m of 0.93 m left
#: across), while a robot's slow track gives its direction only from its noisy fixes.
ALONG_TRACK_SPEED = 3.0


@dataclass(frozen=True)
class ResidualNoise:
    """The noise the residuals of a solve show, per kind of measurement (SI).

    Attributes:
        position: RMS per axis [m] of the position residuals of the fixes that kept full
            weight, along the direction of travel where the track is fast
            (:func:`travel_directions`), and
            ``position_correlation`` their :func:`error_correlation`. Across it the wheels'
            corrections turn the trajectory towards the fixes: a car's 0.5 Hz fixes of
            0.93 m on 16-tick wheels left residuals of 0.68 m along, 0.08 m across (pooled,
            0.50 m: "not trusted").
        heading: RMS [rad] of the heading residuals, and ``heading_correlation`` theirs.
        position_white, position_drift: the fixes' white sigma [m] per axis and the rate
            [m²/s] at which an error they share drifts, from their residuals' variogram
            (:func:`drift_fit`), or ``None``; ``fix_interval`` [s] the fixes' interval;
            ``position_variogram`` their variogram ``(lags [s], γ [m²])`` up to
            :data:`MAX_DRIFT_LAG` (:func:`travel_variogram`).
        wheel_chi2: χ² per row of the wheel-rotation corrections' priors (about 1 or less
            when the wheels are as noisy as assumed: the data determine the corrections only
            in part; well above 1, the wheels are noisier).
        Each is ``None`` for fewer than :data:`MIN_NOISE_FIXES` measurements of its kind
        (the heading's for fewer than :data:`MIN_FEW_FIXES`).
        few_fixes: ``(count, RMS per axis [m])`` of the fixes when they are fewer than
            :data:`MIN_NOISE_FIXES` but at least :data:`MIN_FEW_FIXES` (``position`` is then
            ``None``), else ``None``.
        unfinished: the solve stopped creeping under weights far too tight
            (``SolveStatus.MISWEIGHTED``): its residuals carry its unfinished fit.
    """

    position: float | None = None
    position_correlation: float | None = None
    heading: float | None = None
    heading_correlation: float | None = None
    position_white: float | None = None
    position_drift: float | None = None
    fix_interval: float | None = None
    position_variogram: tuple[np.ndarray, np.ndarray] | None = field(default=None, compare=False)
    wheel_chi2: float | None = None
    few_fixes: tuple[int, float] | None = None
    unfinished: bool = False


def residual_noise(
    solved: SolvedGraph, data: SegmentData, weights: np.ndarray | None
) -> ResidualNoise:
    """:class:`ResidualNoise` of ``solved`` over ``data`` with the fix ``weights`` (the
    robust ones, or ``None``)."""
    residuals = solved.built.pose_residuals(solved.result, solved.partitioned)
    used = data.position_fixes()
    if weights is not None:
        used &= weights >= 1.0
    headings = data.headings_measured()
    out: dict = {"unfinished": solved.outcome.crept}
    tied = solved.built.spec.tied(data)  # the graph's trajectories
    directions, fast = travel_directions(data)
    for name, rows, columns in (
        ("position", used, slice(0, 2)),
        ("heading", headings, slice(2, 3)),
    ):
        count = int(rows.sum())
        if count < MIN_FEW_FIXES:
            continue
        part = residuals[..., columns]
        if name == "position":
            rms = _position_rms(part, rows, directions, fast) * fitted_start_correction(rows, tied)
        else:
            rms = float(np.sqrt(np.mean(part[rows] ** 2)))
        # A heading's RMS is only ever raised to (with_noise_levels): from a few, too.
        if count >= MIN_NOISE_FIXES or name == "heading":
            out[name] = rms
            out[f"{name}_correlation"] = error_correlation(part, rows)
        else:
            out["few_fixes"] = (count, rms)
    if "position" in out and data.sample_index is not None:
        lags, gamma, pairs = travel_variogram(
            residuals[..., :2], used, data, tied, (directions, fast)
        )
        fitted = drift_fit(lags, gamma, pairs)
        if fitted is not None:
            out["position_white"], out["position_drift"], out["fix_interval"] = fitted
            short = lags <= MAX_DRIFT_LAG
            out["position_variogram"] = (lags[short], gamma[short])
    chi2, rows = solved.built.correction_chi2(solved.result, solved.partitioned)
    if rows >= MIN_NOISE_FIXES:
        out["wheel_chi2"] = chi2 / rows
    return ResidualNoise(**out)


def fitted_start_correction(used: np.ndarray, tied: np.ndarray) -> float:
    """The factor that makes the RMS of fix residuals an unbiased noise estimate: each
    trajectory (a chain of ``tied (S,)`` segments) has its start pose fitted to its ``used
    (S, K+1)`` fixes, 3 unknowns taken from their 2 coordinates each (all of them from one
    fix), so the residuals' variance is the noise's times ``1 − 3 / (2 n)`` over a trajectory
    of n fixes: ``√(2 N / (2 N − U))`` over N fixes whose trajectories take U unknowns from
    them (1 where none are left over). 0.5 Hz fixes of 1.18 m on 150 m segments of a town
    car (9 per segment) read 0.90–1.08 m without it, and c_e's mean (e/σ)² over 12 noise
    draws was 2.15."""
    chain = np.cumsum(~np.asarray(tied, bool)) - 1
    per_chain = np.bincount(chain, weights=used.sum(axis=1))
    coordinates = 2.0 * per_chain.sum()
    unknowns = np.minimum(3.0, 2.0 * per_chain).sum()
    if coordinates <= unknowns:
        return 1.0
    return float(np.sqrt(coordinates / (coordinates - unknowns)))


def error_correlation(residuals: np.ndarray, used: np.ndarray) -> float:
    """``1 + 2 Σ_k ρ_k``: the autocorrelation ρ_k (:func:`error_autocorrelation`) summed over
    lags k ≥ 1 as Geyer's initial positive sequence (pairs of lags while their sum stays
    positive; at most :data:`MAX_CORRELATION_LAG`). The variance of a mean of n consecutive
    errors is that factor times a white error's over n; at least 1."""
    rho = error_autocorrelation(residuals, used)
    if rho is None:
        return 1.0
    pairs = rho[: len(rho) // 2 * 2].reshape(-1, 2).sum(axis=1)  # (ρ0 + ρ1), (ρ2 + ρ3), ...
    positive = np.flatnonzero(pairs <= 0)
    kept = pairs[: positive[0]] if len(positive) else pairs
    return float(max(1.0, 2.0 * kept.sum() - 1.0))


def error_autocorrelation(residuals: np.ndarray, used: np.ndarray) -> np.ndarray | None:
    """The autocorrelation ``ρ_k`` (``ρ_0 = 1``, lags up to :data:`MAX_CORRELATION_LAG`) of
    the residuals ``(S, K+1, C)`` of the ``used`` ``(S, K+1)`` measurements, from one to the
    next within each segment (all C components, pooled over the segments); ``None`` for
    fewer than 3 in every segment or no variance."""
    counts = used.sum(axis=1)
    longest = int(counts.max())
    if longest < 3:
        return None
    sequences = np.zeros((len(used), longest, residuals.shape[-1]))
    rows, cols = np.nonzero(used)
    order = np.cumsum(used, axis=1)[rows, cols] - 1  # each fix's place in its segment
    sequences[rows, order] = residuals[rows, cols]
    size = 1 << int(np.ceil(np.log2(2 * longest)))
    spectrum = np.fft.rfft(sequences, n=size, axis=1)
    covariance = np.fft.irfft(np.abs(spectrum) ** 2, n=size, axis=1)[:, :longest].sum(axis=(0, 2))
    if covariance[0] <= 0:
        return None
    return covariance[: min(longest, MAX_CORRELATION_LAG + 1)] / covariance[0]


def honest_sigma(rms: float | None, correlation: float | None) -> float | None:
    """The sigma that weighs measurements honestly from their residuals' ``rms``: times
    ``√correlation`` when their errors are correlated (:data:`CORRELATED_ERRORS`), since n
    of them then carry the information of n / that factor independent ones."""
    if rms is None:
        return None
    factor = correlation or 1.0
    return rms * (float(np.sqrt(factor)) if factor >= CORRELATED_ERRORS else 1.0)


def travel_directions(
    data: SegmentData, span_s: float = TRAVEL_SPAN
) -> tuple[np.ndarray, np.ndarray]:
    """``(S, K+1, 2)`` unit vectors along each sample's direction of travel, the track's
    chord over ±``span_s`` / 2 [s] within its segment, and ``(S, K+1)`` whether the track
    moves there at :data:`ALONG_TRACK_SPEED` or faster (elsewhere the direction is the
    measured heading's, or the chord's, and not used)."""
    steps = max(1, round(span_s / (2.0 * data.dt)))
    index = np.arange(data.poses.shape[1])
    last = np.asarray(data.n_steps)[:, None]
    ahead = np.minimum(index[None, :] + steps, last)
    behind = np.clip(index[None, :] - steps, 0, None) + np.zeros_like(ahead)
    rows = np.arange(len(data))[:, None]
    chord = data.poses[rows, ahead, :2] - data.poses[rows, behind, :2]
    norm = np.hypot(chord[..., 0], chord[..., 1])
    heading = data.poses[..., 2]
    fallback = np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    moving = norm > 1e-9
    unit = np.where(moving[..., None], chord / np.where(moving, norm, 1.0)[..., None], fallback)
    fast = norm >= ALONG_TRACK_SPEED * (ahead - behind) * data.dt
    return unit, fast


def _position_rms(
    residuals: np.ndarray, used: np.ndarray, directions: np.ndarray, fast: np.ndarray
) -> float:
    """RMS per axis [m] of the ``used`` position ``residuals (S, K+1, 2)``: at ``fast``
    samples their component along the ``directions`` alone, elsewhere both."""
    along = np.einsum("skc,skc->sk", directions, residuals)
    squares = np.where(fast, along**2, (residuals**2).sum(axis=-1))
    values = np.where(fast, 1.0, 2.0)
    return float(np.sqrt(squares[used].sum() / values[used].sum()))


def travel_variogram(
    residuals: np.ndarray,
    used: np.ndarray,
    data: SegmentData,
    tied: np.ndarray | None = None,
    travel: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`error_variogram` of the position ``residuals (S, K+1, 2)``: of their
    differences' component along the direction of travel from samples the track passes at
    :data:`ALONG_TRACK_SPEED` or faster (``travel``: :func:`travel_directions`' directions
    and fast samples, computed if not given), of both components from the others, pooled
    (``pairs`` counts components)."""
    directions, fast = travel_directions(data) if travel is None else travel
    steps, weighted, counted = [], [], []
    for (lags, gamma, pairs), width in (
        (error_variogram(residuals, used & fast, data, tied, directions=directions), 1.0),
        (error_variogram(residuals, used & ~fast, data, tied), 2.0),
    ):
        steps.append(np.rint(lags / data.dt).astype(int))
        weighted.append(gamma * pairs * width)
        counted.append(pairs * width)
    step = np.concatenate(steps)
    if not len(step):
        return np.zeros(0), np.zeros(0), np.zeros(0)
    found = np.unique(step)
    total = np.bincount(step, np.concatenate(counted))[found]
    gamma = np.bincount(step, np.concatenate(weighted))[found] / total
    return found * data.dt, gamma, total


def error_variogram(
    residuals: np.ndarray,
    used: np.ndarray,
    data: SegmentData,
    tied: np.ndarray | None = None,
    directions: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The residuals' variogram ``γ(L) = ½ E[(r(t + L) − r(t))²]`` per component, pooled
    over the C components of ``residuals (S, K+1, C)`` at the ``used (S, K+1)`` samples,
    along each chain of ``tied (S,)`` segments (one trajectory; default
    :meth:`SegmentData.tied`) on the log's sample grid, for lags ``L`` of 1 sample to
    :data:`MAX_VARIOGRAM_LAG`: ``(lags [s], γ [m²], pairs)``, lags without a pair left out.
    With ``directions (S, K+1, 2)`` (unit vectors; C = 2), the variogram of the differences'
    component along the direction at their start, ``u(t) · (r(t + L) − r(t))``, alone.

    A fit absorbs an error's slow part into the trajectory (its start, heading, scale), so
    the residuals' variance and autocorrelation show less of it than there is; their
    differences over short lags are what the fit leaves alone (:func:`drift_fit`) — along
    the direction of travel: across it, the wheels' corrections turn the trajectory with a
    slow error within seconds (a car at 25 m/s, 1 Hz fixes sharing 1.5 m over 40 s: the
    pooled components' rate read half the error's, c_e's mean (e/σ)² over 40 draws 4.6)."""
    heads = np.flatnonzero(~(data.tied() if tied is None else np.asarray(tied, bool)))
    stops = [*heads[1:], len(data)]
    index = data.sample_index
    starts = index[heads, 0]
    lengths = np.array(
        [
            int(index[stop - 1, data.n_steps[stop - 1]] - index[h, 0]) + 1
            for h, stop in zip(heads, stops, strict=True)
        ]
    )
    max_lag = min(int(lengths.max()) - 1, int(MAX_VARIOGRAM_LAG / data.dt))
    rows, cols = np.nonzero(used)
    if max_lag < 1 or not len(rows):
        return np.zeros(0), np.zeros(0), np.zeros(0)
    chain = np.repeat(np.arange(len(heads)), np.diff([*heads, len(data)]))
    at = index[rows, cols] - starts[chain[rows]]
    # Chains in groups by the transform each needs (a 200 km log's 207 chains of 30 to
    # 3,290 samples: each padded to the longest's 8,192 was 3.3 times the work)
    sizes = 1 << np.ceil(np.log2(lengths + np.minimum(lengths - 1, max_lag) + 1)).astype(int)
    pairs, total = np.zeros(max_lag + 1), np.zeros(max_lag + 1)
    for size in np.unique(sizes):
        group = sizes == size
        slot = np.cumsum(group) - 1  # each chain's row among its group's
        mine = group[chain[rows]]
        place = (slot[chain[rows[mine]]], at[mine])
        grid = np.zeros((int(group.sum()), int(lengths[group].max()), residuals.shape[-1]))
        mask = np.zeros(grid.shape[:2])
        grid[place] = residuals[rows[mine], cols[mine]]
        mask[place] = 1.0
        unit = None
        if directions is not None:
            unit = np.zeros(grid.shape)
            unit[place] = directions[rows[mine], cols[mine]]
        lag = min(max_lag, grid.shape[1] - 1)
        group_pairs, group_total = _lag_sums(grid, mask, unit, lag, int(size))
        pairs[: lag + 1] += group_pairs
        total[: lag + 1] += group_total
    width = residuals.shape[-1] if directions is None else 1
    lags = np.arange(max_lag + 1)
    keep = (lags > 0) & (pairs > 0)
    gamma = total[keep] / (2.0 * width * pairs[keep])
    return lags[keep] * data.dt, gamma, pairs[keep]


def _lag_sums(
    grid: np.ndarray, mask: np.ndarray, unit: np.ndarray | None, max_lag: int, size: int
) -> tuple[np.ndarray, np.ndarray]:
    """For lags 0 to ``max_lag``, summed over the chains of ``grid`` ``(chains, samples, C)``
    (the residuals on the chains' sample grid), ``mask`` (1 at a fix) and ``unit`` (the
    directions of travel, or ``None``): the pairs of fixes, and the sums of
    :func:`error_variogram`'s squared differences (with ``unit``, along the direction);
    transforms of ``size`` (at least samples + ``max_lag`` + 1)."""

    def spectrum(a: np.ndarray) -> np.ndarray:
        return np.fft.rfft(a, n=size, axis=1)

    def correlate(fa: np.ndarray, fb: np.ndarray) -> np.ndarray:
        """``Σ_t a(t) b(t + L)`` for L = 0..max_lag from the spectra of a and b, summed
        over chains (and components)."""
        out = np.fft.irfft(np.conj(fa) * fb, n=size, axis=1)[:, : max_lag + 1]
        return out.sum(axis=tuple(i for i in range(out.ndim) if i != 1))

    f_mask = spectrum(mask)
    pairs = np.rint(correlate(f_mask, f_mask))
    if unit is None:
        f_squares, f_grid = spectrum((grid**2).sum(axis=2)), spectrum(grid)
        cross = correlate(f_grid, f_grid)  # summed over the components
        return pairs, correlate(f_squares, f_mask) + correlate(f_mask, f_squares) - 2.0 * cross
    return pairs, _directed_sums(grid, mask, unit, spectrum, correlate)


def _directed_sums(
    grid: np.ndarray,
    mask: np.ndarray,
    unit: np.ndarray,
    spectrum: Callable[[np.ndarray], np.ndarray],
    correlate: Callable[[np.ndarray, np.ndarray], np.ndarray],
) -> np.ndarray:
    """``Σ_t m(t) m(t + L) (u(t) · (r(t + L) − r(t)))²`` per lag L for :func:`error_variogram`
    (``grid``, ``mask``, ``unit``: the residuals, the fixes and the directions on its
    chains' grid): the square expanded into correlations of a function of t with one of
    t + L."""
    ux, uy = unit[..., 0] * mask, unit[..., 1] * mask
    rx, ry = grid[..., 0], grid[..., 1]
    along = ux * rx + uy * ry  # u(t) · r(t)
    f = spectrum
    ahead = (
        correlate(f(ux * ux), f(rx * rx))
        + 2.0 * correlate(f(ux * uy), f(rx * ry))
        + correlate(f(uy * uy), f(ry * ry))
    )  # (u(t) · r(t + L))²
    mixed = correlate(f(along * ux), f(rx)) + correlate(f(along * uy), f(ry))
    return ahead - 2.0 * mixed + correlate(f(along**2), f(mask))


def drift_fit(
    lags: np.ndarray, gamma: np.ndarray, pairs: np.ndarray
) -> tuple[float, float, float] | None:
    """``(white, rate, interval)``: white noise of sigma ``white`` [m] and an error that
    drifts at ``rate`` [m²/s] fitted to a variogram (:func:`error_variogram`) at lags short
    beside any drift the fit absorbs (:data:`DRIFT_LAGS` fix intervals, at least
    :data:`MIN_DRIFT_LAG`, at most :data:`MAX_DRIFT_LAG`), ``γ(L) = white² + rate · L``
    (a Gauss–Markov error of stationary sigma q and time τ has ``rate = q² / τ`` at lags
    short beside τ), least squares weighted by the pairs, and the shortest lag [s] (the
    fixes' interval); ``None`` for fewer than three lags."""
    if len(lags) == 0:
        return None
    window = min(max(DRIFT_LAGS * float(lags[0]), MIN_DRIFT_LAG), MAX_DRIFT_LAG)
    short = lags <= window
    if short.sum() < 3:
        return None
    weight = np.sqrt(pairs[short])
    design = np.stack([np.ones(short.sum()), lags[short]], axis=1) * weight[:, None]
    (white2, rate), *_ = np.linalg.lstsq(design, gamma[short] * weight, rcond=None)
    return float(np.sqrt(max(white2, 0.0))), float(max(rate, 0.0)), float(lags[0])
