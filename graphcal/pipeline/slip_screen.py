"""Whether a log shows slow wheel slip: a likelihood-ratio screen on the solved graph.

From the solution without slip (slip scales at zero), one Gauss–Newton step of the graph with
slip scales lowers χ² by about what the full solve would (the scales enter nearly linearly;
measured within 1 % of a Levenberg–Marquardt iteration, at a third of its cost). Per chunk,
that drop is 0.55–0.59 on drives without slip; above the detection threshold the solve with
slip continues from there to convergence. The step is taken on at most
:data:`SLIP_SCREEN_SEGMENTS` segments spread over the log: the statistic is a mean per chunk,
and a long log's screening then costs a fraction of one of its iterations.
"""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed, exception_reason
from graphcal.graph import keys
from graphcal.graph.builder import build_segment_graph
from graphcal.graph.built_graph import BuiltGraph
from graphcal.graph.covariance import with_covariance
from graphcal.graph.estimates import SolvedGraph
from graphcal.graph.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.partitioned import PartitionedGraph
from graphcal.graph.segment_solve import ValuesStart, solve_segment_graph
from graphcal.graph.solve_options import SolveOptions
from graphcal.graph.values import copy_value
from graphcal.log.segments import SegmentData, spread

#: Slip is screened on this many segments spread over the log (all of a shorter log; the
#: warm start's sample, :mod:`graphcal.pipeline.warm_start`): the statistic is a mean over
#: chunks, about 380 of them in 32 segments (on the 200 km drive without slip 0.56 from 32,
#: 0.59 from all 284 segments; the threshold is 1.3).
SLIP_SCREEN_SEGMENTS = 32


def with_slip_if_shown(
    solved: SolvedGraph,
    data: SegmentData,
    weights: np.ndarray | None,
    spec: SegmentGraphSpec,
    detection: float,
    options: SolveOptions,
) -> tuple[SolvedGraph, float]:
    """The solve with slip scales if the log shows slip, else ``solved``; both with their
    covariance, and the statistic that decided (see the module docstring).

    Args:
        solved: the solve without slip scales of ``data`` with the fix ``weights`` (``None``:
            the data's own); its covariance is computed here, and its graph freed before
            the graph with slip scales is built (the two are never held at once: on a
            200 km log each is most of the memory).
        spec: the graph with slip scales.
        detection: slip is modelled when it lowers χ² by more than this per chunk.
        options: of the solve with slip scales (its ``workers`` also screen and compute
            the covariance).

    Raises:
        CalibrationFailed: if the screening step fails.
    """
    label, workers = options.label, options.workers
    solved = _released(with_covariance(solved, label, workers))
    weighted = data if weights is None else dataclasses.replace(data, fix_weights=weights)
    screened = spread(len(data), SLIP_SCREEN_SEGMENTS)
    screen = build_segment_graph(weighted.take(screened), spec)
    at_solution = _moved(solved.result, screened, screen.values, shared_keys(spec))
    statistic = _chi2_drop_per_chunk(screen, at_solution, spec, workers)
    if statistic <= detection:
        return solved, statistic
    with_slip, initial = screen, at_solution
    if len(screened) < len(data):
        with_slip = build_segment_graph(weighted, spec)
        initial = _moved(solved.result, np.arange(len(data)), with_slip.values, shared_keys(spec))
    final = solve_segment_graph(weighted, spec, options, start=ValuesStart(initial, with_slip))
    return dataclasses.replace(final, outcome=solved.outcome.then(final.outcome)), statistic


def _chi2_drop_per_chunk(
    screen: BuiltGraph, at_solution: gtsam.Values, spec: SegmentGraphSpec, workers: int
) -> float:
    """How much one Gauss–Newton step of ``screen`` (a graph with slip scales) from
    ``at_solution`` lowers χ², per chunk."""
    screening = PartitionedGraph(screen.graph, at_solution, shared_keys(spec))
    try:
        with screening.parallel(workers):
            drop = screening.gauss_newton_decrement()
    except RuntimeError as exc:
        reason = exception_reason(exc)
        raise CalibrationFailed(f"joint solve failed: {reason}") from exc
    chunks = sum(len(bounds) - 1 for bounds in screen.bounds)
    return 2.0 * drop / chunks


def _released(solution: SolvedGraph) -> SolvedGraph:
    """``solution`` without its factors and its split graph (the values, estimates, spec
    and chunking stay): what is left once nothing more is solved on that graph."""
    built = dataclasses.replace(
        solution.built, graph=gtsam.NonlinearFactorGraph(), chunk_factors=()
    )
    return dataclasses.replace(solution, built=built, partitioned=None)


def _moved(
    result: gtsam.Values, segments: np.ndarray, values: gtsam.Values, shared: list[int]
) -> gtsam.Values:
    """``values`` of a graph over ``segments`` of ``result``'s graph, with ``result``'s value
    of every variable the two share (segment ``segments[i]``'s as segment ``i``'s)."""
    moved = gtsam.Values(values)
    for key in values.keys():
        source = key if key in shared else keys.in_segment(key, segments[keys.segment_of(key)])
        if result.exists(source):
            copy_value(moved, result, source, key)
    return moved
