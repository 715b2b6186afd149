"""Distributions the truth-free tests read their thresholds from (no SciPy)."""

from __future__ import annotations

import math


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
