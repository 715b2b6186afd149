"""Solving a segment graph: build (or take) it, optimize it from a chosen start, check theta's
plausibility and compute its covariance (:mod:`graphcal.graph.solution.covariance`).

A graph that splits into segments is solved part by part
(:class:`~graphcal.graph.optimization.partitioned.PartitionedGraph`); one that does not (theta
alone, or one segment, or one chain of tied segments) as one graph: Levenberg–Marquardt driven from
Python (:func:`graphcal.graph.optimization.solve.solve_lm`, with the rollout of
:mod:`graphcal.graph.optimization.rollout`) and GTSAM's marginals.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.graph.construction.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.partitioned_lm import optimize_partitioned
from graphcal.graph.optimization.solve import degrees_of_freedom, solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.optimization.values import taken_from
from graphcal.graph.solution.covariance import partitioned_marginals, whole_graph_marginals
from graphcal.graph.solution.estimates import SolvedGraph
from graphcal.graph.solution.plausibility import (
    BeyondPlausible,
    check_plausible,
    plausible_ranges,
)
from graphcal.log.segments import SegmentData


@dataclass(frozen=True)
class BuilderStart:
    """Start at the builder's initial values
    (:func:`~graphcal.graph.construction.builder.build_segment_graph`), with ``shared``'s values of
    graph-wide variables (by key: theta, time offset, lever arm).

    Attributes:
        shared: those values (none: the builder's own).
        gauss_newton_first: the first step is an undamped Gauss–Newton step (``shared``
            near the optimum, such as a warm start's).
        solution: a solution of the same segments under other settings (other noise levels,
            fix weights), or ``None``: every variable of the built graph it holds, in the
            same dimension, starts from it (the others from the builder).
    """

    shared: dict[int, np.ndarray] = field(default_factory=dict)
    gauss_newton_first: bool = False
    solution: gtsam.Values | None = None

    @classmethod
    def warm(cls, shared: dict[int, np.ndarray] | None) -> BuilderStart:
        """From a warm start's graph-wide values (``None`` or empty: the builder's own, and
        a damped first step)."""
        return cls(shared or {}, gauss_newton_first=bool(shared))


@dataclass(frozen=True)
class ValuesStart:
    """Start at ``values`` of every variable of the graph (e.g. an earlier solution's),
    on ``built``, that graph already built (``None``: built here); with
    ``gauss_newton_first``, the first step undamped (values a Gauss–Newton solve stopped at
    short of its minimum)."""

    values: gtsam.Values
    built: BuiltGraph | None = None
    gauss_newton_first: bool = False


def solve_segment_graph(
    data: SegmentData,
    spec: SegmentGraphSpec,
    options: SolveOptions,
    *,
    start: BuilderStart | ValuesStart | None = None,
    covariance: bool = True,
) -> SolvedGraph:
    """Build the graph of ``spec`` over ``data`` (or take the ``start``'s) and solve it with
    Levenberg–Marquardt from ``start`` (default: the builder's initial values), segment by
    segment (:class:`~graphcal.graph.optimization.partitioned.PartitionedGraph`), as ``options``
    say: the iteration limit and tolerance, ``label`` in errors, the segments shared out among
    ``workers`` processes (the result does not depend on it), with ``report_iterations`` a
    progress line per iteration of a long solve (:func:`graphcal.progress.say`).

    An estimated theta is checked for plausibility (for a vehicle whose nominal theta is the
    initial ``spec.theta``; the solve stops where it runs out of that range,
    :attr:`~graphcal.graph.optimization.solve_options.SolveStatus.RUNAWAY`; not where it
    stopped creeping,
    :attr:`~graphcal.graph.optimization.solve_options.SolveStatus.MISWEIGHTED`: no solution)
    and, with ``covariance``, gets its marginal covariance.

    Raises:
        CalibrationFailed: if the solve fails, or theta is non-finite or implausible.
    """
    start = BuilderStart() if start is None else start
    if spec.estimate_theta:  # a runaway stops the solve where it leaves the range
        ranges = plausible_ranges(np.asarray(spec.theta, float), spec.theta_prior_sigmas)
        options = dataclasses.replace(options, runaway=BeyondPlausible(ranges))
    if isinstance(start, ValuesStart):
        built = start.built if start.built is not None else build_segment_graph(data, spec)
        values, gauss_newton_first = start.values, start.gauss_newton_first
    else:
        built = build_segment_graph(data, spec, start.shared)
        values, gauss_newton_first = built.values, start.gauss_newton_first
        if start.solution is not None:
            values = taken_from(built.values, start.solution)
    partitioned = PartitionedGraph(built.graph, values, shared_keys(spec))
    if len(partitioned.parts) < 2:  # nothing to split: one graph, one solve
        return _solve_whole_graph(built, values, options, covariance)
    theta = np.asarray(spec.theta, float)
    marginal, nuisance = None, {}
    label = options.label
    with partitioned.parallel(options.workers):
        outcome = optimize_partitioned(
            partitioned, options, CalibrationFailed, gauss_newton_first=gauss_newton_first
        )
        if spec.estimate_theta:
            theta = np.asarray(partitioned.shared_values.atVector(keys.THETA))
            if not outcome.crept:  # not a solution: no verdict
                check_plausible(
                    theta,
                    label,
                    spec.theta,
                    lambda: implausibility_causes(built, partitioned.values()),
                    spec.theta_prior_sigmas,
                )
            if covariance:
                marginal, nuisance = partitioned_marginals(partitioned, built.spec, label)
    result = partitioned.values()
    return SolvedGraph(
        theta=theta,
        covariance=marginal,
        start_states=built.start_states(result),
        outcome=outcome,
        initial_error=partitioned.initial_error,
        final_error=partitioned.error(),
        result=result,
        built=built,
        degrees_of_freedom=partitioned.factor_dims() - partitioned.dim(),
        nuisance=nuisance,
        partitioned=partitioned,
    )


def _solve_whole_graph(
    built: BuiltGraph, start: gtsam.Values, options: SolveOptions, covariance: bool
) -> SolvedGraph:
    """:func:`solve_segment_graph` for a graph that does not split into segments (theta
    alone, as in the batch solve of Step 1, or one segment with theta fixed, as in input
    estimation; one chain of tied segments): Levenberg–Marquardt on the whole graph and
    GTSAM's marginals, cheaper than the split machinery there."""
    spec, label = built.spec, options.label
    initial_error = float(built.graph.error(start))
    # Python-driven: its steps roll the chunk-boundary poses out
    # (graphcal.graph.optimization.rollout), which GTSAM's optimizer cannot.
    result, outcome = solve_lm(built.graph, start, options, CalibrationFailed, driver="python")
    theta = np.asarray(spec.theta, float)
    marginal, nuisance = None, {}
    if spec.estimate_theta:
        theta = np.asarray(result.atVector(keys.THETA))
        if not outcome.crept:  # not a solution: no verdict
            check_plausible(
                theta,
                label,
                spec.theta,
                lambda: implausibility_causes(built, result),
                spec.theta_prior_sigmas,
            )
        if covariance:
            marginal, nuisance = whole_graph_marginals(built, result, label)
    return SolvedGraph(
        theta=theta,
        covariance=marginal,
        start_states=built.start_states(result),
        outcome=outcome,
        initial_error=initial_error,
        final_error=float(built.graph.error(result)),
        result=result,
        built=built,
        degrees_of_freedom=degrees_of_freedom(built.graph, result),
        nuisance=nuisance,
    )


#: Fix rate [Hz] below which an implausible theta names the rate among its causes, and
#: heading sigma [rad] below which it names the heading's weight (0.05°).
SLOW_FIX_RATE = 2.0
TIGHT_HEADING_SIGMA = float(np.deg2rad(0.05))
#: Mean |yaw rate| [rad/s] of the segments below which the drive leaves t_r and d to priors.
STRAIGHT_YAW_RATE = 0.02


def implausibility_causes(built: BuiltGraph, result: gtsam.Values) -> tuple[str, ...]:
    """What in the data or the weights of ``built`` may have driven its solve to an
    implausible theta (one phrase each, with the key or option to change)."""
    data, spec = built.data, built.spec
    causes = []
    if data.has_heading() and float(spec.tracking_sigmas[2]) < TIGHT_HEADING_SIGMA:
        causes.append(
            f"the heading weighs as a {np.degrees(spec.tracking_sigmas[2]):.3f}° measurement "
            "(check heading_unit and the heading noise, [joint] heading_noise_from_log)"
        )
    fixes = data.position_fixes()
    seconds = float(data.n_steps.sum() * data.dt)
    rate = float(fixes.sum()) / seconds if seconds > 0 else 0.0
    if rate < SLOW_FIX_RATE:
        causes.append(f"position fixes at only {rate:.1f} Hz")
    if spec.time_offset_sigma is not None and result.exists(keys.TIME_OFFSET):
        offsets = np.asarray(result.atVector(keys.TIME_OFFSET))
        beyond = np.abs(offsets - spec.time_offset_means()) > 3.0 * spec.time_offset_sigma
        if beyond.any():
            offset = float(offsets[np.argmax(beyond)])
            causes.append(
                f"the wheels' time offset went to {offset:+.2f} s, beyond its prior "
                f"(±{spec.time_offset_sigma:g} s): check the streams' time bases"
            )
    turned = np.abs(np.diff(data.poses[..., 2], axis=1))[data.valid[:, 1:]].sum()
    if seconds > 0 and turned / seconds < STRAIGHT_YAW_RATE:
        causes.append(
            f"the drive barely turns (mean |yaw rate| {turned / seconds:.3f} rad/s), so t_r "
            "and d rest on their priors"
        )
    return tuple(causes)
