"""The terms of a chunk's error beside the odometry: how the measured pose is predicted from
the state — through the antenna's lever arm, a heading bias and the fixes' slowly varying
error (:mod:`graphcal.factors.chunk`) — with their Jacobians, vectorized over ``C`` chunks."""

from __future__ import annotations

import numpy as np

from graphcal.model import wrap_angle


def tracking_residuals(
    at_fix: np.ndarray,
    measured_poses: np.ndarray,
    lever_arm: np.ndarray | None,
    heading_bias: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """``measurement_k − measured_k`` of the poses ``k = 1..L`` ``(C, L, 3)``, the predicted
    measurement ``[p_k + R(ψ_k) · arm, ψ_k + bias]``; and how its x and y move with the
    heading beyond the state's own (the lever arm turning with it, ``(C, L, 2)``; ``None``
    without a lever arm). The heading's residual is wrapped to ``(−π, π]``: a chunk's start
    pose is unwrapped against a reference heading from the path the graph was built on, a
    branch 2π away where that path turned through more than π too much (a skid-steer robot
    integrated with its datasheet track, half its effective one, spinning on the spot)."""
    residual = at_fix - measured_poses[:, 1:]
    turn = None
    if lever_arm is not None:
        cos, sin = np.cos(at_fix[..., 2]), np.sin(at_fix[..., 2])
        ahead, left = lever_arm[:, 0:1], lever_arm[:, 1:2]
        residual[..., 0] += cos * ahead - sin * left
        residual[..., 1] += sin * ahead + cos * left
        turn = np.stack([-sin * ahead - cos * left, cos * ahead - sin * left], axis=-1)
    if heading_bias is not None:
        residual[..., 2] += heading_bias[:, None]
    residual[..., 2] = wrap_angle(residual[..., 2])  # whatever branch the state is on
    return residual, turn


def lever_arm_jacobian(
    at_fix: np.ndarray | None, count: int, dim: int, n_tracked: int
) -> np.ndarray:
    """d error / d lever arm ``(C, dim, 2)``: ``R(ψ_k)`` on the tracked x and y rows
    (``at_fix`` ``None``: no tracked rows)."""
    d_arm = np.zeros((count, dim, 2))
    if at_fix is not None:
        cos, sin = np.cos(at_fix[..., 2]), np.sin(at_fix[..., 2])
        d_arm[:, 0:n_tracked:3] = np.stack([cos, -sin], axis=-1)
        d_arm[:, 1:n_tracked:3] = np.stack([sin, cos], axis=-1)
    return d_arm


def heading_bias_jacobian(count: int, dim: int, n_tracked: int) -> np.ndarray:
    """d error / d heading bias ``(C, dim, 1)``: 1 on the tracked heading rows."""
    d_bias = np.zeros((count, dim, 1))
    d_bias[:, 2:n_tracked:3] = 1.0
    return d_bias


def chunk_fractions(count: int, n_steps: int, fractions: np.ndarray | None) -> np.ndarray:
    """``(C, L)``: how far through the chunk (0 at its start, 1 at its end) each tracked
    pose's measurement was taken."""
    at = np.broadcast_to(np.arange(1.0, n_steps + 1.0), (count, n_steps))
    if fractions is not None:
        at = at - 1.0 + fractions
    return at / n_steps


def fix_offsets(fix_offset: np.ndarray, along: np.ndarray) -> np.ndarray:
    """``(C, L, 2)``: the fixes' error at each tracked pose, linear from its value at the
    chunk's start to its value at the end (``fix_offset (C, 2, 2)``)."""
    return (
        fix_offset[:, None, 0] * (1.0 - along)[..., None]
        + fix_offset[:, None, 1] * along[..., None]
    )


def fix_offset_jacobian(along: np.ndarray, dim: int, n_tracked: int) -> np.ndarray:
    """d error / d fixes' error at the chunk's start and end ``(C, dim, 4)``: ``1 − a_k`` and
    ``a_k`` on the tracked x and y rows, ``a_k`` how far through the chunk fix k is."""
    count = len(along)
    d_offset = np.zeros((count, dim, 4))
    if n_tracked == 0:  # nothing tracked: the error does not depend on them
        return d_offset
    d_offset[:, 0:n_tracked:3, 0] = 1.0 - along
    d_offset[:, 1:n_tracked:3, 1] = 1.0 - along
    d_offset[:, 0:n_tracked:3, 2] = along
    d_offset[:, 1:n_tracked:3, 3] = along
    return d_offset
