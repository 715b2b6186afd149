"""Levenberg–Marquardt on one whole graph: GTSAM's optimizer, or the same steps driven from
Python by the rules of :mod:`graphcal.graph.optimization.levenberg_marquardt`."""

from __future__ import annotations

from typing import Literal

import gtsam
import numpy as np

from graphcal.errors import GraphcalError, exception_reason
from graphcal.graph.optimization.levenberg_marquardt import (
    CreepWatch,
    Damping,
    RunawayWatch,
    Verdict,
    converged,
    judge_step,
    raised_scale,
)
from graphcal.graph.optimization.linear_systems import add_damping, hessian_diagonal_by_column
from graphcal.graph.optimization.rollout import chunk_links, linear_gaps, rolled_out
from graphcal.graph.optimization.solve_options import SolveOptions, SolveOutcome, SolveStatus

#: Who drives the Levenberg–Marquardt iterations (:func:`solve_lm`).
Driver = Literal["gtsam", "python"]


def solve_lm(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    options: SolveOptions,
    error_type: type[GraphcalError] = GraphcalError,
    driver: Driver = "gtsam",
) -> tuple[gtsam.Values, SolveOutcome]:
    """Optimize ``graph`` from ``values`` as ``options`` say (iteration limit, tolerance);
    return the result and how the solve ended.

    Levenberg–Marquardt with diagonal damping (odometry residuals are tight, so the Hessian's
    diagonal spans many orders of magnitude), converged when the error falls by less than
    ``relative_error_tol`` relatively or 1e-12 absolutely. ``driver``:

    * ``"gtsam"``: ``gtsam.LevenbergMarquardtOptimizer``. It copies its ``Values`` into Python
      for every call of a Python factor, so an iteration costs (Python factors × variables):
      right for graphs of few large Python factors (the segment graphs).
    * ``"python"``: the same steps driven from Python, every linearization and error on a
      Python-owned ``Values`` — for graphs of many small Python factors (localization
      graphs: 3.7× faster on a 4 km smoothing graph, to the same result within 1e-11, and
      growing with the drive). Damping ``λ · clamp(diag(JᵀJ), 1e-6, 1e32)`` per variable
      (the diagonal of the first linearization, raised to the largest seen, as MINPACK
      scales), a step accepted when the error falls by at least 1e-3 of what the
      linearization predicts (then λ / 10), else λ × 10 up to 1e5; GTSAM's defaults.
      With ``options.misweighted_chi2``, it stops where it creeps above that χ²/dof
      (:class:`~graphcal.graph.optimization.levenberg_marquardt.CreepWatch`), with
      ``options.runaway`` where it runs out of the plausible range
      (:class:`~graphcal.graph.optimization.levenberg_marquardt.RunawayWatch`).

    GTSAM's exceptions (e.g. an indeterminate linear system) become ``error_type`` with the
    message ``"<options.label> failed: <reason>"``. GTSAM's optimizer does not say why it
    stopped: below its iteration limit it converged.
    """
    try:
        if driver == "python":
            return _levenberg_marquardt(graph, values, options)
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(options.max_iterations)
        params.setDiagonalDamping(True)
        params.setRelativeErrorTol(options.relative_error_tol)
        params.setAbsoluteErrorTol(1e-12)
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        result = optimizer.optimize()
        iterations = int(optimizer.iterations())
        return result, SolveOutcome.after(iterations, options, iterations < options.max_iterations)
    except RuntimeError as exc:
        reason = exception_reason(exc)
        raise error_type(f"{options.label} failed: {reason}") from exc


def degrees_of_freedom(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> int:
    """Residual dimensions of ``graph`` minus the dimensions of the unknowns in ``values``."""
    residuals = sum(graph.at(i).dim() for i in range(graph.size()) if graph.at(i) is not None)
    return int(residuals - values.dim())


def _levenberg_marquardt(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, options: SolveOptions
) -> tuple[gtsam.Values, SolveOutcome]:
    relative_error_tol = options.relative_error_tol
    values = gtsam.Values(values)
    keys = list(graph.keyVector())
    zero = values.zeroVectors()
    dims = np.array([len(zero.at(key)) for key in keys])
    first_column = np.concatenate([[0], np.cumsum(dims)])
    dim_of = {key: int(dim) for key, dim in zip(keys, dims, strict=True)}
    links = chunk_links(graph)
    error = float(graph.error(values))
    damping_scale: np.ndarray | None = None
    damping = Damping()
    watch = CreepWatch.of(options, 0)
    if watch.watching:
        watch.dof = degrees_of_freedom(graph, values)
    runaway = RunawayWatch(options.runaway)
    iterations, stop = 0, None
    while iterations < options.max_iterations:
        linear = graph.linearize(values)
        diagonal = hessian_diagonal_by_column(linear, int(first_column[-1]))
        damping_scale = raised_scale(damping_scale, diagonal)
        iterations += 1
        new_error = error
        # The linearization's own error at zero: with robust noise models it differs from the
        # nonlinear error (it weights with the square root). Constant over the λ trials.
        linear_at_zero = float(linear.error(zero))
        gaps = linear_gaps(graph, linear, links, dim_of)
        while True:
            damped = linear.clone()
            root = damping.roots(damping_scale)
            columns = zip(keys, first_column[:-1], dims, strict=True)
            add_damping(damped, dim_of, {key: root[a : a + dim] for key, a, dim in columns})
            try:
                step = damped.optimize()
            except RuntimeError:  # indeterminate at this damping: damp more, as GTSAM does
                if not damping.can_increase():
                    raise
                damping.increase()
                continue
            predicted = linear_at_zero - float(linear.error(step))
            predicted_gaps = [gap.at(step) for gap in gaps]
            candidate = rolled_out(graph, values.retract(step), links, predicted_gaps)
            new_error = float(graph.error(candidate))
            judgement = judge_step(error, new_error, predicted, damping, relative_error_tol)
            if judgement.verdict is Verdict.ACCEPT:
                values = candidate
                damping.decrease(judgement.gain_ratio)
                break
            if judgement.verdict is Verdict.AT_MINIMUM:
                new_error = error  # no step lowers the error: at the minimum
                stop = SolveStatus.NOT_IMPROVING
                break
            damping.increase()
        decrease = error - new_error
        if stop is None and converged(decrease, error, relative_error_tol):
            stop = SolveStatus.CONVERGED
        if stop is None:
            stop = watch.stopped(error, new_error)
        if stop is None and runaway.running_away(values, not watch.above(new_error)):
            stop = SolveStatus.RUNAWAY
        error = new_error
        if stop is not None:
            break
    return values, SolveOutcome(
        stop or SolveStatus.ITERATION_LIMIT, iterations, options.max_iterations
    )
