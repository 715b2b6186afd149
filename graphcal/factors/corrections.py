"""Priors on wheel-rotation corrections and on theta (C++ GTSAM factors).

A correction ``c_k = [dn_rl, dn_rr]`` [rev] is added to the measured rotations of step k, so
the corrected input is ``u_k = u~_k + c_k``. A chunk's corrections are one ``2L``-vector
variable ``[dn_rl_0, dn_rr_0, dn_rl_1, ...]``.

* Size (the paper bounds inputs to measured × [0.95, 1.05], §4.4; or the wheel noise): a
  zero-mean prior on each ``c_k``, a soft version of the box constraint.
* Smoothness (the paper's R on Δu, §4.2): penalizes the change of the *corrected* rotation
  between consecutive steps, ``u_{k+1} - u_k = (u~_{k+1} - u~_k) + (c_{k+1} - c_k)``.
* Theta prior: the nominal theta with broad sigmas.

The size term alone is a ``gtsam.PriorFactorVector`` at zero whose noise model the chunks of
one wheel noise share; with smoothness the terms are one linear factor
(``gtsam.LinearContainerFactor``). Both are linear in the corrections and evaluated in C++.
"""

from __future__ import annotations

import functools

import gtsam
import numpy as np

from graphcal.model import THETA_NOMINAL


def _linear(jacobian_factor: gtsam.JacobianFactor, keys_and_dims: list[tuple[int, int]]):
    point = gtsam.Values()
    for key, dim in keys_and_dims:
        point.insert(key, np.zeros(dim))
    return gtsam.LinearContainerFactor(jacobian_factor, point)


def chunk_correction_prior(
    key: int,
    measured: np.ndarray,
    size: np.ndarray,
    smooth_sigma: float | None,
    quantization: float = 0.0,
) -> gtsam.NonlinearFactor:
    """Size and within-chunk smoothness of a ``2L``-vector of corrections: a prior at zero
    under their noise model, or with smoothness one linear factor.

    Args:
        key: the chunk's correction vector ``[dn_rl_0, dn_rr_0, dn_rl_1, ...]``.
        measured: measured ``[n_rl, n_rr]`` of its ``L`` steps, ``(L, 2)`` [rev].
        size: size-prior sigmas ``(L, 2)`` [rev] (white noise of each step's rotation).
        smooth_sigma: sigma of the change of a corrected rotation between steps [rev], or
            ``None`` for no smoothness term.
        quantization: sigma [rev] of the rounding error of each wheel's cumulative count
            (``1 / (ticks √12)`` for an encoder's ticks), or 0. A step's rotation is the
            difference of two counts, so its error is ``e_k+1 − e_k``: the prior's
            covariance per wheel gains ``q²`` times the tridiagonal ``[−1, 2, −1]`` (errors of
            neighbouring steps cancel in a sum, as they do in the odometry), beside the white
            ``size²``. Correlation across chunk boundaries is left out.
    """
    measured = np.asarray(measured, float)
    n = 2 * len(measured)
    sizes = np.asarray(size, float).reshape(-1)
    if smooth_sigma is None or n <= 2:
        # a prior at zero under the size (and rounding) noise, which the chunks of one wheel
        # noise share: as a dense linear factor, each chunk held its own 2L × 2L matrix, 80 KB
        # at 50 steps — 350 MB of a 200 km log's graph
        return gtsam.PriorFactorVector(key, np.zeros(n), _size_noise(sizes.tobytes(), quantization))
    if quantization > 0:
        a, b = [_whitening(sizes.tobytes(), float(quantization))], [np.zeros(n)]
    else:
        a, b = [np.diag(1.0 / sizes)], [np.zeros(n)]
    if smooth_sigma is not None and n > 2:
        a.append((np.eye(n, k=2)[: n - 2] - np.eye(n)[: n - 2]) / smooth_sigma)
        b.append(-np.diff(measured, axis=0).reshape(-1) / smooth_sigma)
    factor = gtsam.JacobianFactor(
        key, np.vstack(a), np.concatenate(b), gtsam.noiseModel.Unit.Create(len(np.concatenate(b)))
    )
    return _linear(factor, [(key, n)])


@functools.lru_cache(maxsize=64)
def _size_noise(sizes: bytes, quantization: float) -> gtsam.noiseModel.Base:
    """The noise model of white ``sizes`` (the float64 bytes of ``(2L,)`` sigmas) and, with
    ``quantization``, differenced counts rounded by it (:func:`_whitening`'s covariance),
    made once for the chunks that share it."""
    size = np.frombuffer(sizes, dtype=float)
    if quantization <= 0:
        return gtsam.noiseModel.Diagonal.Sigmas(size.copy())
    return gtsam.noiseModel.Gaussian.Covariance(_covariance(size, quantization))


def _covariance(size: np.ndarray, quantization: float) -> np.ndarray:
    """The corrections' covariance ``(2L, 2L)``: white ``size²`` and, per wheel, ``q²``
    times the tridiagonal ``[−1, 2, −1]`` of differenced rounded counts."""
    n = len(size)
    return np.diag(size**2) + quantization**2 * (2.0 * np.eye(n) - np.eye(n, k=2) - np.eye(n, k=-2))


@functools.lru_cache(maxsize=32)
def _whitening(sizes: bytes, quantization: float) -> np.ndarray:
    """``W`` with ``W Σ Wᵀ = I`` for the corrections' covariance ``Σ`` of white ``sizes``
    (the float64 bytes of ``(2L,)`` sigmas) and differenced counts rounded by
    ``quantization``. The chunks of a log share a few of these (one wheel noise, the same
    chunk length), so each is computed once: inverting it for every chunk of every graph
    was half of a robot's calibration."""
    size = np.frombuffer(sizes, dtype=float)
    whiten = np.linalg.inv(np.linalg.cholesky(_covariance(size, quantization)))
    whiten.setflags(write=False)
    return whiten


def chunk_boundary_smoothness(
    key: int,
    n_steps: int,
    last_measured: np.ndarray,
    next_key: int,
    next_n_steps: int,
    next_first_measured: np.ndarray,
    smooth_sigma: float,
) -> gtsam.LinearContainerFactor:
    """Smoothness between the last step of one correction chunk and the first of the next."""
    a1 = np.zeros((2, 2 * n_steps))
    a1[:, -2:] = -np.eye(2)
    a2 = np.zeros((2, 2 * next_n_steps))
    a2[:, :2] = np.eye(2)
    b = -(np.asarray(next_first_measured, float) - np.asarray(last_measured, float))
    factor = gtsam.JacobianFactor(
        key, a1, next_key, a2, b, gtsam.noiseModel.Isotropic.Sigma(2, smooth_sigma)
    )
    return _linear(factor, [(key, 2 * n_steps), (next_key, 2 * next_n_steps)])


def theta_prior_factor(
    key: int, sigmas: np.ndarray, mean: np.ndarray = THETA_NOMINAL
) -> gtsam.PriorFactorVector:
    """A prior on theta ``[c_e, c_d, t_r, d]`` (SI), by default at the nominal values."""
    return gtsam.PriorFactorVector(
        key, np.asarray(mean, float), gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, float))
    )
