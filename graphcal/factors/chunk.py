"""Eq. (1) integrated over a chunk of steps inside one GTSAM factor.

Python factors cost ~50 µs per call plus a copy of the optimizer's values
(``docs/performance.md``), so graphcal integrates many 40 Hz steps per factor, vectorized:

* :class:`OdometryChunk` holds a chunk's measurements — its ``L`` measured inputs and,
  optionally, the ``L+1`` measured poses to track — and evaluates the error with its
  Jacobians for given values (pure numpy, no keys): the measurement half of the pair, as
  ``PreintegratedImuMeasurements`` is for ``ImuFactor``.
* :class:`ChunkOdometryFactor` places a chunk between graph variables. Each of its slots is
  named: the start (a Pose2 key, or a held state), theta (a 4-vector key, or a fixed value),
  the chunk's wheel-rotation corrections (one ``2L``-vector key, laid out
  ``[dn_rl_0, dn_rr_0, dn_rl_1, ...]``, or none), the end (the Pose2 key of the next
  chunk's start, or none for a segment's last chunk) and the defects of real logs, each an
  optional key: relative wheel-slip scales, the wheels' time offset against the pose, the
  GNSS antenna's lever arm and a heading bias of the measured (fused) heading.

The error stacks, in this order, the tracking residuals ``measurement_k − measured_k`` of the
poses ``k = 1..L`` (if the chunk has measured poses) and the continuity residual
``predicted_L − end`` (if it has an end), in world coordinates ``[px, py, psi]``; headings of
Pose2 variables are unwrapped against a reference heading. The predicted measurement of the
state ``x_k = [p_k, ψ_k]`` is ``[p_k + R(ψ_k) · arm, ψ_k + bias]`` (zero arm and bias unless
given), and a wheel time offset ``τ`` turns the measured rotation of step k into
``n_k + τ · ṅ_k`` (the rotation over ``[t_k + τ, t_k+1 + τ]`` to first order; ``ṅ_k``, the
chunk's ``rotation_rates``, from :func:`graphcal.data.timing.rotation_rate_changes`).

:func:`segment_odometry_factor` is the whole-segment case (the batch residual of eqs. 6–11).
"""

from __future__ import annotations

from dataclasses import dataclass

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

#: Default sigmas [m, m, rad] of the continuity residual: a near-hard constraint, as the model
#: equation is in the paper.
CONTINUITY_SIGMAS = np.array([1e-4, 1e-4, 1e-5])


@dataclass(frozen=True)
class ChunkError:
    """Error of a chunk and its Jacobians with respect to states (not Pose2 tangents).

    Attributes:
        error: ``(dim,)`` tracking residuals then the continuity residual.
        start, theta: ``(dim, 3)``, ``(dim, 4)``.
        corrections: ``(dim, L, 2)`` or ``None`` (no corrections given).
        end: ``(dim, 3)`` or ``None`` (no end given).
        slip: ``(dim, 2)`` or ``None`` (no slip given).
        time_offset, lever_arm, heading_bias: ``(dim, 1)``, ``(dim, 2)``, ``(dim, 1)`` or
            ``None`` (not given).
    """

    error: np.ndarray
    start: np.ndarray | None = None
    theta: np.ndarray | None = None
    corrections: np.ndarray | None = None
    end: np.ndarray | None = None
    slip: np.ndarray | None = None
    time_offset: np.ndarray | None = None
    lever_arm: np.ndarray | None = None
    heading_bias: np.ndarray | None = None


class OdometryChunk:
    """The measurements of ``L`` consecutive steps and the model's error over them.

    Args:
        inputs: measured ``[n_rl, n_rr, beta, ay]`` of the steps, ``(L, 4)``.
        measured_poses: measured states ``(L+1, 3)`` to track (row 0, the start, is not
            tracked), or ``None``.
        reference_heading: heading [rad] against which Pose2 angles are unwrapped (default:
            the measured start heading).
        rotation_rates: ``(L, 2)`` change [rev/s] of each step's rotation per second of wheel
            time offset (needed only to evaluate with a time offset).
    """

    def __init__(
        self,
        inputs: np.ndarray,
        measured_poses: np.ndarray | None = None,
        reference_heading: float | None = None,
        rotation_rates: np.ndarray | None = None,
    ):
        self.inputs = np.array(inputs, dtype=float)
        self.rotation_rates = None
        if rotation_rates is not None:
            self.rotation_rates = np.asarray(rotation_rates, float)
            if self.rotation_rates.shape != (len(self.inputs), 2):
                raise ValueError(
                    f"rotation rates must be ({len(self.inputs)}, 2), "
                    f"got {self.rotation_rates.shape}"
                )
        if self.inputs.ndim != 2 or self.inputs.shape[1] != 4 or len(self.inputs) == 0:
            raise ValueError(f"inputs must be (L, 4) with L >= 1, got {self.inputs.shape}")
        self.measured_poses = None if measured_poses is None else np.asarray(measured_poses, float)
        if self.measured_poses is not None and self.measured_poses.shape != (self.n_steps + 1, 3):
            raise ValueError(
                f"measured poses must be ({self.n_steps + 1}, 3) for {self.n_steps} steps, "
                f"got {self.measured_poses.shape}"
            )
        if reference_heading is None:
            if self.measured_poses is None:
                raise ValueError("a chunk without measured poses needs a reference heading")
            reference_heading = float(self.measured_poses[0, 2])
        self.reference_heading = float(reference_heading)

    @property
    def n_steps(self) -> int:
        """Number of steps L."""
        return len(self.inputs)

    def error(
        self,
        start: np.ndarray,
        theta: np.ndarray,
        corrections: np.ndarray | None = None,
        end: np.ndarray | None = None,
        jacobians: bool = True,
        slip: np.ndarray | None = None,
        time_offset: float | None = None,
        lever_arm: np.ndarray | None = None,
        heading_bias: float | None = None,
    ) -> ChunkError:
        """Residuals for a start state ``(3,)``, theta ``(4,)``, corrections ``(L, 2)`` [rev]
        added to the measured rotations, the end state ``(3,)`` of the next chunk (any
        heading branch: the continuity heading is wrapped), relative slip scales ``(2,)``
        of the two wheels (the rotation of wheel w becomes ``n_w · (1 + slip_w)``), the
        wheels' time offset [s] (positive: wheels late against the pose), the antenna's
        lever arm ``(2,)`` [m] (ahead, left of the centre of gravity) and the bias [rad] of
        the measured heading. Arguments left ``None`` are zero and get no Jacobian."""
        if time_offset is not None and self.rotation_rates is None:
            raise ValueError("a time offset needs the chunk's rotation rates")
        inputs = self.inputs
        if corrections is not None or slip is not None or time_offset is not None:
            inputs = inputs.copy()
        if slip is not None:
            inputs[:, N_RL] += self.inputs[:, N_RL] * slip[0]
            inputs[:, N_RR] += self.inputs[:, N_RR] * slip[1]
        if time_offset is not None:
            inputs[:, [N_RL, N_RR]] += time_offset * self.rotation_rates
        if corrections is not None:
            inputs[:, N_RL] += corrections[:, 0]
            inputs[:, N_RR] += corrections[:, 1]
        states, d_start, d_theta = integrate_with_jacobians(start, inputs, theta, jacobians)
        # Error pieces, the state rows each piece differentiates, and per row the 3×3
        # d piece / d state (None: identity).
        parts, rows, transforms = [], [], []
        tracked = self.measured_poses is not None
        if tracked:
            residual = states[1:] - self.measured_poses[1:]
            transform = None
            if lever_arm is not None:
                cos, sin = np.cos(states[1:, 2]), np.sin(states[1:, 2])
                ahead, left = float(lever_arm[0]), float(lever_arm[1])
                residual[:, 0] += cos * ahead - sin * left
                residual[:, 1] += sin * ahead + cos * left
                transform = np.broadcast_to(np.eye(3), (self.n_steps, 3, 3)).copy()
                transform[:, 0, 2] = -sin * ahead - cos * left
                transform[:, 1, 2] = cos * ahead - sin * left
            if heading_bias is not None:
                residual[:, 2] += heading_bias
            parts.append(residual.reshape(-1))
            rows.append(slice(1, None))
            transforms.append(transform)
        if end is not None:
            gap = states[-1] - end
            gap[2] = wrap_angle(gap[2])
            parts.append(gap)
            rows.append(slice(-1, None))
            transforms.append(None)
        if not parts:
            raise ValueError("a chunk needs measured poses to track or an end to reach")
        error = np.concatenate(parts)
        if not jacobians:
            return ChunkError(error)

        def stack(full: np.ndarray) -> np.ndarray:  # (L+1, 3, ...) -> (dim, ...)
            blocks = []
            for r, transform in zip(rows, transforms, strict=True):
                block = full[r]
                if transform is not None:
                    block = np.einsum("nij,nj...->ni...", transform, block)
                blocks.append(block.reshape(-1, *full.shape[2:]))
            return np.concatenate(blocks)

        dim = len(error)
        n_tracked = 3 * self.n_steps if tracked else 0
        d_end = None
        if end is not None:
            d_end = np.zeros((dim, 3))
            d_end[-3:] = -np.eye(3)
        d_corrections = d_slip = d_time = None
        if corrections is not None or slip is not None or time_offset is not None:
            d_rotations = stack(wheel_rotation_jacobian(states, inputs, theta))  # (dim, L, 2)
            if corrections is not None:
                d_corrections = d_rotations
            if slip is not None:  # d n_w / d slip_w = measured n_w, summed over the steps
                d_slip = np.einsum("dlw,lw->dw", d_rotations, self.inputs[:, [N_RL, N_RR]])
            if time_offset is not None:  # d n_w / d tau = the rotation rate change
                d_time = np.einsum("dlw,lw->d", d_rotations, self.rotation_rates)[:, None]
        d_arm = d_bias = None
        if lever_arm is not None and tracked:
            d_arm = np.zeros((dim, 2))
            cos, sin = np.cos(states[1:, 2]), np.sin(states[1:, 2])
            d_arm[0:n_tracked:3] = np.column_stack([cos, -sin])
            d_arm[1:n_tracked:3] = np.column_stack([sin, cos])
        elif lever_arm is not None:
            d_arm = np.zeros((dim, 2))
        if heading_bias is not None:
            d_bias = np.zeros((dim, 1))
            d_bias[2:n_tracked:3] = 1.0
        return ChunkError(
            error,
            stack(d_start),
            stack(d_theta),
            d_corrections,
            d_end,
            d_slip,
            d_time,
            d_arm,
            d_bias,
        )


class ChunkOdometryFactor:
    """An :class:`OdometryChunk` between graph variables (the ``gtsam.CustomFactor`` callable).

    Args:
        chunk: the measurements.
        start: the start's Pose2 key, or a held start state ``(3,)``.
        theta: theta's 4-vector key, or a fixed theta ``(4,)`` (SI).
        corrections: key of the chunk's ``2L``-vector of wheel-rotation corrections, or ``None``.
        end: key of the Pose2 the chunk must reach (the next chunk's start), or ``None``.
        tracking_sigmas: ``[m, m, rad]`` of the tracking residuals (default
            :func:`~graphcal.factors.poses.pose_sigmas`).
        continuity_sigmas: ``[m, m, rad]`` of the continuity residual
            (default :data:`CONTINUITY_SIGMAS`).
        slip: key of the chunk's 2-vector of relative wheel-slip scales, or ``None``.
        time_offset: key of the 1-vector wheel time offset [s], or ``None``.
        lever_arm: key of the 2-vector antenna lever arm [m], or ``None``.
        heading_bias: key of the 1-vector heading bias [rad], or ``None``.
        fix_weights: ``(L,)`` weight in (0, 1] of each tracked position (robust
            down-weighting: its sigmas are divided by the weight's square root), or ``None``
            for all 1.

    Keys, in order: start, end, corrections, theta, slip, time_offset, lever_arm,
    heading_bias — each only if it is a key.
    """

    def __init__(
        self,
        chunk: OdometryChunk,
        start: int | np.ndarray,
        theta: int | np.ndarray,
        corrections: int | None = None,
        end: int | None = None,
        tracking_sigmas: np.ndarray | None = None,
        continuity_sigmas: np.ndarray | None = None,
        slip: int | None = None,
        time_offset: int | None = None,
        lever_arm: int | None = None,
        heading_bias: int | None = None,
        fix_weights: np.ndarray | None = None,
    ):
        self.chunk = chunk
        self.slip_key = slip
        self.time_offset_key = time_offset
        self.lever_arm_key = lever_arm
        self.heading_bias_key = heading_bias
        self.start_key, self.start_state = _slot(start, 3, "start")
        self.theta_key, self.theta = _slot(theta, 4, "theta")
        self.corrections_key = corrections
        self.end_key = end
        if chunk.measured_poses is None and end is None:
            raise ValueError("a chunk needs measured poses to track or an end to reach")
        sigmas = []
        if chunk.measured_poses is not None:
            track = pose_sigmas() if tracking_sigmas is None else np.asarray(tracking_sigmas, float)
            track = np.tile(track, (chunk.n_steps, 1))
            if fix_weights is not None:
                weights = np.asarray(fix_weights, float)
                if weights.shape != (chunk.n_steps,) or not np.all(weights > 0):
                    raise ValueError(f"fix weights must be ({chunk.n_steps},) positive numbers")
                track[:, :2] /= np.sqrt(weights)[:, None]
            sigmas.append(track.reshape(-1))
        if end is not None:
            cont = CONTINUITY_SIGMAS if continuity_sigmas is None else continuity_sigmas
            sigmas.append(np.asarray(cont, float))
        self.sigmas = np.concatenate(sigmas)

    @property
    def keys(self) -> list[int]:
        """The factor's keys in slot order (those slots that are keys)."""
        slots = (
            self.start_key,
            self.end_key,
            self.corrections_key,
            self.theta_key,
            self.slip_key,
            self.time_offset_key,
            self.lever_arm_key,
            self.heading_bias_key,
        )
        return [k for k in slots if k is not None]

    def factor(self) -> gtsam.CustomFactor:
        """The ``gtsam.CustomFactor`` of this chunk."""
        noise = gtsam.noiseModel.Diagonal.Sigmas(self.sigmas)
        return gtsam.CustomFactor(noise, self.keys, self)

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        reference = self.chunk.reference_heading
        start = (
            self.start_state
            if self.start_key is None
            else state_from_pose2(values.atPose2(self.start_key), reference)
        )
        theta = self.theta if self.theta_key is None else values.atVector(self.theta_key)
        corrections = None
        if self.corrections_key is not None:
            corrections = values.atVector(self.corrections_key).reshape(self.chunk.n_steps, 2)
        end = None
        if self.end_key is not None:  # its heading branch does not matter: the gap is wrapped
            end = state_from_pose2(values.atPose2(self.end_key), start[2])
        slip = None if self.slip_key is None else values.atVector(self.slip_key)
        time_offset = lever_arm = heading_bias = None
        if self.time_offset_key is not None:
            time_offset = float(values.atVector(self.time_offset_key)[0])
        if self.lever_arm_key is not None:
            lever_arm = values.atVector(self.lever_arm_key)
        if self.heading_bias_key is not None:
            heading_bias = float(values.atVector(self.heading_bias_key)[0])
        result = self.chunk.error(
            start,
            theta,
            corrections,
            end,
            H is not None,
            slip,
            time_offset,
            lever_arm,
            heading_bias,
        )
        if H is not None:
            blocks = []
            if self.start_key is not None:
                blocks.append(result.start @ body_to_world(start[2]))
            if self.end_key is not None:
                blocks.append(result.end @ body_to_world(end[2]))
            if self.corrections_key is not None:
                blocks.append(result.corrections.reshape(len(result.error), -1))
            if self.theta_key is not None:
                blocks.append(result.theta)
            if self.slip_key is not None:
                blocks.append(result.slip)
            if self.time_offset_key is not None:
                blocks.append(result.time_offset)
            if self.lever_arm_key is not None:
                blocks.append(result.lever_arm)
            if self.heading_bias_key is not None:
                blocks.append(result.heading_bias)
            for i, block in enumerate(blocks):
                H[i] = np.ascontiguousarray(block)
        return result.error


def _slot(value: int | np.ndarray, size: int, name: str) -> tuple[int | None, np.ndarray | None]:
    """``(key, None)`` for a key, ``(None, fixed value)`` for an array."""
    if isinstance(value, int | np.integer):
        return int(value), None
    array = np.asarray(value, float)
    if array.shape != (size,):
        raise ValueError(f"{name} must be a key or a ({size},) array, got shape {array.shape}")
    return None, array


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
    chunk = OdometryChunk(inputs, measured_poses)
    start = measured_poses[0] if start_key is None else start_key
    return ChunkOdometryFactor(chunk, start, theta_key, tracking_sigmas=sigmas).factor()
