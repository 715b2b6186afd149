"""The noise a solve's residuals show, per kind of measurement: variance components.

A real recording's noise is rarely what a profile says, and rarely white: a u-blox
receiver's fixes at 10 Hz err alike for about a second, a fused pose's for many. After the
whole-log solve (:mod:`graphcal.pipeline.whole_log`) the fixes' position residuals, the
headings' and the wheel corrections' priors say how noisy each kind of measurement was
(:func:`residual_noise`); the fixes are then weighted by :func:`honest_sigma`, their RMS
inflated by how much their errors are alike (:func:`error_correlation`): n fixes whose
errors are alike carry the information of fewer independent ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.graph.estimates import SolvedGraph
from graphcal.log.segments import SegmentData

#: Fixes a position-noise estimate needs at least.
MIN_NOISE_FIXES = 100
#: The fixes count as correlated (weighted by :func:`honest_sigma`)
#: when their residuals' variance of a mean exceeds white noise's by this factor (white
#: simulated fixes: 1.00–1.02; a real u-blox receiver at 10 Hz: 3.0; a fused pose at 20 Hz:
#: 45, its errors alike for seconds).
CORRELATED_ERRORS = 1.5
#: Largest lag [fixes] :func:`error_correlation` sums over.
MAX_CORRELATION_LAG = 400


@dataclass(frozen=True)
class ResidualNoise:
    """The noise the residuals of a solve show, per kind of measurement (SI).

    Attributes:
        position: RMS per axis [m] of the position residuals of the fixes that kept full
            weight, and ``position_correlation`` their :func:`error_correlation`.
        heading: RMS [rad] of the heading residuals, and ``heading_correlation`` theirs.
        wheel_chi2: χ² per row of the wheel-rotation corrections' priors (about 1 or less
            when the wheels are as noisy as assumed: the data determine the corrections only
            in part; well above 1, the wheels are noisier).
        Each is ``None`` for fewer than :data:`MIN_NOISE_FIXES` measurements of its kind.
    """

    position: float | None = None
    position_correlation: float | None = None
    heading: float | None = None
    heading_correlation: float | None = None
    wheel_chi2: float | None = None


def residual_noise(
    solved: SolvedGraph, data: SegmentData, weights: np.ndarray | None
) -> ResidualNoise:
    """:class:`ResidualNoise` of ``solved`` over ``data`` with the fix ``weights`` (the
    robust ones, or ``None``)."""
    residuals = solved.built.pose_residuals(solved.result, solved.partitioned)
    used = data.position_fixes()
    if weights is not None:
        used &= weights >= 1.0
    headings = data.valid.copy()
    if data.measured is not None:
        headings &= data.measured[..., 1]
    out = {}
    for name, rows, columns in (
        ("position", used, slice(0, 2)),
        ("heading", headings, slice(2, 3)),
    ):
        if rows.sum() >= MIN_NOISE_FIXES:
            part = residuals[..., columns]
            out[name] = float(np.sqrt(np.mean(part[rows] ** 2)))
            out[f"{name}_correlation"] = error_correlation(part, rows)
    chi2, rows = solved.built.correction_chi2(solved.result, solved.partitioned)
    if rows >= MIN_NOISE_FIXES:
        out["wheel_chi2"] = chi2 / rows
    return ResidualNoise(**out)


def error_correlation(residuals: np.ndarray, used: np.ndarray) -> float:
    """``1 + 2 Σ_k ρ_k``: the autocorrelation ρ_k of the residuals ``(S, K+1, C)`` of the
    ``used`` ``(S, K+1)`` measurements, from one to the next within each segment (all C
    components, pooled over the segments), summed over lags k ≥ 1 as Geyer's initial
    positive sequence (pairs of lags while their sum stays positive; at most
    :data:`MAX_CORRELATION_LAG`). The variance
    of a mean of n consecutive errors is that factor times a white error's over n; at least
    1."""
    counts = used.sum(axis=1)
    longest = int(counts.max())
    if longest < 3:
        return 1.0
    sequences = np.zeros((len(used), longest, residuals.shape[-1]))
    rows, cols = np.nonzero(used)
    order = np.cumsum(used, axis=1)[rows, cols] - 1  # each fix's place in its segment
    sequences[rows, order] = residuals[rows, cols]
    size = 1 << int(np.ceil(np.log2(2 * longest)))
    spectrum = np.fft.rfft(sequences, n=size, axis=1)
    covariance = np.fft.irfft(np.abs(spectrum) ** 2, n=size, axis=1)[:, :longest].sum(axis=(0, 2))
    if covariance[0] <= 0:
        return 1.0
    rho = covariance[: min(longest, MAX_CORRELATION_LAG + 1)] / covariance[0]
    pairs = rho[: len(rho) // 2 * 2].reshape(-1, 2).sum(axis=1)  # (ρ0 + ρ1), (ρ2 + ρ3), ...
    positive = np.flatnonzero(pairs <= 0)
    kept = pairs[: positive[0]] if len(positive) else pairs
    return float(max(1.0, 2.0 * kept.sum() - 1.0))


def honest_sigma(rms: float | None, correlation: float | None) -> float | None:
    """The sigma that weighs measurements honestly from their residuals' ``rms``: times
    ``√correlation`` when their errors are correlated (:data:`CORRELATED_ERRORS`), since n
    of them then carry the information of n / that factor independent ones."""
    if rms is None:
        return None
    factor = correlation or 1.0
    return rms * (float(np.sqrt(factor)) if factor >= CORRELATED_ERRORS else 1.0)
