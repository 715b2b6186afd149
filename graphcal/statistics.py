"""Distributions the truth-free tests read their thresholds from (no SciPy)."""

from __future__ import annotations

import math
from statistics import NormalDist


def chi2_survival(x: float, dof: int) -> float:
    """P(χ²_dof > x) for an integer ``dof`` ≥ 1 (closed form; no SciPy)."""
    if x <= 0:
        return 1.0
    half = 0.5 * x
    if dof % 2 == 0:
        term, total = 1.0, 1.0
        for i in range(1, dof // 2):
            term *= half / i
            total += term
        return math.exp(-half) * total
    total = math.erfc(math.sqrt(half))
    term = math.sqrt(half) * math.exp(-half) / math.gamma(1.5)
    for i in range(1, (dof + 1) // 2):
        total += term
        term *= half / (i + 0.5)
    return min(1.0, total)


def chi2_quantile(probability: float, dof: int) -> float:
    """The χ² value below which ``probability`` of the distribution with ``dof`` degrees of
    freedom lies (bisection on :func:`chi2_survival`)."""
    low, high = 0.0, 10.0 * dof + 100.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        if chi2_survival(middle, dof) > 1.0 - probability:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def scaled_chi2_deviate(x: float, mean: float, sd: float) -> float:
    """The standard normal deviate of ``x`` under the scaled χ² ``g·χ²_h`` with this
    ``mean`` and ``sd`` (Satterthwaite: ``g = sd²/(2 mean)``, ``h = 2 mean²/sd²``), by the
    Wilson–Hilferty cube root: a weighted sum of χ²₁ terms (a quadratic form of Gaussian
    noise) is skewed, and with few terms its upper tail is far heavier than a normal one of
    the same mean and sd. Tends to ``(x − mean)/sd`` as ``h`` grows."""
    if sd <= 0.0 or mean <= 0.0:
        return math.inf if x > mean else 0.0
    h = 2.0 * mean**2 / sd**2
    g = sd**2 / (2.0 * mean)
    v = 2.0 / (9.0 * h)
    return ((max(x, 0.0) / (g * h)) ** (1.0 / 3.0) - (1.0 - v)) / math.sqrt(v)


def student_t_quantile(probability: float, dof: float) -> float:
    """The value below which ``probability`` of Student's t distribution with ``dof``
    (≥ 1, not necessarily whole) degrees of freedom lies: the Cornish–Fisher expansion in
    ``1/dof`` about the normal quantile (Abramowitz and Stegun 26.7.5), within 1 % for
    ``dof`` ≥ 2 at the quantiles tests use (t₂ at 0.97725: 4.49 for 4.53); below 2, between
    the closed forms of t₁ and t₂."""
    z = NormalDist().inv_cdf(probability)
    if not math.isfinite(dof):
        return z
    if dof < 2.0:  # between t₁ (Cauchy) and t₂, both in closed form, linear in 1/dof
        one = math.tan(math.pi * (probability - 0.5))
        two = (2 * probability - 1) / math.sqrt(2 * probability * (1 - probability))
        share = min(max(2.0 / float(dof) - 1.0, 0.0), 1.0)
        return two + share * (one - two)
    nu = float(dof)
    g1 = (z**3 + z) / 4.0
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96.0
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384.0
    g4 = (79 * z**9 + 776 * z**7 + 1482 * z**5 - 1920 * z**3 - 945 * z) / 92160.0
    return z + g1 / nu + g2 / nu**2 + g3 / nu**3 + g4 / nu**4
