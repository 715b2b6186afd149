"""The chunk factor: an :class:`~graphcal.factors.chunk.OdometryChunk` between graph variables.

Python factors cost ~50 µs per call plus a copy of the optimizer's values
(``docs/performance.md``), so graphcal integrates many 40 Hz steps per factor, vectorized, and
the chunk factors of one graph share a :class:`~graphcal.factors.chunk_batch.ChunkBatch` that
evaluates them all in one numpy pass.

Each of a :class:`ChunkOdometryFactor`'s slots is named: the start (a Pose2 key, or a held
state), theta (a 4-vector key, or a fixed value), the chunk's wheel-rotation corrections (one
``2L``-vector key, laid out ``[dn_rl_0, dn_rr_0, dn_rl_1, ...]``, or none), the end (the
Pose2 key of the next chunk's start, or none for a segment's last chunk) and the defects of
real logs, each an optional key: relative wheel-slip scales, the wheels' time offset against
the pose, the GNSS antenna's lever arm, a heading bias of the measured (fused) heading and the rear
tyres' slip gain of a log without a sideslip.
Headings of Pose2 variables are unwrapped against the chunk's reference heading.

:func:`segment_odometry_factor` is the whole-segment case (the batch residual of eqs. 6–11).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.factors.chunk import CONTINUITY_SIGMAS, ChunkError, OdometryChunk, chunk_errors
from graphcal.factors.chunk_batch import ChunkArguments, ChunkBatch
from graphcal.factors.chunk_inputs import StackedChunks
from graphcal.factors.poses import pose_sigmas


@dataclass(frozen=True)
class DefectKeys:
    """The keys of a chunk factor's defect variables (each ``None``: not estimated).

    Attributes:
        slip: key of the chunk's 2-vector of relative wheel-slip scales.
        time_offset: key of the wheel time offset [s]: a vector of one element per run of
            the log, of which this chunk's wheels read element ``time_offset_slot[0]`` of
            ``time_offset_slot[1]`` (default the one of one).
        lever_arm: key of the 2-vector antenna lever arm [m].
        heading_bias: key of the 1-vector heading bias [rad].
        fix_offset: keys of the 2-vector world-frame error [m] of the fixes at the chunk's
            start and at its end (a slowly varying GNSS error, linear between:
            :mod:`graphcal.graph.construction.gauss_markov`).
        rear_slip_gain: key of the 1-vector rear slip gain [rad per m/s²] of a log without a
            sideslip (:class:`~graphcal.factors.chunk_inputs.DefectValues`).
    """

    slip: int | None = None
    time_offset: int | None = None
    lever_arm: int | None = None
    heading_bias: int | None = None
    fix_offset: tuple[int, int] | None = None
    time_offset_slot: tuple[int, int] = (0, 1)
    rear_slip_gain: int | None = None


@dataclass(frozen=True)
class ChunkNoise:
    """The sigmas of a chunk factor's residuals.

    Attributes:
        tracking: ``[m, m, rad]`` of the tracking residuals (default
            :func:`~graphcal.factors.poses.pose_sigmas`).
        continuity: ``[m, m, rad]`` of the continuity residual (default
            :data:`~graphcal.factors.chunk.CONTINUITY_SIGMAS`).
        fix_weights: ``(L,)`` weight in (0, 1] of each tracked position (robust
            down-weighting: its sigmas are divided by the weight's square root), or ``None``
            for all 1.
    """

    tracking: np.ndarray | None = None
    continuity: np.ndarray | None = None
    fix_weights: np.ndarray | None = None


class ChunkOdometryFactor:
    """An :class:`~graphcal.factors.chunk.OdometryChunk` between graph variables (the
    ``gtsam.CustomFactor`` callable).

    Args:
        chunk: the measurements.
        start: the start's Pose2 key, or a held start state ``(3,)``.
        theta: theta's 4-vector key, or a fixed theta ``(4,)`` (SI).
        corrections: key of the chunk's ``2L``-vector of wheel-rotation corrections, or ``None``.
        end: key of the Pose2 the chunk must reach (the next chunk's start), or ``None``.
        noise: the residuals' sigmas and fix weights (:class:`ChunkNoise`; default: the
            defaults there).
        defects: keys of the defect variables (:class:`DefectKeys`; default: none).
        batch: the :class:`~graphcal.factors.chunk_batch.ChunkBatch` this factor is
            evaluated in, shared by the chunk factors of a graph (default: one of its own).

    Keys, in order: start, end, corrections, theta, slip, time_offset, lever_arm,
    heading_bias, the fixes' error at the start and at the end, the rear slip gain — each only
    if it is a key.
    """

    def __init__(
        self,
        chunk: OdometryChunk,
        start: int | np.ndarray,
        theta: int | np.ndarray,
        corrections: int | None = None,
        end: int | None = None,
        *,
        noise: ChunkNoise = ChunkNoise(),
        defects: DefectKeys = DefectKeys(),
        batch: ChunkBatch | None = None,
    ):
        self.chunk = chunk
        self.slip_key = defects.slip
        self.time_offset_key = defects.time_offset
        slot = defects.time_offset_slot
        self.time_offset_slot, self.time_offset_size = (int(n) for n in slot)
        if not 0 <= self.time_offset_slot < self.time_offset_size:
            raise ValueError(f"time offset element {slot} out of range")
        self.lever_arm_key = defects.lever_arm
        self.heading_bias_key = defects.heading_bias
        self.fix_offset_keys = defects.fix_offset or (None, None)
        self.rear_slip_gain_key = defects.rear_slip_gain
        tracking_sigmas, continuity_sigmas = noise.tracking, noise.continuity
        fix_weights = noise.fix_weights
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
        self.rows = chunk.residual_rows if end is not None else _without_continuity(chunk)
        self.sigmas = np.concatenate(sigmas)
        if self.rows is not None:
            self.sigmas = self.sigmas[self.rows]
        # The vector slots in read order: name, key (or None), size.
        self._vector_slots = (
            ("corrections", self.corrections_key, 2 * chunk.n_steps),
            ("theta", self.theta_key, 4),
            ("slip", self.slip_key, 2),
            ("time_offset", self.time_offset_key, self.time_offset_size),
            ("lever_arm", self.lever_arm_key, 2),
            ("heading_bias", self.heading_bias_key, 1),
            ("fix_offset_start", self.fix_offset_keys[0], 2),
            ("fix_offset_end", self.fix_offset_keys[1], 2),
            ("rear_slip_gain", self.rear_slip_gain_key, 1),
        )
        self._vector_keys = [key for _, key, _ in self._vector_slots if key is not None]
        self.batch = ChunkBatch() if batch is None else batch
        self.batch_index = self.batch.add(self)

    def _slot_keys(self) -> tuple[int | None, ...]:
        return (
            self.start_key,
            self.end_key,
            self.corrections_key,
            self.theta_key,
            self.slip_key,
            self.time_offset_key,
            self.lever_arm_key,
            self.heading_bias_key,
            *self.fix_offset_keys,
            self.rear_slip_gain_key,
        )

    @property
    def keys(self) -> list[int]:
        """The factor's keys in slot order (those slots that are keys)."""
        return [k for k in self._slot_keys() if k is not None]

    def factor(self) -> gtsam.CustomFactor:
        """The ``gtsam.CustomFactor`` of this chunk."""
        noise = gtsam.noiseModel.Diagonal.Sigmas(self.sigmas)
        return gtsam.CustomFactor(noise, self.keys, self)

    def raw(self, values: gtsam.Values) -> np.ndarray:
        """The factor's variables at ``values`` as read, in one vector: Pose2 slots as
        ``[x, y, θ]``, vectors as they are (what tells two reads apart, cheaply)."""
        parts = []
        for key in (self.start_key, self.end_key):
            if key is not None:
                pose = values.atPose2(key)
                parts.append((pose.x(), pose.y(), pose.theta()))
        for key in self._vector_keys:
            parts.append(values.atVector(key))
        return np.concatenate(parts) if parts else np.zeros(0)

    def arguments(self, raw: np.ndarray) -> ChunkArguments:
        """The factor's arguments from a :meth:`raw` read (headings unwrapped: the start
        against the chunk's reference heading, the end against the start)."""
        at = 0
        start = self.start_state
        if self.start_key is not None:
            start = _state(raw[0:3], self.chunk.reference_heading)
            at = 3
        end = None
        if self.end_key is not None:  # its heading branch does not matter: the gap is wrapped
            end = _state(raw[at : at + 3], float(start[2]))
            at += 3
        read = {}
        for name, key, size in self._vector_slots:
            if key is not None:
                read[name] = raw[at : at + size]
                at += size
        corrections = read.get("corrections")
        if corrections is not None:
            corrections = corrections.reshape(self.chunk.n_steps, 2)
        time_offset, bias = read.get("time_offset"), read.get("heading_bias")
        gain = read.get("rear_slip_gain")
        return ChunkArguments(
            start,
            read.get("theta", self.theta),
            corrections,
            end,
            read.get("slip"),
            None if time_offset is None else time_offset[self.time_offset_slot],
            read.get("lever_arm"),
            None if bias is None else bias[0],
            None
            if "fix_offset_start" not in read
            else np.stack([read["fix_offset_start"], read["fix_offset_end"]]),
            None if gain is None else gain[0],
        )

    def read(self, values: gtsam.Values) -> ChunkArguments:
        """The factor's arguments at ``values``."""
        return self.arguments(self.raw(values))

    def shape_signature(self) -> tuple:
        """Chunks with equal signatures stack into one vectorized evaluation."""
        return (
            self.chunk.n_steps,
            self.chunk.measured_poses is None,
            self.chunk.rotation_rates is None,
            self.chunk.fractions is None,
            *(key is None for key in self._slot_keys()),
            self.time_offset_slot,
            self.time_offset_size,
        )

    def jacobian_blocks(
        self, result: ChunkError, start: np.ndarray, end: np.ndarray | None
    ) -> list[np.ndarray]:
        """GTSAM's Jacobian blocks ``(C, dim, key dim)`` in key order from a batched
        :func:`~graphcal.factors.chunk.chunk_errors` of ``C`` chunks shaped like this one,
        Pose2 slots in their tangent spaces (start ``(C, 3)``, end ``(C, 3)`` states)."""
        count, dim = result.error.shape
        blocks = []
        if self.start_key is not None:
            blocks.append(_in_tangent(result.start, start[:, 2]))
        if self.end_key is not None:
            blocks.append(_in_tangent(result.end, end[:, 2]))
        if self.corrections_key is not None:
            blocks.append(result.corrections.reshape(count, dim, -1))
        if self.theta_key is not None:
            blocks.append(result.theta)
        time_offset = result.time_offset
        if self.time_offset_key is not None and self.time_offset_size > 1:
            time_offset = np.zeros((count, dim, self.time_offset_size))
            time_offset[..., self.time_offset_slot] = result.time_offset[..., 0]
        for key, block in (
            (self.slip_key, result.slip),
            (self.time_offset_key, time_offset),
            (self.lever_arm_key, result.lever_arm),
            (self.heading_bias_key, result.heading_bias),
        ):
            if key is not None:
                blocks.append(block)
        if self.fix_offset_keys[0] is not None:
            blocks += [result.fix_offset[..., :2], result.fix_offset[..., 2:]]
        if self.rear_slip_gain_key is not None:
            blocks.append(result.rear_slip_gain)
        return blocks

    def theta_augmented_hessians(self, thetas: np.ndarray) -> np.ndarray:
        """``[AᵀA Aᵀb; bᵀA bᵀb] (C, 5, 5)`` of this factor's whitened linearization at each
        theta of ``thetas (C, 4)`` (``b``: minus the whitened error) — GTSAM's
        ``augmentedHessian`` of :meth:`factor` linearized there — in one vectorized
        evaluation of the chunk stacked ``C`` times. For a factor whose only variable is
        theta: a held start, no end, no corrections, no defects (the paper's Step 1)."""
        others = [k for k in self._slot_keys() if k is not None and k != self.theta_key]
        if self.theta_key is None or others:
            raise ValueError("theta_augmented_hessians needs a factor on theta alone")
        thetas = np.asarray(thetas, float)
        count, chunk = len(thetas), self.chunk

        def stacked(array: np.ndarray | None) -> np.ndarray | None:
            return None if array is None else np.broadcast_to(array, (count, *array.shape))

        result = chunk_errors(
            StackedChunks(
                stacked(chunk.inputs), stacked(chunk.measured_poses), None, stacked(chunk.fractions)
            ),
            np.broadcast_to(self.start_state, (count, 3)),
            thetas,
        )
        error, jacobian = result.error, result.theta
        if self.rows is not None:
            error, jacobian = error[:, self.rows], jacobian[:, self.rows]
        rows = np.concatenate([jacobian, -error[..., None]], axis=2) / self.sigmas[:, None]
        return rows.transpose(0, 2, 1) @ rows  # batched BLAS: (75, 4200, 5) 54 -> 7 ms (einsum)

    def __call__(
        self, factor: gtsam.CustomFactor, values: gtsam.Values, H: list | None
    ) -> np.ndarray:
        error, blocks = self.batch.evaluate(self.batch_index, values, H is not None)
        if H is not None:
            for i, block in enumerate(blocks):
                H[i] = block
        return error


def _without_continuity(chunk: OdometryChunk) -> np.ndarray | None:
    """:attr:`OdometryChunk.residual_rows` of a chunk without an end (no continuity rows)."""
    rows = chunk.residual_rows
    return None if rows is None else rows[:-3]


def _state(pose: np.ndarray, reference_heading: float) -> np.ndarray:
    """State ``[px, py, psi]`` of a raw Pose2 ``[x, y, θ]``, the heading on the branch nearest
    ``reference_heading`` (:func:`~graphcal.factors.poses.state_from_pose2`, in scalars)."""
    psi = reference_heading + (float(pose[2]) - reference_heading + math.pi) % math.tau - math.pi
    return np.array([pose[0], pose[1], psi])


def _in_tangent(block: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``(C, dim, 3)`` Jacobians by states turned into Jacobians by Pose2 tangents at
    ``heading (C,)`` (Pose2 retracts in its body frame:
    :func:`~graphcal.factors.poses.body_to_world`)."""
    cos, sin = np.cos(heading)[:, None], np.sin(heading)[:, None]
    out = block.copy()
    out[..., 0] = block[..., 0] * cos + block[..., 1] * sin
    out[..., 1] = -block[..., 0] * sin + block[..., 1] * cos
    return out


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
    return ChunkOdometryFactor(chunk, start, theta_key, noise=ChunkNoise(sigmas)).factor()
