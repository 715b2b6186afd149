"""The rear tyres' slip in a log without a sideslip: the model's point, the rear axle, moves
at the sideslip ``beta = −g · a_y`` to the heading (its tyres' slip angle, steady state: the
lateral force they carry over their cornering stiffness), ``g`` the rear slip gain [rad per
m/s²]. Without it the point that moves along the heading is ``g v²`` ahead of the axle, and
an estimated antenna lever arm took the mean of that (1.177 m for an antenna 1.35 m ahead of
the axle on a 4 km city drive, 8σ off; docs/defects.md).

:func:`rear_slip_gain_jacobian` is how a chunk's states move with ``g``, for
:func:`~graphcal.factors.chunk.chunk_errors`: a sideslip turns each step's travel off the
heading and stretches it (eq. 1, ``travel = v / cos beta``); the heading does not move.
"""

from __future__ import annotations

import numpy as np

from graphcal.model import AY, BETA, step_increments


def rear_slip_gain_jacobian(
    states: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    fractions: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """d states / d g ``(C, L+1, 3, 1)`` of states integrated from ``inputs (C, L, 4)`` (their
    sideslip column already ``beta − g · a_y``) with ``theta``; and, for measurements
    part-way through the steps (``fractions (C, L)``,
    :func:`~graphcal.model.partial_steps`), the direct d partial / d g ``(C, L, 3, 1)``
    through step k's own sideslip (``None`` without ``fractions``)::

        d p_k / d g = sum_(j<k) −a_y,j · travel_j ([−sin, cos] + tan beta_j [cos, sin])(course_j)
    """
    heading = states[..., :-1, 2]
    increments = step_increments(inputs, theta, True)  # (v, omega), once for both
    whole = _position_effects(heading, inputs, increments, 1.0)
    full = np.zeros((*states.shape, 1))
    np.cumsum(whole, axis=-2, out=full[..., 1:, :2, 0])
    direct = None
    if fractions is not None:
        part = _position_effects(heading, inputs, increments, fractions)
        direct = np.zeros((*part.shape[:-1], 3, 1))
        direct[..., :2, 0] = part
    return full, direct


def _position_effects(
    heading: np.ndarray,
    inputs: np.ndarray,
    increments: tuple[np.ndarray, np.ndarray],
    fraction: np.ndarray | float,
) -> np.ndarray:
    """``(..., K, 2)``: how the position at the end of ``fraction`` of each step, from the
    step's start ``heading (..., K)`` with its eq. (2) ``increments`` ``(v, omega)``, moves
    with ``g``."""
    v, omega = increments
    beta = inputs[..., BETA]
    travel = fraction * v / np.cos(beta)
    course = heading + 0.5 * fraction * omega + beta
    cos_c, sin_c, tan_b = np.cos(course), np.sin(course), np.tan(beta)
    scale = -inputs[..., AY] * travel
    return np.stack([scale * (tan_b * cos_c - sin_c), scale * (tan_b * sin_c + cos_c)], axis=-1)
