"""The joint method's batch study: every batch's theta with its covariance and verdict.

Two ways to solve the batches (``[batches] joint_solve``):

* ``"linearized"`` (the default): the joint graph over all selected segments, with the
  batches' settings, is linearized once at the whole-log solution and every segment is
  eliminated down to the shared variables (:mod:`graphcal.graph.solution.reduced_systems`); each
  batch is then one Gauss–Newton step on the sum of its members' systems. One elimination of the
  log serves all batches, so the study costs about one whole-log iteration whatever the
  number of batches. The whole-log solution has every segment's variables at their optimum
  for its theta, and a batch's theta lies within a few of its σ of it, where the model is
  nearly linear: on the synthetic drives the batches' thetas are within 0.01σ and their σ
  within 0.4 % of the exact solves (``docs/performance.md``).
* ``"exact"``: one joint Levenberg–Marquardt solve per batch from the nominal theta, in
  worker processes (1–2 s a batch): the paper's study as it was run.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed, GraphcalError, exception_reason
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.values import taken_from
from graphcal.graph.solution.observability import Observability
from graphcal.graph.solution.plausibility import check_plausible
from graphcal.graph.solution.reduced_systems import ReducedSystems, reduced_systems
from graphcal.log.segments import SegmentData
from graphcal.pipeline.solvers.joint import calibrate_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.parallel import map_tasks
from graphcal.progress import Progress, muted, reports_progress, say

#: ``[batches] joint_solve``: how the joint method solves its batches.
JOINT_BATCH_SOLVES = ("linearized", "exact")


@dataclass(frozen=True)
class BatchEstimate:
    """One batch's joint estimate (SI).

    Attributes:
        theta: ``[c_e, c_d, t_r, d]``.
        covariance: its 4×4 marginal covariance.
        observability: which parameters the batch determined.
    """

    theta: np.ndarray
    covariance: np.ndarray
    observability: Observability


@reports_progress
def solve_joint_batches(
    data: SegmentData,
    batches: np.ndarray,
    settings: JointSettings,
    batch_solve: str = "linearized",
    start: gtsam.Values | None = None,
    workers: int = 1,
    progress: Progress | None = None,
) -> list[BatchEstimate | None]:
    """Each batch's joint estimate, ``None`` where its solve failed (see the module
    docstring for ``batch_solve``).

    Args:
        data: the selected segments; ``batches`` ``(B, N)`` index them.
        settings: the batches' joint settings.
        batch_solve: ``"linearized"`` or ``"exact"``.
        start: for ``"linearized"``, the whole-log solution's values (the linearization
            point; its keys as in the graph of ``data``); ``None`` linearizes at the
            builder's initial values, which only suits a log where those are the solution.
        workers: processes (the results do not depend on it).
        progress: gets the progress lines.

    Raises:
        ValueError: for an unknown ``batch_solve``.
        CalibrationFailed: if the linearized systems cannot be formed (a segment's own
            variables indeterminate).
    """
    if batch_solve not in JOINT_BATCH_SOLVES:
        raise ValueError(
            f"joint_solve must be one of {', '.join(JOINT_BATCH_SOLVES)}, got {batch_solve!r}"
        )
    if batch_solve == "exact":
        tasks = [(data.take(batch), settings) for batch in batches]
        solved = map_tasks(_exact_task, tasks, workers, "joint batch solves")
        return [
            None if r is None else BatchEstimate(r.theta, r.covariance, r.observability)
            for r in solved
        ]
    return _linearized(data, np.asarray(batches, int), settings, start, workers)


def _exact_task(data: SegmentData, settings: JointSettings):
    """One joint solve; ``None`` if it failed."""
    try:
        with muted():  # one batch of many: the parent reports the count
            return calibrate_joint(data, settings)
    except GraphcalError:
        return None


def _linearized(
    data: SegmentData,
    batches: np.ndarray,
    settings: JointSettings,
    start: gtsam.Values | None,
    workers: int,
) -> list[BatchEstimate | None]:
    """The ``"linearized"`` batch solves."""
    systems = segment_systems(data, settings, start, workers)
    return linearized_batches(systems, batches, settings)


def segment_systems(
    data: SegmentData, settings: JointSettings, start: gtsam.Values | None, workers: int
) -> ReducedSystems:
    """Every segment of ``data`` eliminated down to the shared variables of the joint graph
    of ``settings``, linearized at ``start`` (the whole-log solution; ``None``: the builder's
    initial values): what the linearized batch solves and the segments' agreement
    (:mod:`graphcal.pipeline.methods.agreement`) are read from.

    Raises:
        CalibrationFailed: if a segment's own variables are indeterminate.
    """
    spec = settings.graph_spec()
    built = build_segment_graph(data, spec)
    values = built.values if start is None else taken_from(built.values, start)
    if spec.time_offset_sigma is not None:  # the batches' frame: their prior's mean
        values.update(keys.TIME_OFFSET, spec.for_runs(data.runs).time_offset_means())
    segmented = PartitionedGraph(built.graph, values, shared_keys(spec))
    say(f"joint batches: {len(data)} segments linearized at the whole-log solution")
    try:
        with segmented.parallel(workers):
            return reduced_systems(segmented, len(data))
    except (RuntimeError, np.linalg.LinAlgError) as exc:
        reason = exception_reason(exc)
        raise CalibrationFailed(f"joint batches failed: {reason}") from exc


def linearized_batches(
    systems: ReducedSystems, batches: np.ndarray, settings: JointSettings
) -> list[BatchEstimate | None]:
    """Each batch's estimate from the segments' ``systems`` (``None`` where singular or
    implausible)."""
    solution = systems.solve(np.asarray(batches, int))
    out: list[BatchEstimate | None] = []
    for theta, covariance in zip(
        solution.values[:, :4], solution.covariance[:, :4, :4], strict=True
    ):
        out.append(_estimate(theta, covariance, settings, settings.theta_initial))
    say(f"joint batches: {len(batches)} solved from the segments' systems")
    return out


def _estimate(
    theta: np.ndarray, covariance: np.ndarray, settings: JointSettings, reference: np.ndarray
) -> BatchEstimate | None:
    """A batch's estimate, or ``None`` if its information was singular or its theta is
    implausible (what a failed exact solve gives)."""
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(covariance))):
        return None
    try:
        check_plausible(
            theta, "joint batch", reference=reference, prior_sigmas=settings.theta_prior_sigmas
        )
    except CalibrationFailed:
        return None
    return BatchEstimate(theta, covariance, settings.observability(covariance))
