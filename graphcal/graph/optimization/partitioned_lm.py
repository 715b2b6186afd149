"""Levenberg–Marquardt on a :class:`~graphcal.graph.optimization.partitioned.PartitionedGraph`, part
by part.

Each step solves the damped system reduced to the shared variables, back-substitutes every
part and judges the step by the rules of :mod:`graphcal.graph.optimization.levenberg_marquardt`
(those of :func:`graphcal.graph.optimization.solve.solve_lm`'s Python driver on the whole graph; the
damping's scale: the largest Hessian diagonal seen at a damped linearization). Once a step at the
first damping matched its prediction, the steps are undamped (Gauss–Newton), and the last
one, predicted to lower the error by at most the tolerance, leaves its linearization for the
covariance. The optimum is the same.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import gtsam
import numpy as np

from graphcal.errors import GraphcalError, exception_reason
from graphcal.graph.optimization.levenberg_marquardt import (
    CreepWatch,
    Damping,
    RunawayWatch,
    Verdict,
    converged,
    gauss_newton_next,
    judge_step,
    last_step_tolerance,
    raised_scale,
)
from graphcal.graph.optimization.linear_systems import predicted_decrease, vector_values
from graphcal.graph.optimization.solve_options import SolveOptions, SolveOutcome, SolveStatus
from graphcal.progress import say

if TYPE_CHECKING:
    from graphcal.graph.optimization.partitioned import PartitionedGraph

#: Seconds after which :func:`optimize` reports each iteration.
PROGRESS_AFTER_S = 2.0


@dataclass(frozen=True)
class _Iteration:
    """How an iteration ended: the error after it, whether it ends the solve (``stop``: why;
    ``None``: go on) and how its step was taken (for the progress line)."""

    new_error: float
    stop: SolveStatus | None
    how: str


@dataclass(frozen=True)
class _Trial:
    """A trial step: the augmented Hessian it solved, the shared step and the decrease its
    linearization predicts."""

    total: np.ndarray
    step: dict[int, np.ndarray]
    predicted: float


class _Solve:
    """The state of one solve: the error at the current values, the damping and its scale
    on the shared keys, and whether the next step is undamped."""

    def __init__(self, graph: PartitionedGraph, options: SolveOptions, undamped: bool):
        self.graph = graph
        self.tol = options.relative_error_tol
        self.step_sigmas = options.last_step_sigmas
        self.error = graph.error()
        self.shared_scale: np.ndarray | None = None
        self.damping = Damping()
        self.undamped = undamped  # this iteration's step is a Gauss–Newton step
        self.gauss_newton = True  # until one fails

    def iterate(self) -> _Iteration:
        """Trial steps until one is accepted or none lowers the error."""
        while True:
            trial = self._trial()
            if trial is None:
                continue
            ended = self._judge(trial)
            if ended is not None:
                return ended

    def finish(self, ended: _Iteration) -> SolveStatus | None:
        """Move on to the error after the iteration; why the solve stops (``None``: it goes
        on)."""
        decrease = self.error - ended.new_error
        # Undamped, the next linearization decides (and serves the covariance).
        stop = ended.stop
        if stop is None and converged(decrease, self.error, self.tol) and not self.undamped:
            stop = SolveStatus.CONVERGED
        self.error = ended.new_error
        return stop

    def _damp_from_now_on(self) -> None:
        self.undamped = self.gauss_newton = False

    def _trial(self) -> _Trial | None:
        """The (damped) step of the reduced system; ``None`` when it could not be solved and
        the damping changed (raises when it cannot grow)."""
        graph = self.graph
        try:
            total, diagonal, shared_linear = graph.system(
                None if self.undamped else self.damping.lam
            )
            self.shared_scale = raised_scale(self.shared_scale, diagonal)
            root = self.damping.roots(self.shared_scale)
            if self.undamped:
                root = np.zeros_like(root)
            shared_step = graph.solve_shared(total, root**2)
            if not np.all(np.isfinite(shared_step)):
                raise np.linalg.LinAlgError("non-finite step")
        except (RuntimeError, np.linalg.LinAlgError):
            graph.workers.release()
            if self.undamped:  # not determined without damping: damp, from now on
                self._damp_from_now_on()
                return None
            # indeterminate at this damping: damp more, as GTSAM does
            if not self.damping.can_increase():
                raise
            self.damping.increase()
            return None
        step = graph.by_key(shared_step)
        predicted = math.fsum(graph.workers.step(step)) + predicted_decrease(
            shared_linear.gradientAtZero(),
            vector_values(step),
            {} if self.undamped else graph.by_key(root),
            graph.shared,
        )
        return _Trial(total, step, predicted)

    def _judge(self, trial: _Trial) -> _Iteration | None:
        """Take, or reject, ``trial``; ``None`` to try again (damped, or damped more)."""
        graph, error = self.graph, self.error
        # A Gauss–Newton step that lowers the error by at most the tolerance, or moves no
        # variable by more than ``last_step_sigmas`` of its σ, is the last; its undamped
        # linearization gives the covariance. It is taken without evaluating the error: at
        # that size its decrease is its prediction.
        last = last_step_tolerance(error, self.tol, self.step_sigmas)
        if self.undamped and abs(trial.predicted) <= last:
            return self._last_step(trial)  # (rounding: slightly below 0)
        errors = graph.workers.try_step()
        candidate_shared = graph.shared_values.retract(vector_values(trial.step))
        new_error = float(graph.shared_graph.error(candidate_shared)) + math.fsum(errors)
        judgement = judge_step(error, new_error, trial.predicted, self.damping, self.tol)
        if judgement.verdict is Verdict.ACCEPT:
            return self._accept(candidate_shared, new_error, judgement.gain_ratio)
        if self.undamped:  # the model was not good enough: damp, from now on
            self._damp_from_now_on()
            return None
        if judgement.verdict is Verdict.AT_MINIMUM:
            return _Iteration(error, SolveStatus.NOT_IMPROVING, f"λ {self.damping.lam:.0e}")
        self.damping.increase()
        return None

    def _last_step(self, trial: _Trial) -> _Iteration:
        graph = self.graph
        graph.workers.try_step(False)
        graph.shared_values = graph.shared_values.retract(vector_values(trial.step))
        graph.workers.accept()
        new_error = self.error - trial.predicted
        graph.moved(new_error, trial.total[:-1, :-1].copy())
        return _Iteration(new_error, SolveStatus.CONVERGED, "Gauss–Newton")

    def _accept(self, candidate_shared: gtsam.Values, new_error: float, ratio: float) -> _Iteration:
        graph = self.graph
        graph.shared_values = candidate_shared
        graph.workers.accept()
        graph.moved(new_error, None)
        how = "Gauss–Newton" if self.undamped else f"λ {self.damping.lam:.0e}"
        # Gauss–Newton next if this step was (or needed no more damping than the first) and
        # its linearization predicted its decrease well.
        next_undamped = gauss_newton_next(self.undamped, self.damping.lam, ratio)
        if not self.undamped:
            self.damping.decrease(ratio)
        self.undamped = self.gauss_newton and next_undamped
        return _Iteration(new_error, None, how)


def optimize(
    graph: PartitionedGraph, options: SolveOptions, *, gauss_newton_first: bool = False
) -> SolveOutcome:
    """Levenberg–Marquardt to convergence from ``graph``'s current values (updated in
    place), as ``options`` say (iteration limit, tolerance, progress); returns how it ended.
    Raises ``RuntimeError`` from GTSAM (or numpy's ``LinAlgError``) if a system cannot be
    solved at any damping.

    Once a step at no more than the first damping lowered the error by what its
    linearization predicted (within :data:`GAUSS_NEWTON_FIDELITY`), the next steps are
    undamped Gauss–Newton steps; if one fails or is not accepted, the solve damps again
    and stays Levenberg–Marquardt (a log whose parameters are barely determined, such as
    t_r and d on a straight road, needs the damping). The solve stops when an undamped step
    would lower the error by at most ``options.relative_error_tol`` of it, or move no
    variable by more than ``options.last_step_sigmas`` of its σ
    (:func:`~graphcal.graph.optimization.levenberg_marquardt.last_step_tolerance`). That
    step is taken without evaluating the error (the error after it is the one predicted,
    exact to far below the tolerance), and its undamped linearization, a step this small
    from the solution, gives
    :meth:`~graphcal.graph.optimization.partitioned.PartitionedGraph.shared_information` without
    linearizing again (at the sample drive's tolerance, within 5e-5 of the covariance at the
    solution itself).

    With ``options.misweighted_chi2``, a solve that creeps above that χ²/dof stops there
    (:class:`~graphcal.graph.optimization.levenberg_marquardt.CreepWatch`); with
    ``options.runaway``, one whose shared variables run out of their plausible range
    (:class:`~graphcal.graph.optimization.levenberg_marquardt.RunawayWatch`).

    ``gauss_newton_first``: the first step is already undamped (values near the optimum,
    such as a warm start's: no damping to compute).

    With ``options.report_iterations``, a line per iteration (χ²/dof, damping λ, elapsed
    time, :func:`graphcal.progress.say`) once the solve has run for :data:`PROGRESS_AFTER_S`
    (a long log's solve shows it is moving; a short one prints nothing)."""
    started = time.perf_counter()
    dof = max(1, graph.factor_dims() - graph.dim())
    solve = _Solve(graph, options, gauss_newton_first)
    watch = CreepWatch.of(options, dof)
    runaway = RunawayWatch(options.runaway)
    iterations, stop = 0, None
    while iterations < options.max_iterations:
        iterations += 1
        ended = solve.iterate()
        graph.workers.release()
        before = solve.error
        stop = solve.finish(ended)
        if stop is None:
            stop = watch.stopped(before, solve.error)
        judged = not watch.above(solve.error)
        if stop is None and runaway.running_away(graph.shared_values, judged):
            stop = SolveStatus.RUNAWAY
        elapsed = time.perf_counter() - started
        if options.report_iterations and elapsed >= PROGRESS_AFTER_S:
            say(
                f"  iteration {iterations}: χ²/dof {2.0 * solve.error / dof:.4f}, {ended.how} "
                f"({elapsed:.0f} s)"
            )
        if stop is not None:
            break
    return SolveOutcome(stop or SolveStatus.ITERATION_LIMIT, iterations, options.max_iterations)


def optimize_partitioned(
    graph: PartitionedGraph,
    options: SolveOptions,
    error_type: type[GraphcalError] = GraphcalError,
    *,
    gauss_newton_first: bool = False,
) -> SolveOutcome:
    """:func:`optimize`, GTSAM's and numpy's exceptions turned into ``error_type`` with the
    message ``"<options.label> failed: <reason>"``."""
    try:
        return optimize(graph, options, gauss_newton_first=gauss_newton_first)
    except (RuntimeError, np.linalg.LinAlgError) as exc:
        reason = exception_reason(exc)
        raise error_type(f"{options.label} failed: {reason}") from exc
