"""The slip screen's score test (:mod:`graphcal.pipeline.solvers.slip_screen`) on the
structure of its reduced system, without dense algebra on every slip scale at once.

With every local variable eliminated, the screen's system on the graph-wide variables ``k``
(theta and the sensor terms) and the slip scales ``s`` is ``T``, the data's part of it
``D``. Each part of the graph touches its own segment's scales, and their priors join only a
segment's (or a tied chain's) chunks: ``B = T_ss`` and ``D_ss`` are block diagonal, and all
that couples the blocks is the few graph-wide variables. With ``G = T_sk T_kk⁻¹``:

    A = B − G T_ks                     the scales' information, graph-wide eliminated
    H = D_ss + Q C Qᵀ,  Q = [G, D_sk],  C = [[D_kk, −I], [−I, 0]]
    A⁻¹ = B⁻¹ + Y Z Yᵀ,  Y = B⁻¹ T_sk,  Z = (T_kk − T_ks B⁻¹ T_sk)⁻¹   (Woodbury)
    A⁻¹H = M₀ + R Sᵀ,  M₀ = B⁻¹ D_ss (block diagonal),
           R = [(B⁻¹Q + Y Z YᵀQ) C, Y],  S = [Q, D_ss Y Zᵀ]

so ``tr(A⁻¹H) = tr M₀ + tr(SᵀR)`` and ``tr((A⁻¹H)²) = tr(M₀²) + 2 tr(Sᵀ M₀ R) +
tr((SᵀR)²)``: blocks of a segment's size and products ``s × 3k``. The dense forms cost
``s³`` several times over (~13 Gflop for a 24 km drive's 1,222 scales): 0.62 → 0.04 s, the
same three numbers to 6·10⁻¹⁵ (``docs/performance.md``, twenty-second part).
"""

from __future__ import annotations

import numpy as np


def diagonal_blocks(*matrices: np.ndarray) -> list[slice]:
    """The finest contiguous blocks ``[a, b)`` that hold every nonzero of the symmetric
    square ``matrices`` (a coupling beyond the diagonal blocks merges them: never wrong,
    at worst one block)."""
    pattern = np.zeros(matrices[0].shape, bool)
    for matrix in matrices:
        pattern |= matrix != 0
    size = len(pattern)
    if size == 0:
        return []
    pattern[np.arange(size), np.arange(size)] = True
    last = size - 1 - np.argmax(pattern[:, ::-1], axis=1)  # each row's last nonzero column
    reach = np.maximum.accumulate(last)
    ends = np.flatnonzero(reach == np.arange(size)) + 1
    return [slice(int(a), int(b)) for a, b in zip(np.r_[0, ends[:-1]], ends, strict=True)]


class _BlockDiagonal:
    """A block-diagonal matrix held as its ``blocks`` of a dense ``matrix``."""

    def __init__(self, matrix: np.ndarray, blocks: list[slice]):
        self.matrix = matrix
        self.blocks = blocks

    def solve(self, right: np.ndarray) -> np.ndarray:
        """``matrix⁻¹ right`` block by block (``right`` ``(s,)`` or ``(s, m)``)."""
        out = np.empty_like(right, dtype=float)
        for block in self.blocks:
            out[block] = np.linalg.solve(self.matrix[block, block], right[block])
        return out


class ScreenSystem:
    """The screen's reduced system (module docstring) from the augmented Hessians ``(n+1,
    n+1)`` of the whole screen ``total`` and of its data alone ``data``, the graph-wide
    variables the first ``k`` of ``n``, the slip scales the rest.

    Attributes:
        gain: ``G = T_sk T_kk⁻¹`` ``(s, k)``; ``−Gᵀ`` is the graph-wide variables'
            response to the scales.
        score: ``g`` ``(s,)``, the scales' gradient with the graph-wide variables
            eliminated.
    """

    def __init__(self, total: np.ndarray, data: np.ndarray, k: int):
        n = len(total) - 1
        self.t_kk, self.t_ks, self.b = total[:k, :k], total[:k, k:n], total[k:n, k:n]
        self.d_ks, self.d_ss = data[:k, k:n], data[k:n, k:n]
        gradient = total[:n, n]
        self.gain = np.linalg.solve(self.t_kk, self.t_ks).T
        self.score = gradient[k:] - self.gain @ gradient[:k]
        self.q = np.hstack([self.gain, self.d_ks.T])
        self.c = np.block([[data[:k, :k], -np.eye(k)], [-np.eye(k), np.zeros((k, k))]])

    def restricted(self, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Bᵀg, BᵀAB, BᵀHB)`` of the test restricted to the directions ``basis``
        ``(s, q)``."""
        a_basis = self.b @ basis - self.gain @ (self.t_ks @ basis)
        h_basis = self.d_ss @ basis + self.q @ (self.c @ (self.q.T @ basis))
        return basis.T @ self.score, basis.T @ a_basis, basis.T @ h_basis

    def test(self) -> tuple[float, float, float]:
        """``T = gᵀ A⁻¹ g``, its null mean ``tr(A⁻¹H)`` and σ ``√(2 tr((A⁻¹H)²))`` (the
        same three numbers as the dense formulas)."""
        b, d_ss, q = self.b, self.d_ss, self.q
        blocks = _BlockDiagonal(b, diagonal_blocks(b, d_ss))
        y = blocks.solve(self.t_ks.T)
        z = np.linalg.inv(self.t_kk - self.t_ks @ y)
        r = np.hstack([(blocks.solve(q) + y @ (z @ (y.T @ q))) @ self.c, y])
        s = np.hstack([q, d_ss @ y @ z.T])
        small = s.T @ r  # (3k, 3k)
        mean, square = float(np.trace(small)), float(np.sum(small * small.T))
        for block in blocks.blocks:
            m0 = np.linalg.solve(b[block, block], d_ss[block, block])
            mean += float(np.trace(m0))
            square += float(np.sum(m0 * m0.T)) + 2.0 * float(np.sum(s[block] * (m0 @ r[block])))
        projected = y.T @ self.score
        statistic = float(self.score @ blocks.solve(self.score)) + float(projected @ z @ projected)
        # tr((A⁻¹H)²) ≥ 0 for A positive definite and H semidefinite; a degenerate system's
        # rounding (a garbled log of the loader's fuzz test) can dip below: no spread, not NaN
        return statistic, mean, float(np.sqrt(max(2.0 * square, 0.0)))
