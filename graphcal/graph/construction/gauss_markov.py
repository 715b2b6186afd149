"""First-order Gauss–Markov priors of a vector that varies slowly from span to span.

A quantity that drifts over seconds to minutes — a rear wheel's slow slip
(:mod:`graphcal.graph.construction.slip`), a GNSS receiver's position error — is one vector per span
of the drive (a chunk of a segment) with the stationary prior ``N(0, sigma²)`` at the first span
of a chain and a Gauss–Markov step between consecutive spans,
``v_j − φ v_(j−1) ~ N(0, sigma² (1 − φ²))``, ``φ = exp(−duration / correlation_time)``, so
that every span's vector has the stationary sigma. Both factors are linear in the vectors.
"""

from __future__ import annotations

import gtsam
import numpy as np


def stationary_prior(key: int, size: int, sigma: float) -> gtsam.PriorFactorVector:
    """The stationary prior ``N(0, sigma² I)`` of a chain's first ``size``-vector."""
    return gtsam.PriorFactorVector(
        key, np.zeros(size), gtsam.noiseModel.Isotropic.Sigma(size, float(sigma))
    )


def gauss_markov_step(
    previous_key: int,
    key: int,
    size: int,
    duration: float,
    sigma: float,
    correlation_time: float,
) -> gtsam.LinearContainerFactor:
    """The step from the span ``previous_key`` to the next one ``key``, which starts
    ``duration`` [s] later; ``sigma`` stationary, ``correlation_time`` [s]."""
    phi = float(np.exp(-duration / correlation_time))
    step_sigma = sigma * np.sqrt(max(1.0 - phi**2, 1e-12))
    linear = gtsam.JacobianFactor(
        previous_key,
        -phi * np.eye(size),
        key,
        np.eye(size),
        np.zeros(size),
        gtsam.noiseModel.Isotropic.Sigma(size, float(step_sigma)),
    )
    zero = gtsam.Values()
    zero.insert(previous_key, np.zeros(size))
    zero.insert(key, np.zeros(size))
    # Linear in the vectors: linearized at zero, the container is exact everywhere.
    return gtsam.LinearContainerFactor(linear, zero)
