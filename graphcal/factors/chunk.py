"""Eq. (1) integrated over a chunk of steps: the measurement half of the chunk factor.

:class:`OdometryChunk` holds a chunk's measurements — its ``L`` measured inputs and,
optionally, the ``L+1`` measured poses to track — and evaluates the error with its Jacobians
for given values (pure numpy, no keys), as ``PreintegratedImuMeasurements`` is for
``ImuFactor``; :func:`chunk_errors` does the same for many chunks of one shape at once.
:class:`~graphcal.factors.chunk_factor.ChunkOdometryFactor` places a chunk between graph
variables.

The error stacks, in this order, the tracking residuals ``measurement_k − measured_k`` of the
poses ``k = 1..L`` (if the chunk has measured poses) and the continuity residual
``predicted_L − end`` (if it has an end), in world coordinates ``[px, py, psi]``. A
measurement taken between two samples (a GNSS fix at its own time) is predicted part-way
through its step (``fractions``: :func:`graphcal.model.partial_steps`), and a chunk whose
samples do not all measure position and heading (``measured``) keeps only the rows of the
components that were measured (:attr:`OdometryChunk.residual_rows`). The
predicted measurement of the state ``x_k = [p_k, ψ_k]`` is ``[p_k + R(ψ_k) · arm + e_k,
ψ_k + bias]`` (zero arm, error and bias unless given; ``e_k`` is the fixes' slowly varying
error, linear through the chunk from its value at the start to its value at the end), and
a wheel time offset ``τ`` turns the measured rotation of step k into ``n_k + τ · ṅ_k`` (the
rotation over ``[t_k + τ, t_k+1 + τ]`` to first order; ``ṅ_k``, the chunk's
``rotation_rates``, from :func:`graphcal.log.timing.rotation_rate_changes`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.factors.chunk_inputs import NO_DEFECTS, DefectValues, StackedChunks
from graphcal.factors.chunk_rows import JacobianRows, PredictedFixes, predict_fixes
from graphcal.factors.chunk_terms import (
    chunk_fractions,
    fix_offset_jacobian,
    fix_offsets,
    heading_bias_jacobian,
    lever_arm_jacobian,
    tracking_residuals,
)
from graphcal.factors.rear_slip import rear_slip_gain_jacobian
from graphcal.model import (
    AY,
    BETA,
    N_RL,
    N_RR,
    integrate_with_jacobians,
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
        fix_offset: ``(dim, 4)``: by the fixes' error at the chunk's start then at its end,
            or ``None`` (not given).
        rear_slip_gain: ``(dim, 1)`` or ``None`` (not given).
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
    fix_offset: np.ndarray | None = None
    rear_slip_gain: np.ndarray | None = None


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
        fractions: ``(L,)`` in ``(0, 1]``: pose ``k``'s measurement was taken at this fraction
            of step ``k-1`` (1: at sample ``k``), or ``None`` for all at their samples.
        measured: ``(L+1, 2)`` booleans: which of pose ``k``'s position and heading were
            measured (row 0 unused), or ``None`` for all; the others have no residual row.
    """

    def __init__(
        self,
        inputs: np.ndarray,
        measured_poses: np.ndarray | None = None,
        reference_heading: float | None = None,
        rotation_rates: np.ndarray | None = None,
        fractions: np.ndarray | None = None,
        measured: np.ndarray | None = None,
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
        self.fractions = None
        if fractions is not None and not np.all(np.asarray(fractions) == 1.0):
            self.fractions = np.asarray(fractions, float)
            if self.fractions.shape != (self.n_steps,) or not np.all(
                (self.fractions > 0) & (self.fractions <= 1)
            ):
                raise ValueError(f"fractions must be ({self.n_steps},) numbers in (0, 1]")
        self.measured = None
        if measured is not None and not np.all(measured):
            self.measured = np.asarray(measured, bool)
            if self.measured.shape != (self.n_steps + 1, 2):
                raise ValueError(f"measured must be ({self.n_steps + 1}, 2) booleans")

    @property
    def residual_rows(self) -> np.ndarray | None:
        """Rows of :func:`chunk_errors`' full error (tracking rows then continuity) that
        this chunk keeps, or ``None`` for all: a position not measured drops its x and y
        rows, a heading not measured its heading row."""
        if self.measured is None or self.measured_poses is None:
            return None
        keep = np.repeat(self.measured[1:], [2, 1], axis=1).reshape(-1)
        return np.flatnonzero(np.concatenate([keep, np.ones(3, bool)]))

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
        defects: DefectValues = NO_DEFECTS,
    ) -> ChunkError:
        """Residuals for a start state ``(3,)``, theta ``(4,)``, corrections ``(L, 2)`` [rev]
        added to the measured rotations, the end state ``(3,)`` of the next chunk (any
        heading branch: the continuity heading is wrapped) and the ``defects``' values
        (:class:`DefectValues`). Arguments left ``None`` are zero and get no Jacobian."""
        if defects.time_offset is not None and self.rotation_rates is None:
            raise ValueError("a time offset needs the chunk's rotation rates")

        def one(x):
            return None if x is None else np.asarray(x, float)[None]

        def scalar(x):
            return None if x is None else np.array([float(x)])

        batch = chunk_errors(
            StackedChunks(
                self.inputs[None],
                one(self.measured_poses),
                one(self.rotation_rates),
                one(self.fractions),
            ),
            one(start),
            one(theta),
            one(corrections),
            one(end),
            jacobians,
            DefectValues(
                one(defects.slip),
                scalar(defects.time_offset),
                one(defects.lever_arm),
                scalar(defects.heading_bias),
                one(defects.fix_offset),
                scalar(defects.rear_slip_gain),
            ),
        )
        fields = (getattr(batch, f.name) for f in dataclasses.fields(batch))
        return ChunkError(*(None if x is None else x[0] for x in fields))


def chunk_errors(
    chunks: StackedChunks,
    start: np.ndarray,
    theta: np.ndarray,
    corrections: np.ndarray | None = None,
    end: np.ndarray | None = None,
    jacobians: bool = True,
    defects: DefectValues = NO_DEFECTS,
) -> ChunkError:
    """:meth:`OdometryChunk.error` of ``C`` chunks of ``L`` steps at once, vectorized over the
    chunks: their measurements ``chunks`` (:class:`StackedChunks`), ``start (C, 3)``,
    ``theta (C, 4)``, ``corrections (C, L, 2)``, ``end (C, 3)`` and the ``defects``
    (:class:`DefectValues`: ``slip (C, 2)``, ``time_offset (C,)`` with the chunks'
    rotation rates, ``lever_arm (C, 2)``, ``heading_bias (C,)``, ``fix_offset (C, 2, 2)``,
    ``rear_slip_gain (C,)``).
    Every field of the result
    has the leading chunk axis; the error has every tracking row (a chunk's
    :attr:`~OdometryChunk.residual_rows` picks its own)."""
    inputs, measured_poses = chunks.inputs, chunks.measured_poses
    rotation_rates, fractions = chunks.rotation_rates, chunks.fractions
    slip, time_offset = defects.slip, defects.time_offset
    lever_arm, heading_bias = defects.lever_arm, defects.heading_bias
    fix_offset = defects.fix_offset
    count, n_steps = inputs.shape[:2]
    rear_slip_gain = defects.rear_slip_gain
    rotations = _wheel_rotations(inputs, corrections, slip, time_offset, rotation_rates)
    if rear_slip_gain is not None:  # the rear axle's sideslip: beta − gain · a_y
        rotations = rotations.copy() if rotations is inputs else rotations
        rotations[..., BETA] -= rear_slip_gain[:, None] * inputs[..., AY]
    states, d_start, d_theta = integrate_with_jacobians(start, rotations, theta, jacobians)
    tracked = measured_poses is not None
    fixes = predict_fixes(states, rotations, theta, fractions if tracked else None, jacobians)
    along = None if fix_offset is None else chunk_fractions(count, n_steps, fractions)
    offsets = None if fix_offset is None else fix_offsets(fix_offset, along)
    error, layout = _error_pieces(
        (count, n_steps), states, fixes, measured_poses, end, lever_arm, heading_bias, offsets
    )
    if not jacobians:
        return ChunkError(error)
    dim = error.shape[1]
    n_tracked = 3 * n_steps if tracked else 0
    d_end = None if end is None else _end_jacobian(count, dim)
    d_corrections = d_slip = d_time = None
    if corrections is not None or slip is not None or time_offset is not None:
        d_rotations = layout.rotations(states, rotations, theta)  # (C, dim, L, 2)
        if corrections is not None:
            d_corrections = d_rotations
        if slip is not None:  # d n_w / d slip_w = measured n_w, summed over the steps
            d_slip = np.empty((count, dim, 2))
            for w, column in enumerate((N_RL, N_RR)):  # matmul: 5× einsum's speed here
                d_slip[..., w] = np.matmul(d_rotations[..., w], inputs[..., column, None])[..., 0]
        if time_offset is not None:  # d n_w / d tau = the rotation rate change
            flat = d_rotations.reshape(count, dim, 2 * n_steps)
            d_time = np.matmul(flat, rotation_rates.reshape(count, 2 * n_steps, 1))
    d_arm = None
    if lever_arm is not None:
        d_arm = lever_arm_jacobian(fixes.states if tracked else None, count, dim, n_tracked)
    d_bias = None if heading_bias is None else heading_bias_jacobian(count, dim, n_tracked)
    d_offset = None if fix_offset is None else fix_offset_jacobian(along, dim, n_tracked)
    d_rear_slip = None
    if rear_slip_gain is not None:
        d_rear_slip = layout.stack(*rear_slip_gain_jacobian(states, rotations, theta, fractions))
    return ChunkError(
        error,
        layout.stack(d_start),
        layout.stack(d_theta, fixes.d_theta),
        d_corrections,
        d_end,
        d_slip,
        d_time,
        d_arm,
        d_bias,
        d_offset,
        d_rear_slip,
    )


def _wheel_rotations(
    inputs: np.ndarray,
    corrections: np.ndarray | None,
    slip: np.ndarray | None,
    time_offset: np.ndarray | None,
    rotation_rates: np.ndarray | None,
) -> np.ndarray:
    """The inputs ``(C, L, 4)`` with the wheel rotations [rev] the model integrates: the
    measured ones scaled by the slip, shifted by the time offset and corrected (``inputs``
    itself, not a copy, when none of these is given)."""
    if corrections is None and slip is None and time_offset is None:
        return inputs
    rotations = inputs.copy()
    if slip is not None:
        rotations[..., N_RL] += inputs[..., N_RL] * slip[:, 0:1]
        rotations[..., N_RR] += inputs[..., N_RR] * slip[:, 1:2]
    if time_offset is not None:
        rotations[..., [N_RL, N_RR]] += time_offset[:, None, None] * rotation_rates
    if corrections is not None:
        rotations[..., N_RL] += corrections[..., 0]
        rotations[..., N_RR] += corrections[..., 1]
    return rotations


def _error_pieces(
    shape: tuple[int, int],
    states: np.ndarray,
    fixes: PredictedFixes,
    measured_poses: np.ndarray | None,
    end: np.ndarray | None,
    lever_arm: np.ndarray | None,
    heading_bias: np.ndarray | None,
    fix_offset: np.ndarray | None = None,
) -> tuple[np.ndarray, JacobianRows]:
    """The error ``(C, dim)``: the tracking residuals (given measured poses; ``fix_offset
    (C, L, 2)`` the fixes' error at each) then the continuity residual (given an end); and
    the rows of the Jacobians that go with it. ``shape``: ``(C, L)``."""
    count, n_steps = shape
    parts, rows, turns = [], [], []
    if measured_poses is not None:
        residual, turn = tracking_residuals(fixes.states, measured_poses, lever_arm, heading_bias)
        if fix_offset is not None:  # the fixes' shared error: predicted fix = p + offset
            residual[..., :2] += fix_offset
        parts.append(residual.reshape(count, -1))
        rows.append(slice(1, None))
        turns.append(turn)
    if end is not None:
        gap = states[:, -1] - end
        gap[:, 2] = wrap_angle(gap[:, 2])
        parts.append(gap)
        rows.append(slice(-1, None))
        turns.append(None)
    if not parts:
        raise ValueError("a chunk needs measured poses to track or an end to reach")
    return np.concatenate(parts, axis=1), JacobianRows(count, n_steps, fixes, rows, turns)


def _end_jacobian(count: int, dim: int) -> np.ndarray:
    """d error / d end state ``(C, dim, 3)``: minus the identity on the continuity rows."""
    d_end = np.zeros((count, dim, 3))
    d_end[:, -3:] = -np.eye(3)
    return d_end
