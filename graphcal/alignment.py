"""A path fitted rigidly to measured positions: how an integrated path is compared with
its measurements, its shape judged and not a start heading whose error alone is metres over
a segment."""

from __future__ import annotations

import numpy as np

from graphcal.model import lever_offset


def aligned_trajectory(
    states: np.ndarray,
    measured: np.ndarray,
    weights: np.ndarray | None = None,
    lever_arm: np.ndarray | None = None,
) -> np.ndarray:
    """``states (K+1, 3)`` turned and shifted as one rigid body to fit the positions of
    ``measured (K+1, 3)`` in weighted least squares (weights ``(K+1,)``, default 1): the
    2-D Procrustes solution, headings turned with the positions. With ``lever_arm``
    ``[ahead, left]`` [m] the measured positions are of a point that far from the centre of
    gravity (a GNSS antenna): that point's path is fitted, and the states moved with it. An
    integrated path that starts at a measured pose inherits that pose's error (1.5° of
    heading is 4 m of drift over 150 m); aligned, it is as close to the measurements as its
    shape allows."""
    w = np.ones(len(states)) if weights is None else np.asarray(weights, float)
    total = float(w.sum())
    if total <= 0:
        return states
    p = states[:, :2]
    a = p
    if lever_arm is not None:
        a = p + lever_offset(states[:, 2], lever_arm)
    b = measured[:, :2]
    # Elementwise sums, not BLAS: the same bits whatever the arrays' memory alignment.
    a_mean = np.sum(w[:, None] * a, axis=0) / total
    b_mean = np.sum(w[:, None] * b, axis=0) / total
    da, db = (a - a_mean) * w[:, None], b - b_mean
    h = np.sum(da[:, :, None] * db[:, None, :], axis=0)  # Σ w (a − ā)ᵀ (b − b̄)
    angle = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    cos, sin = np.cos(angle), np.sin(angle)
    out = np.empty_like(states)
    dx, dy = p[:, 0] - a_mean[0], p[:, 1] - a_mean[1]  # the same motion for every point
    out[:, 0] = cos * dx - sin * dy + b_mean[0]
    out[:, 1] = sin * dx + cos * dy + b_mean[1]
    out[:, 2] = states[:, 2] + angle
    return out
