"""Each segment's share of the shared variables' information, kept to answer many batches.

Given the shared variables (theta, time offset, lever arm), the segments of a calibration
graph are independent. Linearized at one point, each segment's system eliminated down to the
shared variables is a small augmented Hessian ``[Λ_s η_s; η_sᵀ c_s]`` (its Schur complement).
The linearized system of any batch of segments is then the sum of its members' and of the
shared variables' own factors (their priors), ``[Λ η; ηᵀ c]``:

* the batch's Gauss–Newton step from the linearization point is ``δ = Λ⁻¹ η``;
* its information is ``Λ`` and its covariance ``Λ⁻¹``.

The batch studies of the paper draw 100 to 1000 batches from a few dozen segments: one
elimination per segment serves them all, and the batches are solved together with numpy.
Linearized at the whole-log solution, where every segment's variables are already at their
optimum for the whole log's theta, the step is the batch's own solve to within the
curvature of the model over a batch's spread (``docs/performance.md``). Linearized at the
truth without a prior on theta, the covariance is the batch's Cramér–Rao bound, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.graph.construction import keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.solution.covariance import covariance_from_information


@dataclass(frozen=True)
class BatchSolution:
    """The batches' linearized solves (SI, shared variables stacked in key order).

    Attributes:
        values: ``(B, n)`` the shared variables after each batch's Gauss–Newton step; NaN rows
            where a batch's information is singular.
        covariance: ``(B, n, n)`` the inverse of each batch's information; NaN where singular.
    """

    values: np.ndarray
    covariance: np.ndarray

    @property
    def solved(self) -> np.ndarray:
        """``(B,)`` True where the batch's information was invertible."""
        return np.all(np.isfinite(self.values), axis=1)


@dataclass(frozen=True)
class ReducedSystems:
    """Every segment's system reduced to the shared variables at one linearization point.

    Attributes:
        shared_keys: the shared variables' keys, in the order of the matrices' rows.
        point: ``(n,)`` their values at the linearization point.
        segments: ``(S, n+1, n+1)`` each segment's reduced augmented Hessian (zeros for a
            segment the graph does not have).
        shared: ``(n+1, n+1)`` the augmented Hessian of the factors on the shared variables
            alone (their priors).
    """

    shared_keys: tuple[int, ...]
    point: np.ndarray
    segments: np.ndarray
    shared: np.ndarray

    @property
    def dimension(self) -> int:
        """``n``: the shared variables' total dimension."""
        return len(self.point)

    def batch_systems(self, batches: np.ndarray) -> np.ndarray:
        """``(B, n+1, n+1)``: each batch's augmented Hessian, its members' summed with the
        shared one; ``batches`` ``(B, N)`` are segment indices."""
        batches = np.asarray(batches, int)
        if batches.ndim != 2:
            raise ValueError(
                f"batches must be a (B, N) array of segment indices, got {batches.shape}"
            )
        return self.segments[batches].sum(axis=1) + self.shared

    def solve(self, batches: np.ndarray) -> BatchSolution:
        """Each batch's Gauss–Newton step and covariance (see the module docstring)."""
        return self._solved(self.batch_systems(batches))

    def solve_groups(self, groups: list[np.ndarray]) -> BatchSolution:
        """:meth:`solve` for groups of segments of any sizes (lists of segment indices)."""
        systems = [self.segments[np.asarray(g, int)].sum(axis=0) + self.shared for g in groups]
        return self._solved(np.array(systems).reshape(len(groups), *self.shared.shape))

    def _solved(self, systems: np.ndarray) -> BatchSolution:
        """The Gauss–Newton step and covariance of each augmented Hessian of ``systems``."""
        n = self.dimension
        information = 0.5 * (systems[:, :n, :n] + systems[:, :n, :n].transpose(0, 2, 1))
        values = np.full((len(systems), n), np.nan)
        covariance = np.full((len(systems), n, n), np.nan)
        if n == 0 or len(systems) == 0:
            return BatchSolution(values, covariance)
        good = np.all(np.isfinite(systems), axis=(1, 2))
        covariance[good] = covariance_from_information(information[good])
        good &= np.all(np.isfinite(covariance), axis=(1, 2))
        step = np.einsum("bij,bj->bi", covariance[good], systems[good, :n, n])
        values[good] = self.point + step
        return BatchSolution(values, covariance)


def reduced_systems(
    partitioned: PartitionedGraph, segment_count: int, joined: bool = False
) -> ReducedSystems:
    """The :class:`ReducedSystems` of a segment graph (:mod:`graphcal.graph.construction.builder`)
    split by ``partitioned``, at its current values; ``segment_count`` segments (indexed as the
    graph's keys index them). Eliminates every part once (in the workers of
    :meth:`PartitionedGraph.parallel` if entered). With ``joined``, a part may hold tied
    segments (one trajectory): its system is its first segment's, the others' are zero, so
    that only sums over whole chains (the whole log) are meaningful.

    Raises:
        ValueError: if a part of the graph holds variables of more than one segment and
            not ``joined``.
        RuntimeError: from GTSAM if a segment's own variables are indeterminate.
    """
    parts, shared = partitioned.part_systems()
    segments = np.zeros((segment_count, *shared.shape))
    for part, system in zip(partitioned.parts, parts, strict=True):
        owners = {keys.segment_of(key) for key in part.local}
        if len(owners) != 1 and not joined:
            raise ValueError(f"a part of the graph joins segments {sorted(owners)}")
        owner = min(owners)
        if not 0 <= owner < segment_count:
            raise ValueError(f"segment {owner} outside 0..{segment_count - 1}")
        system.add_to(segments[owner])
    return ReducedSystems(tuple(partitioned.shared), partitioned.shared_vector(), segments, shared)
