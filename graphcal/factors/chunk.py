"""Wheel-odometry factors: eq. (1) integrated over a chunk of steps inside one GTSAM factor.

One class, :class:`OdometryChunkError`, evaluates the model over ``L`` steps vectorized and
serves every graph graphcal builds, because each of its variables can be a graph variable or
held fixed:

* the start pose (``gtsam.Pose2``), or a fixed start state;
* an end pose (``gtsam.Pose2``) that the prediction must reach (continuity; multiple shooting);
* wheel-rotation corrections (``[dn_rl, dn_rr]`` per step, added to the measured rotations):
  one 2-vector variable per step, or one ``2L``-vector variable for the whole chunk (laid out
  ``[dn_rl_0, dn_rr_0, dn_rl_1, ...]``; far fewer variables for long sequences), or none;
* theta (a 4-vector ``[c_e, c_d, t_r, d]``), or a fixed theta.

Its error stacks the tracking residuals of the predicted poses ``1..L`` against the measured
poses (if given) and the continuity residual ``predicted end - end pose``. Residuals are in
world coordinates ``[px, py, psi]``.

Three builders cover the common shapes:

* :func:`wheel_odometry_factor` — one step between two Pose2 variables: eq. (1) is the Pose2
  composition ``x_{k+1} = x_k ⊕ (v cos(ω/2+β), v sin(ω/2+β), ω)``;
* :func:`segment_odometry_factor` — a whole segment against its measured poses (the batch
  Gauss–Newton residual of eqs. 6–11);
* :func:`odometry_chunk_factor` — the general case.

Python factors cost ~50 µs per call plus a copy of the optimizer's values (``NOTES.md``), so
long sequences should use a few large chunks rather than one factor per step.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from graphcal.factors.poses import body_to_world, pose_sigmas, state_from_pose2
from graphcal.model import (
    N_RL,
    N_RR,
    integrate_with_jacobians,
    wheel_rotation_jacobian,
    wrap_angle,
)


class OdometryChunkError:
    """Residual and Jacobians of the odometry model over a chunk (the CustomFactor callable).

    Args:
        inputs: measured inputs ``[n_rl, n_rr, beta, ay]`` of the ``L`` steps, ``(L, 4)``.
        measured_poses: measured states ``(L+1, 3)`` to track (row 0, the start, is not
            tracked), or ``None`` for no tracking residuals.
        start_state: fixed start state ``[px, py, psi]``; ``None`` makes the start a Pose2 key.
        reference_heading: heading branch for Pose2 start/end variables (default: the measured
            or fixed start heading).
        has_end: whether an end Pose2 key follows (continuity residual).
        has_corrections: whether correction keys follow.
        corrections_as_vector: one ``2L``-vector correction key instead of ``L`` 2-vector keys.
        theta: fixed theta; ``None`` makes theta the last key.

    Keys, in order: ``[start?] [end?] [correction_0 .. correction_{L-1} | corrections?]
    [theta?]``.
    """

    def __init__(
        self,
        inputs: np.ndarray,
        measured_poses: np.ndarray | None = None,
        start_state: np.ndarray | None = None,
        reference_heading: float | None = None,
        has_end: bool = False,
        has_corrections: bool = False,
        theta: np.ndarray | None = None,
        corrections_as_vector: bool = False,
    ):
        self.inputs = np.array(inputs, dtype=float)
        n_steps = len(self.inputs)
        if self.inputs.ndim != 2 or self.inputs.shape[1] != 4 or n_steps == 0:
            raise ValueError(f"inputs must be (L, 4) with L >= 1, got {self.inputs.shape}")
        self.measured_poses = None if measured_poses is None else np.asarray(measured_poses, float)
        if self.measured_poses is not None and self.measured_poses.shape != (n_steps + 1, 3):
            raise ValueError(
                f"measured poses must be ({n_steps + 1}, 3) for {n_steps} steps, "
                f"got {self.measured_poses.shape}"
            )
        if self.measured_poses is None and not has_end:
            raise ValueError("a chunk needs measured poses to track or an end pose to reach")
        self.start_state = None if start_state is None else np.asarray(start_state, float)
        if reference_heading is None:
            if self.start_state is not None:
                reference_heading = float(self.start_state[2])
            elif self.measured_poses is not None:
                reference_heading = float(self.measured_poses[0, 2])
            else:
                raise ValueError("a Pose2 start needs a reference heading to unwrap against")
        self.reference_heading = float(reference_heading)
        self.has_end = has_end
        self.has_corrections = has_corrections
        self.corrections_as_vector = corrections_as_vector
        self.theta = None if theta is None else np.asarray(theta, float)

    @property
    def n_steps(self) -> int:
        """Number of steps L."""
        return len(self.inputs)

    @property
    def dim(self) -> int:
        """Length of the error vector."""
        return 3 * self.n_steps * (self.measured_poses is not None) + 3 * self.has_end

    def n_keys(self) -> int:
        """Number of keys the factor expects."""
        return (
            (self.start_state is None)
            + self.has_end
            + (1 if self.corrections_as_vector else self.n_steps) * self.has_corrections
            + (self.theta is None)
        )

    def evaluate(
        self,
        start: np.ndarray,
        theta: np.ndarray,
        corrections: np.ndarray | None = None,
        end: np.ndarray | None = None,
        jacobians: bool = True,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Error and Jacobians (w.r.t. states, not Pose2 tangents) for given values.

        Args:
            start: start state ``(3,)``; theta ``(4,)``; corrections ``(L, 2)`` or ``None``;
            end: end state ``(3,)`` (needed when ``has_end``; its heading may be on any
                branch, the continuity residual's heading is wrapped).

        Returns:
            ``error (dim,)`` and a dict with ``"start" (dim, 3)``, ``"end" (dim, 3)``,
            ``"corrections" (dim, L, 2)``, ``"theta" (dim, 4)`` as applicable.
        """
        inputs = self.inputs
        if corrections is not None:
            inputs = inputs.copy()
            inputs[:, N_RL] += corrections[:, 0]
            inputs[:, N_RR] += corrections[:, 1]
        states, d_start, d_theta = integrate_with_jacobians(start, inputs, theta, jacobians)
        parts, rows = [], []  # error pieces, and which state rows each Jacobian piece uses
        if self.measured_poses is not None:
            parts.append((states[1:] - self.measured_poses[1:]).reshape(-1))
            rows.append(slice(1, None))
        if self.has_end:
            gap = states[-1] - end
            gap[2] = wrap_angle(gap[2])
            parts.append(gap)
            rows.append(slice(-1, None))
        error = np.concatenate(parts)
        if not jacobians:
            return error, {}

        def stack(full: np.ndarray) -> np.ndarray:  # (L+1, 3, ...) -> (dim, ...)
            return np.concatenate([full[r].reshape(-1, *full.shape[2:]) for r in rows])

        jac = {"start": stack(d_start), "theta": stack(d_theta)}
        if self.has_corrections:
            jac["corrections"] = stack(wheel_rotation_jacobian(states, inputs, theta))
        if self.has_end:
            d_end = np.zeros((len(error), 3))
            d_end[-3:] = -np.eye(3)
            jac["end"] = d_end
        return error, jac

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        keys = list(factor.keys())
        position = 0
        start_key = end_key = theta_key = None
        if self.start_state is None:
            start_key = keys[position]
            position += 1
            start = state_from_pose2(values.atPose2(start_key), self.reference_heading)
        else:
            start = self.start_state
        end = None
        if self.has_end:
            end_key = keys[position]
            position += 1
        correction_keys: list[int] = []
        corrections = None
        if self.has_corrections and self.corrections_as_vector:
            correction_keys = [keys[position]]
            position += 1
            corrections = values.atVector(correction_keys[0]).reshape(self.n_steps, 2)
        elif self.has_corrections:
            correction_keys = keys[position : position + self.n_steps]
            position += self.n_steps
            corrections = np.array([values.atVector(k) for k in correction_keys])
        if self.theta is None:
            theta_key = keys[position]
            theta = values.atVector(theta_key)
        else:
            theta = self.theta
        if self.has_end:  # its heading branch does not matter: the residual is wrapped
            end = state_from_pose2(values.atPose2(end_key), start[2])
        error, jac = self.evaluate(start, theta, corrections, end, H is not None)
        if H is not None:
            out: list[np.ndarray] = []
            if start_key is not None:
                out.append(jac["start"] @ body_to_world(start[2]))
            if end_key is not None:
                out.append(jac["end"] @ body_to_world(end[2]))
            if correction_keys and self.corrections_as_vector:
                out.append(jac["corrections"].reshape(len(error), -1))
            elif correction_keys:
                out.extend(np.moveaxis(jac["corrections"], 1, 0))
            if theta_key is not None:
                out.append(jac["theta"])
            for i, block in enumerate(out):
                H[i] = np.ascontiguousarray(block)
        return error


def odometry_chunk_factor(
    error: OdometryChunkError,
    keys: Sequence[int],
    tracking_sigmas: np.ndarray | None = None,
    continuity_sigmas: np.ndarray | None = None,
) -> gtsam.CustomFactor:
    """Wrap an :class:`OdometryChunkError` as a ``gtsam.CustomFactor``.

    Args:
        error: the chunk's model and which of its variables are keys.
        keys: the keys, in the order the error expects.
        tracking_sigmas: sigmas ``[m, m, rad]`` of the tracking residuals (default: the
            paper's W with 0.2 m position noise).
        continuity_sigmas: sigmas of the continuity residual (default 1e-4 m, 1e-4 m, 1e-5 rad:
            a near-hard constraint, as the model equation is in the paper).
    """
    if len(keys) != error.n_keys():
        raise ValueError(f"chunk factor expects {error.n_keys()} keys, got {len(keys)}")
    sigmas = []
    if error.measured_poses is not None:
        track = pose_sigmas() if tracking_sigmas is None else np.asarray(tracking_sigmas, float)
        sigmas.append(np.tile(track, error.n_steps))
    if error.has_end:
        cont = (
            np.array([1e-4, 1e-4, 1e-5])
            if continuity_sigmas is None
            else np.asarray(continuity_sigmas, float)
        )
        sigmas.append(cont)
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.concatenate(sigmas))
    return gtsam.CustomFactor(noise, list(keys), error)


def segment_odometry_factor(
    theta_key: int,
    measured_poses: np.ndarray,
    inputs: np.ndarray,
    sigmas: np.ndarray | None = None,
    start_key: int | None = None,
) -> gtsam.CustomFactor:
    """A factor tying theta (and optionally the segment's start pose) to a measured segment.

    Args:
        theta_key: key of the 4-vector theta ``[c_e, c_d, t_r, d]`` (SI).
        measured_poses: measured states ``(K+1, 3)`` ``[px, py, psi]``, heading unwrapped.
        inputs: measured inputs ``(K, 4)`` ``[n_rl, n_rr, beta, ay]``.
        sigmas: per-component pose sigmas ``[m, m, rad]``; default :func:`pose_sigmas`.
        start_key: key of the start ``Pose2``; ``None`` holds the start at its measurement
            (the paper's state initialization, Step 1).
    """
    measured_poses = np.asarray(measured_poses, dtype=float)
    error = OdometryChunkError(
        inputs,
        measured_poses,
        start_state=measured_poses[0] if start_key is None else None,
    )
    keys = [theta_key] if start_key is None else [start_key, theta_key]
    return odometry_chunk_factor(error, keys, tracking_sigmas=sigmas)


def wheel_odometry_factor(
    pose_key: int,
    next_pose_key: int,
    theta_key: int,
    inputs: np.ndarray,
    sigmas: np.ndarray,
    correction_key: int | None = None,
    reference_heading: float = 0.0,
) -> gtsam.CustomFactor:
    """One odometry step between two Pose2 variables (eq. 1 as a Pose2 composition).

    Args:
        pose_key, next_pose_key: the Pose2 variables at samples k and k+1.
        theta_key: the shared 4-vector theta.
        inputs: measured ``[n_rl, n_rr, beta, ay]`` of step k [rev, rev, rad, m/s²].
        sigmas: ``[m, m, rad]`` standard deviations of the step's prediction error.
        correction_key: optional 2-vector variable added to the measured wheel rotations.
        reference_heading: approximate heading [rad] of the step (unwraps the Pose2 angle;
            any value within ±π of the truth gives the same factor).
    """
    error = OdometryChunkError(
        np.asarray(inputs, dtype=float).reshape(1, 4),
        reference_heading=reference_heading,
        has_end=True,
        has_corrections=correction_key is not None,
    )
    keys = [pose_key, next_pose_key]
    if correction_key is not None:
        keys.append(correction_key)
    keys.append(theta_key)
    return odometry_chunk_factor(error, keys, continuity_sigmas=sigmas)
