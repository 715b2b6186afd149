"""Linear algebra on GTSAM's linearized systems: augmented Hessians, Hessian diagonals,
damping rows and the decrease a step's linearization predicts."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import gtsam
import numpy as np


@functools.cache
def unit_noise(dim: int) -> gtsam.noiseModel.Unit:
    """``gtsam.noiseModel.Unit`` of dimension ``dim``, made once."""
    return gtsam.noiseModel.Unit.Create(dim)


def hessian_diagonal_by_column(linear: gtsam.GaussianFactorGraph, n_columns: int) -> np.ndarray:
    """Diagonal of ``JᵀJ`` of the whitened linear system, columns in sorted-key order: one
    pass over its sparse Jacobian (graphs of many small factors)."""
    _, columns, entries = linear.sparseJacobian_()
    inside = columns <= n_columns  # the augmented column (b) comes last
    return np.bincount(
        columns[inside].astype(int) - 1, weights=entries[inside] ** 2, minlength=n_columns
    )


def hessian_diagonal_by_key(
    linear: gtsam.GaussianFactorGraph, dims: dict[int, int]
) -> dict[int, np.ndarray]:
    """:func:`hessian_diagonal_by_column` cut into the keys of ``dims`` (zero for keys
    ``linear`` does not have); its columns follow the sorted keys of ``linear``."""
    present = sorted(linear.keys())
    flat = hessian_diagonal_by_column(linear, sum(dims[key] for key in present))
    diagonal = {key: np.zeros(dim) for key, dim in dims.items()}
    at = 0
    for key in present:
        diagonal[key] = flat[at : at + dims[key]]
        at += dims[key]
    return diagonal


def add_damping(
    system: gtsam.GaussianFactorGraph, dims: dict[int, int], root: dict[int, np.ndarray]
) -> None:
    """Add the rows ``diag(root[key])`` on every key of ``root`` to ``system``."""
    for key, r in root.items():
        dim = dims[key]
        system.add(gtsam.JacobianFactor(key, np.diag(r), np.zeros(dim), unit_noise(dim)))


@dataclass(frozen=True)
class SharedBlock:
    """An augmented Hessian on the shared keys a system touches: ``block`` at the rows and
    columns ``index`` of the ``(n+1, n+1)`` augmented Hessian on all of them (the last index
    is ``n``, the right-hand side). A part of a graph whose shared keys include every slip
    scale of a log touches its own few: 32 segments' dense systems on 1,229 shared
    dimensions were 390 MB, sent between processes and summed."""

    index: np.ndarray
    block: np.ndarray

    def add_to(self, total: np.ndarray) -> np.ndarray:
        """``total`` ``(n+1, n+1)`` with this block added in place; returned."""
        total[np.ix_(self.index, self.index)] += self.block
        return total


def shared_block(
    linear: gtsam.GaussianFactorGraph, keys: list[int], dims: dict[int, int]
) -> SharedBlock:
    """``[AᵀA Aᵀb; bᵀA bᵀb]`` of ``linear`` on the ``keys`` it has, placed among all of
    ``keys`` (:class:`SharedBlock`)."""
    n = sum(dims[k] for k in keys)
    if linear.size() == 0:
        return SharedBlock(np.array([n]), np.zeros((1, 1)))
    in_linear = set(linear.keyVector())
    present = [k for k in keys if k in in_linear]
    ordering = gtsam.Ordering()
    for key in present:
        ordering.push_back(key)
    hessian = linear.augmentedHessian(ordering)
    starts = dict(zip(keys, np.cumsum([0] + [dims[k] for k in keys])[:-1], strict=True))
    index = np.concatenate(
        [np.arange(starts[k], starts[k] + dims[k]) for k in present] + [np.array([n])]
    ).astype(int)
    return SharedBlock(index, hessian)


def augmented_hessian(
    linear: gtsam.GaussianFactorGraph, keys: list[int], dims: dict[int, int]
) -> np.ndarray:
    """``[AᵀA Aᵀb; bᵀA bᵀb]`` of ``linear`` on ``keys`` (zero blocks for keys it lacks)."""
    n = sum(dims[k] for k in keys)
    return shared_block(linear, keys, dims).add_to(np.zeros((n + 1, n + 1)))


def predicted_decrease(
    gradient: gtsam.VectorValues,
    step: gtsam.VectorValues,
    root: dict[int, np.ndarray],
    keys: list[int],
) -> float:
    """This system's share of the decrease its linearization predicts for a step of the
    damped normal equations ``(H + Λ) δ = −g`` (``Λ = diag(root²)`` on its damped keys):
    ``−½ gᵀδ + ½ δᵀΛδ`` (as ``δᵀHδ = −gᵀδ − δᵀΛδ``)."""
    total = 0.0
    for key in keys:
        if gradient.exists(key):
            total -= 0.5 * float(np.dot(gradient.at(key), step.at(key)))
    for key, r in root.items():
        total += 0.5 * float(np.sum((r * step.at(key)) ** 2))
    return total


def split_by_key(vector: np.ndarray, keys: list[int], dims: dict[int, int]) -> list[np.ndarray]:
    """``vector`` cut into the blocks of ``keys``."""
    out, at = [], 0
    for key in keys:
        out.append(vector[at : at + dims[key]])
        at += dims[key]
    return out


def vector_values(by_key: dict[int, np.ndarray]) -> gtsam.VectorValues:
    """A ``gtsam.VectorValues`` of ``by_key``'s vectors."""
    out = gtsam.VectorValues()
    for key, value in by_key.items():
        out.insert(key, value)
    return out
