"""A built segment graph: its factors, initial values and chunking, and what is read off
its solutions (start states, corrections, fix residuals)."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.factors import pose2_from_state, state_from_pose2
from graphcal.factors.chunk_factor import ChunkOdometryFactor
from graphcal.graph.construction import keys
from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.log.segments import SegmentData
from graphcal.model import lever_offset


@dataclass(frozen=True)
class ChunkFactorSlot:
    """Where a chunk factor sits: its index in the graph, its segment and its steps
    ``first .. end`` (tracking the poses ``first+1 .. end``), which rows of the full
    tracking error it keeps (``None``: all; :attr:`OdometryChunk.residual_rows`) and the
    factor object itself (its measurements and sigmas, for evaluations outside GTSAM)."""

    index: int
    segment: int
    first: int
    end: int
    rows: np.ndarray | None = None
    factor: ChunkOdometryFactor | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class BuiltGraph:
    """A built segment graph: factors, initial values and the chunking of each segment."""

    graph: gtsam.NonlinearFactorGraph
    values: gtsam.Values
    bounds: list[np.ndarray]
    spec: SegmentGraphSpec
    data: SegmentData
    chunk_factors: tuple[ChunkFactorSlot, ...] = ()

    def fix_residuals(
        self, result: gtsam.Values, partitioned: PartitionedGraph | None = None
    ) -> np.ndarray:
        """Position residuals ``(S, K+1, 2)`` [m] of every measured pose at ``result`` (the
        predicted antenna position minus the measured one; zero at padding and at held
        starts), for robust reweighting: :meth:`pose_residuals` without the heading."""
        return self.pose_residuals(result, partitioned)[..., :2]

    def pose_residuals(
        self, result: gtsam.Values, partitioned: PartitionedGraph | None = None
    ) -> np.ndarray:
        """Pose residuals ``(S, K+1, 3)`` [m, m, rad] of every measured pose at ``result``
        (predicted minus measured; zero where a component was not measured, at padding and
        at held starts). With ``partitioned`` (this graph split at the same values) each
        chunk is evaluated on its segment's own ``Values``: GTSAM copies the ``Values`` for
        every Python factor call."""
        data = self.data
        out = np.zeros((len(data), data.poses.shape[1], 3))
        values_of = {} if partitioned is None else partitioned.values_by_key()
        for slot in self.chunk_factors:
            factor = self.graph.at(slot.index)
            values = values_of.get(int(factor.keys()[0]), result)
            error = np.asarray(factor.unwhitenedError(values))
            n = slot.end - slot.first
            if slot.rows is not None:  # rows of unmeasured components stay zero
                full = np.zeros(3 * n + 3)
                full[slot.rows] = error
                error = full
            out[slot.segment, slot.first + 1 : slot.end + 1] = error[: 3 * n].reshape(n, 3)
        if self.spec.start_prior_sigmas is not None:
            starts = self.start_states(result)
            arm = np.zeros(2)
            if self.spec.lever_arm_sigma is not None:
                arm = np.asarray(result.atVector(keys.LEVER_ARM))
            antenna = starts[:, :2] + lever_offset(starts[:, 2], arm)
            # A tied start's fix is the segment before's last, tracked there.
            measured = data.start_measured() & ~self.spec.tied(data)[:, None]
            out[:, 0, :2] = np.where(measured[:, :1], antenna - data.poses[:, 0, :2], 0.0)
            heading = np.angle(np.exp(1j * (starts[:, 2] - data.poses[:, 0, 2])))
            out[:, 0, 2] = np.where(measured[:, 1], heading, 0.0)
        return out

    def correction_chi2(
        self, result: gtsam.Values, partitioned: PartitionedGraph | None = None
    ) -> tuple[float, int]:
        """χ² of the wheel-rotation corrections' priors at ``result`` and their number of
        rows: how far the corrections went against the wheel noise assumed."""
        values_of = {} if partitioned is None else partitioned.values_by_key()
        chunk = {slot.index for slot in self.chunk_factors}
        correction = ord(chr(gtsam.Symbol(keys.segment_corrections(0, 0)).chr()))
        total, rows = 0.0, 0
        for i in range(self.graph.size()):
            factor = self.graph.at(i)
            if factor is None or i in chunk:
                continue
            factor_keys = [int(k) for k in factor.keys()]
            if any(gtsam.Symbol(k).chr() != correction for k in factor_keys):
                continue
            total += 2.0 * factor.error(values_of.get(factor_keys[0], result))
            rows += int(factor.dim())
        return total, rows

    def start_states(self, result: gtsam.Values) -> np.ndarray:
        """Estimated (or held) start state of each segment, ``(S, 3)``."""
        starts = self.data.poses[:, 0].copy()
        if self.spec.start_prior_sigmas is not None:
            for s in range(len(self.data)):
                pose = result.atPose2(keys.segment_pose(s))
                starts[s] = state_from_pose2(pose, self.data.poses[s, 0, 2])
        return starts

    def corrections(self, result: gtsam.Values, segment: int) -> np.ndarray:
        """Estimated wheel-rotation corrections ``(K, 2)`` [rev] of ``segment``."""
        if self.spec.corrections is None:
            raise ValueError("this segment graph has no correction variables")
        chunks = range(len(self.bounds[segment]) - 1)
        parts = [result.atVector(keys.segment_corrections(segment, j)) for j in chunks]
        return np.concatenate(parts).reshape(-1, 2)

    def values_at(
        self,
        states: list[np.ndarray],
        corrections: list[np.ndarray] | None,
        theta: np.ndarray,
    ) -> gtsam.Values:
        """Values of every variable from per-segment states ``(K+1, 3)``, corrections
        ``(K, 2)`` and theta (e.g. at the truth of a synthetic drive)."""
        values = gtsam.Values()
        if self.spec.estimate_theta:
            values.insert(keys.THETA, np.asarray(theta, float))
        insert_nuisance(values, self.spec)
        tied = self.spec.tied(self.data)
        for s, bounds in enumerate(self.bounds):
            heading = with_heading(self.data, s)
            insert_segment(values, s, bounds, states[s], self.spec, heading, bool(tied[s]))
            if self.spec.corrections is not None and corrections is not None:
                for j in range(len(bounds) - 1):
                    a, b = int(bounds[j]), int(bounds[j + 1])
                    values.insert(keys.segment_corrections(s, j), corrections[s][a:b].ravel())
        return values


def with_heading(data: SegmentData, s: int) -> bool:
    """Segment ``s`` measures the heading somewhere (else it has no heading bias)."""
    measured = data.measured_of(s)
    return measured is None or bool(measured[:, 1].any())


def insert_segment(
    values: gtsam.Values,
    s: int,
    bounds: np.ndarray,
    states: np.ndarray,
    spec: SegmentGraphSpec,
    with_heading: bool = True,
    tied_before: bool = False,
) -> None:
    """Insert the Pose2 variables of segment ``s`` (free start, chunk boundaries) and its
    slip scales and fixes' errors (at zero) and heading bias (if it measures the heading).
    ``tied_before``: the segment starts at the end of the one before, whose last fixes'
    error is its first."""
    if spec.slip_sigma is not None:
        for j in range(len(bounds) - 1):
            values.insert(keys.segment_slip(s, j), np.zeros(2))
    if spec.fix_error_sigma is not None:  # at each chunk boundary (tied: the first is before)
        for j in range(1 if tied_before else 0, len(bounds)):
            values.insert(keys.segment_fix_offset(s, j), np.zeros(2))
    if spec.heading_bias_sigma is not None and with_heading:
        values.insert(keys.segment_heading_bias(s), np.zeros(1))
    if spec.start_prior_sigmas is not None:
        values.insert(keys.segment_pose(s), pose2_from_state(states[0]))
    for j in range(1, len(bounds) - 1):
        values.insert(keys.segment_pose(s, j), pose2_from_state(states[int(bounds[j])]))


def insert_nuisance(values: gtsam.Values, spec: SegmentGraphSpec) -> None:
    """Insert the graph-wide time offset (at its prior mean), lever arm and rear slip gain (at
    zero) if ``spec`` has them."""
    if spec.time_offset_sigma is not None:
        values.insert(keys.TIME_OFFSET, spec.time_offset_means())
    if spec.lever_arm_sigma is not None:
        values.insert(keys.LEVER_ARM, np.zeros(2))
    if spec.rear_slip_gain_sigma is not None:
        values.insert(keys.REAR_SLIP_GAIN, np.zeros(1))
