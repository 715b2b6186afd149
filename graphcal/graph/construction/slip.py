"""Priors of slow wheel slip: relative scales ``[s_rl, s_rr]`` as a Gauss–Markov process.

A rear wheel's slow slip (a tyre's load in a long bend, a wet patch) scales its rotation,
``n_w (1 + s_w)``, for seconds. Per span of the drive (a chunk of a segment, or a few keyframe
intervals of a localization graph) one 2-vector of scales has the stationary prior
``N(0, sigma²)`` at the first span and a first-order Gauss–Markov step between consecutive
spans, ``s_j − φ s_(j−1) ~ N(0, sigma² (1 − φ²))`` with ``φ = exp(−duration / slip_time)``
(:mod:`graphcal.graph.construction.gauss_markov`), so that every span's scale has the stationary
sigma.

Where the process is too fine to resolve, coarser forms stand in for it: across a GNSS gap
one scale whose prior is the variance of the process's mean over the gap
(:func:`slip_mean_sigma`), and in the online smoother noise of each interval with the
process's long-run variance (:func:`slip_noise_covariance`), so that a run of intervals
carries the uncertainty of the correlated slip over its total.
"""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.graph.construction.gauss_markov import gauss_markov_step, stationary_prior


def slip_prior_factor(key: int, sigma: float) -> gtsam.PriorFactorVector:
    """The stationary prior ``N(0, sigma²)`` of the first span's scales (dimensionless)."""
    return stationary_prior(key, 2, sigma)


def slip_step_factor(
    previous_key: int, key: int, duration: float, sigma: float, slip_time: float
) -> gtsam.LinearContainerFactor:
    """The Gauss–Markov step from the span ``previous_key`` to the next one ``key``, which
    starts ``duration`` [s] later; ``sigma`` stationary, ``slip_time`` [s] correlation time."""
    return gauss_markov_step(previous_key, key, 2, duration, sigma, slip_time)


def slip_noise_covariance(duration: float, sigma: float, slip_time: float) -> np.ndarray:
    """``(2, 2)`` covariance of the slip scales of an interval of ``duration`` [s] taken as
    noise: the long-run variance ``sigma² (1 + φ) / (1 − φ)``, ``φ = exp(−duration /
    slip_time)``, of a Gauss–Markov process sampled once per interval (the variance of a sum
    of N such intervals is N times it, as for the process itself over long runs)."""
    phi = float(np.exp(-duration / slip_time))
    return sigma**2 * (1.0 + phi) / max(1.0 - phi, 1e-12) * np.eye(2)


def slip_mean_sigma(duration: float, sigma: float, slip_time: float) -> float:
    """Standard deviation of the Gauss–Markov process's mean over ``duration`` [s]:
    ``sqrt(2 sigma² τ² (T/τ − 1 + e^(−T/τ)) / T²)`` (``τ = slip_time``); ``sigma`` for
    ``T ≪ τ``, ``sigma sqrt(2τ/T)`` for ``T ≫ τ``. One scale with it over an interval
    integrates to the process's variance of the interval's total slip."""
    ratio = duration / slip_time
    if ratio < 1e-6:
        return float(sigma)
    return float(sigma * np.sqrt(2.0 * (ratio - 1.0 + np.exp(-ratio)) / ratio**2))
