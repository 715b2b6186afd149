"""A per-step reference of eq. (1), against which the vectorized integration is checked."""

from __future__ import annotations

import numpy as np

from graphcal.model import BETA, step_increments


def step(state: np.ndarray, inputs: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """One step of eq. (1) for a rigid body: the state after applying ``inputs`` to
    ``state``; the centre of gravity travels ``v / cos(beta)`` along the course.

    ``state`` is ``(..., 3)``, ``inputs`` ``(..., 4)``, ``theta`` ``(4,)`` or ``(..., 4)``.
    """
    state = np.asarray(state, dtype=float)
    v, omega = step_increments(inputs, theta)
    beta = np.asarray(inputs)[..., BETA]
    course = state[..., 2] + 0.5 * omega + beta
    v = v / np.cos(beta)
    return np.stack(
        [
            state[..., 0] + v * np.cos(course),
            state[..., 1] + v * np.sin(course),
            state[..., 2] + omega,
        ],
        axis=-1,
    )
