"""How a chunk's state Jacobians become its error's rows (:mod:`graphcal.factors.chunk`):
the tracked measurements predicted at the samples or part-way through their steps, and each
Jacobian — by the start, theta, a sideslip gain, or each step's wheel rotations — taken from
the states' to the rows of the tracked poses and the end state, vectorized over ``C``
chunks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.model import partial_steps
from graphcal.rotation_jacobians import after_mask, carried_rotation_jacobian


@dataclass(frozen=True)
class PredictedFixes:
    """Where the tracked measurements are predicted: ``states (C, L, 3)``, at the samples
    (``steps`` ``None``) or part-way through the steps (``steps``: the result of
    :func:`graphcal.model.partial_steps`; ``whole (C, L)``: the measurements at their
    samples)."""

    states: np.ndarray
    steps: tuple[np.ndarray, ...] | None = None
    whole: np.ndarray | None = None

    @property
    def d_theta(self) -> np.ndarray | None:
        """Direct d fix / d theta through the part-step ``(C, L, 3, 4)``, or ``None``."""
        return None if self.steps is None else self.steps[2]

    @property
    def d_rotations(self) -> np.ndarray | None:
        """Direct d fix / d step k-1's own rotations ``(C, L, 3, 2)``, or ``None``."""
        return None if self.steps is None else self.steps[3]


def predict_fixes(
    states: np.ndarray,
    rotations: np.ndarray,
    theta: np.ndarray,
    fractions: np.ndarray | None,
    jacobians: bool,
) -> PredictedFixes:
    """The predicted measurements: the states at the samples, or each measurement at its own
    time within its step (``fractions``)."""
    if fractions is None:
        return PredictedFixes(states[:, 1:])
    steps = partial_steps(states, rotations, theta, fractions, jacobians)
    return PredictedFixes(steps[0], steps, fractions == 1.0)


@dataclass(frozen=True)
class JacobianRows:
    """How state Jacobians ``(C, L+1, 3, ...)`` become the error's rows: the error pieces in
    order, the state rows each differentiates (``slice(1, None)``: the tracked poses,
    ``slice(-1, None)``: the end) and per piece how its x and y move with the state's
    heading beyond the state's own (``(C, rows, 2)``; ``None``: not at all)."""

    count: int
    n_steps: int
    fixes: PredictedFixes
    rows: list[slice]
    turns: list[np.ndarray | None]

    def at_fixes(self, full: np.ndarray, direct: np.ndarray | None) -> np.ndarray:
        """Tracked rows of a state Jacobian ``(C, L+1, 3, ...)``: at the samples, or through
        the part-steps (chain rule through state k-1 plus ``direct`` through step k-1)."""
        if self.fixes.steps is None:
            return full[:, 1:]
        _, d_state, *_ = self.fixes.steps
        before = full[:, :-1]
        out = np.matmul(d_state, before.reshape(*before.shape[:3], -1)).reshape(before.shape)
        if direct is not None:
            out += direct
        whole = self.fixes.whole
        if whole.any():  # measurements at their samples: the state itself
            out[whole] = full[:, 1:][whole]
        return out

    def stack(self, full: np.ndarray, direct: np.ndarray | None = None) -> np.ndarray:
        """The error's Jacobian ``(C, dim, ...)`` from a state Jacobian ``(C, L+1, 3, ...)``
        (``direct``: :meth:`at_fixes`)."""
        blocks = []
        for r, turn in zip(self.rows, self.turns, strict=True):
            block = self.at_fixes(full, direct) if r == slice(1, None) else full[:, r]
            if turn is not None:  # x and y gain the heading's derivative times the turn
                block = block.copy()
                heading = block[:, :, 2]
                trailing = (...,) + (None,) * (block.ndim - 3)
                block[:, :, 0] += turn[..., 0][trailing] * heading
                block[:, :, 1] += turn[..., 1][trailing] * heading
            blocks.append(block.reshape(self.count, -1, *full.shape[3:]))
        return np.concatenate(blocks, axis=1)

    def rotations(self, states: np.ndarray, rotations: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The error's Jacobian ``(C, dim, L, 2)`` in each step's wheel rotations, row by row
        without the states' ``(C, L+1, 3, L, 2)`` one: a tracked measurement is a point the
        path carries from its step on (the fix part-way through the step, the antenna on
        the lever arm), the end state one from the last
        (:func:`~graphcal.rotation_jacobians.carried_rotation_jacobian`); a fix part-way
        through step k moves with step k's own rotations directly (``fixes.d_rotations``)."""
        count, n_steps = self.count, self.n_steps
        points, masks = [], []
        for r, turn in zip(self.rows, self.turns, strict=True):
            if r == slice(1, None):
                at = self.fixes.states[..., :2]
                if turn is not None:  # the antenna, R(ψ) · arm from the fix: J⁻¹ · turn
                    at = at + np.stack([turn[..., 1], -turn[..., 0]], axis=-1)
                # a fix at sample k (no part-steps) moves with steps j ≤ k-1, one part-way
                # through step k with steps j < k and its own step (added below)
                first = 1 if self.fixes.steps is None else 0
                points.append(at)
                masks.append(after_mask(n_steps, n_steps, first))
            else:
                points.append(states[:, -1:, :2])
                masks.append(after_mask(1, n_steps, n_steps))
        out = carried_rotation_jacobian(
            states, rotations, theta, np.concatenate(points, axis=1), np.concatenate(masks)
        )
        own = self.fixes.d_rotations  # (C, L, 3, 2), only where tracked through part-steps
        if own is not None and self.rows[0] == slice(1, None):
            own = own.copy()
            turn = self.turns[0]
            if turn is not None:
                own[:, :, 0] += turn[..., 0, None] * own[:, :, 2]
                own[:, :, 1] += turn[..., 1, None] * own[:, :, 2]
            c, m, i, j, w = out.strides
            diagonal = np.lib.stride_tricks.as_strided(
                out, shape=(count, n_steps, 3, 2), strides=(c, m + j, i, w), writeable=True
            )
            diagonal += own
        return out.reshape(count, -1, n_steps, 2)
