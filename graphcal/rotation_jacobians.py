"""How wheel rotations move the states of eq. (1): d pose / d wheel rotations of a path
(:mod:`graphcal.model`'s integration), vectorized over steps — every state's, any point's the
path carries (a fix part-way through a later step, an antenna off the axle) and the final
state's. The chunk factors' and the preintegration's Jacobians in the wheel rotations."""

from __future__ import annotations

import numpy as np

# Through the module: a study that swaps the model's sideslip stretch
# (scripts/eq1_small_angle.py) swaps it here too.
from graphcal import model


def _direct_rotation_effects(
    states: np.ndarray, inputs: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How a wheel rotation at step j moves the pose of step j+1 directly: d px, d py (each
    ``(..., K, 2)``) and d omega ``(..., K, 2)`` per [n_rl, n_rr]_j."""
    inputs = np.asarray(inputs, dtype=float)
    v, omega, dv_dn, domega_dn, _, _ = model.increment_jacobians(inputs, theta, True)
    stretch = model.sideslip_stretch(inputs)[..., None]
    course = states[..., :-1, 2] + 0.5 * omega + inputs[..., model.BETA]
    c, s = np.cos(course)[..., None], np.sin(course)[..., None]
    vv = v[..., None] * stretch
    dv_dn = dv_dn * stretch
    direct_x = dv_dn * c - vv * s * 0.5 * domega_dn
    direct_y = dv_dn * s + vv * c * 0.5 * domega_dn
    return direct_x, direct_y, domega_dn


def wheel_rotation_jacobian(
    states: np.ndarray, inputs: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """d states / d wheel rotations of a trajectory from :func:`graphcal.model.integrate`.

    Args:
        states: ``(..., K+1, 3)`` states integrated from ``inputs`` with ``theta``.
        inputs: ``(..., K, 4)``.
        theta: ``(4,)`` or ``(..., 4)``.

    Returns:
        ``(..., K+1, 3, K, 2)``: entry ``[k, :, j, :]`` is d x_k / d [n_rl, n_rr]_j, zero for
        ``j >= k``. A rotation at step j moves the pose of step j+1 directly and turns the rest
        of the path about the position ``p_{j+1}`` by d omega_j::

            d psi_k / d n_j = d omega_j
            d p_k / d n_j = d v_j [cos, sin](course_j) + v_j [-sin, cos](course_j) d omega_j / 2
                            + d omega_j * J (p_k - p_{j+1}),  J = 90° rotation
    """
    after = after_mask(states.shape[-2], inputs.shape[-2])  # (K+1, 2K): 1 where k > j
    return carried_rotation_jacobian(states, inputs, theta, states[..., :2], after)


def carried_rotation_jacobian(
    states: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    points: np.ndarray,
    after: np.ndarray,
) -> np.ndarray:
    """d (point, heading) / d wheel rotations of ``M`` points the path carries, point ``m``
    [m] moving with it after each step ``j`` where ``after[m, 2j]`` is 1: the rows of
    :func:`wheel_rotation_jacobian` with ``p_k`` any point fixed to the vehicle then (a fix
    part-way through a later step, an antenna off the axle).

    Args:
        states, inputs, theta: as :func:`wheel_rotation_jacobian`'s.
        points: ``(..., M, 2)`` [m].
        after: ``(M, 2K)`` 0/1 float mask, each step's column repeated for the two wheels.

    Returns:
        ``(..., M, 3, K, 2)``: entry ``[m, :, j, :]`` is d [x, y, psi]_m / d [n_rl, n_rr]_j
        through step j's motion and turn.
    """
    direct_x, direct_y, domega_dn = _direct_rotation_effects(states, inputs, theta)
    n_points, n_steps = points.shape[-2], inputs.shape[-2]
    batch = np.broadcast_shapes(
        states.shape[:-2], inputs.shape[:-2], direct_x.shape[:-2], points.shape[:-2]
    )
    # In place, the axes (step j, wheel) as one of 2K: numpy's inner loops run over 2K, not
    # 2 wheels (2.1× faster). Positions from the path's start (metres, not a log's
    # kilometres: no cancellation); x = direct_x + dω py_j+1 − dω y_m, y = direct_y − dω
    # px_j+1 + dω x_m: the step's part (..., 1, 2K) apart, three passes per row.
    flat = (*batch, 1, 2 * n_steps)
    d_om = np.broadcast_to(domega_dn, (*batch, n_steps, 2)).reshape(flat)
    origin = states[..., :1, :2]
    q = np.broadcast_to(points - origin, (*batch, n_points, 2))
    p = np.repeat(np.broadcast_to(states[..., 1:, :2] - origin, (*batch, n_steps, 2)), 2, axis=-2)
    out = np.empty((*batch, n_points, 3, 2 * n_steps))
    for row, (position, direct, sign) in enumerate(((1, direct_x, -1.0), (0, direct_y, 1.0))):
        turn = sign * d_om  # (..., 1, 2K)
        step = np.broadcast_to(direct, (*batch, n_steps, 2)).reshape(flat)
        step = step - turn * p[..., position].reshape(flat)
        target = out[..., row, :]
        np.multiply(q[..., position, None], turn, out=target)
        target += step
        target *= after
    np.multiply(d_om, after, out=out[..., 2, :])
    return out.reshape(*batch, n_points, 3, n_steps, 2)


def after_mask(n_points: int, n_steps: int, first: int = 0) -> np.ndarray:
    """``(M, 2K)`` mask for :func:`carried_rotation_jacobian`: 1.0 where point m, carried from
    state ``first + m`` on, comes after step j (``first + m > j``), twice (the wheels)."""
    mask = np.arange(first, first + n_points)[:, None] > np.arange(n_steps)[None, :]
    return np.repeat(mask, 2, axis=-1).astype(float)


def end_wheel_rotation_jacobian(
    states: np.ndarray, inputs: np.ndarray, theta: np.ndarray
) -> np.ndarray:
    """d (final state) / d wheel rotations ``(..., 3, K, 2)``: the last row of
    :func:`wheel_rotation_jacobian`, with the same arguments. Entry ``[:, j, :]`` is
    d x_K / d [n_rl, n_rr]_j [m/rev, m/rev, rad/rev], in O(K) memory (no ``(K+1, K)`` lever
    table)."""
    states = np.asarray(states, dtype=float)
    direct_x, direct_y, domega_dn = _direct_rotation_effects(states, inputs, theta)
    # lever_j = p_K - p_{j+1}: the rest of the path turns about p_{j+1} by d omega_j.
    lever_x = (states[..., -1:, 0] - states[..., 1:, 0])[..., None]  # (..., K, 1)
    lever_y = (states[..., -1:, 1] - states[..., 1:, 1])[..., None]
    jx = direct_x - domega_dn * lever_y
    jy = direct_y + domega_dn * lever_x
    jx, jy, jpsi = np.broadcast_arrays(jx, jy, domega_dn)
    return np.stack([jx, jy, jpsi], axis=-3)
