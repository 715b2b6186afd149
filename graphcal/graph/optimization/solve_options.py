"""How a Levenberg–Marquardt solve runs, passed as one value (:class:`SolveOptions`), and how
it ended (:class:`SolveOutcome`: a status and a message, as scipy's ``OptimizeResult``)."""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

import gtsam

#: Above this χ²/dof (residuals twice their weights' σ) a solve with
#: ``SolveOptions.noise_read_tolerance`` stops at that tolerance
#: (:func:`~graphcal.graph.optimization.levenberg_marquardt.noise_read`).
FAR_OFF_CHI2 = 4.0


@dataclass(frozen=True)
class SolveOptions:
    """How one solve runs.

    Attributes:
        max_iterations: Levenberg–Marquardt iteration limit.
        relative_error_tol: the solve converges when an iteration lowers the graph error by
            at most this fraction of it (or 1e-12 absolutely).
        label: names the solve in its errors (``"joint solve failed: ..."``).
        workers: processes the segments of a graph that splits are shared out among (the
            result does not depend on it).
        report_iterations: a long solve says a line per iteration
            (:func:`graphcal.progress.say`).
        misweighted_chi2: > 0: the solve stops (:attr:`SolveStatus.MISWEIGHTED`) where it
            creeps at a χ²/dof above this
            (:class:`~graphcal.graph.optimization.levenberg_marquardt.CreepWatch`): weights
            far tighter than the misfit, for a caller that reads the noise from the
            residuals and solves again under it.
        noise_read_tolerance: > 0: while the χ²/dof is above ``noise_read_chi2``, the solve
            stops (:attr:`SolveStatus.NOISE_READ`) where an iteration lowers the error by at
            most this fraction of it, for a caller that reads the noise from the residuals
            and solves again under it (else goes on from there).
        runaway: how far the iterate's graph-wide variables lie beyond their plausible
            range (0 inside; :class:`~graphcal.graph.solution.plausibility.BeyondPlausible`):
            the solve stops (:attr:`SolveStatus.RUNAWAY`) once they run farther out
            iteration after iteration
            (:class:`~graphcal.graph.optimization.levenberg_marquardt.RunawayWatch`), for its
            caller to judge the runaway at once; ``None``: not watched.
        last_step_sigmas: the part-by-part solve
            (:mod:`~graphcal.graph.optimization.partitioned_lm`) also converges at a
            Gauss–Newton step that moves no variable by more than this share of its σ
            (:func:`~graphcal.graph.optimization.levenberg_marquardt.last_step_tolerance`);
            0: at the relative tolerance alone (a minimum to compare with another solver's).
        noise_read_chi2: the χ²/dof above which ``noise_read_tolerance`` applies
            (:data:`FAR_OFF_CHI2`: weights far from the residuals; 0: anywhere, for a caller
            that solves again only where the noise it reads changes).
    """

    max_iterations: int = 50
    relative_error_tol: float = 1e-7
    label: str = "solve"
    workers: int = 1
    report_iterations: bool = False
    misweighted_chi2: float = 0.0
    noise_read_tolerance: float = 0.0
    runaway: Callable[[gtsam.Values], float] | None = None
    last_step_sigmas: float = 0.1
    noise_read_chi2: float = FAR_OFF_CHI2


class SolveStatus(enum.Enum):
    """Why a solve stopped."""

    #: An iteration lowered the error by at most the tolerance.
    CONVERGED = "converged"
    #: No step lowered the error (at any damping the solve may use): the values are the
    #: minimum as far as the solve can tell.
    NOT_IMPROVING = "not improving"
    #: The iteration limit came first.
    ITERATION_LIMIT = "iteration limit"
    #: It crept at a χ²/dof far above any noise (``SolveOptions.misweighted_chi2``): not a
    #: minimum, a point to read the noise at.
    MISWEIGHTED = "misweighted"
    #: An iteration lowered the error by at most ``SolveOptions.noise_read_tolerance``:
    #: where the noise is read, a minimum to that tolerance.
    NOISE_READ = "noise read"
    #: Its graph-wide variables ran out of their plausible range iteration after iteration
    #: (``SolveOptions.runaway``): not a minimum, a runaway to judge.
    RUNAWAY = "runaway"


@dataclass(frozen=True)
class SolveOutcome:
    """How a solve ended: its :class:`SolveStatus`, the iterations it used and its limit."""

    status: SolveStatus
    iterations: int
    max_iterations: int

    @property
    def converged(self) -> bool:
        """The solve stopped at a minimum, not at its iteration limit."""
        return self.status is not SolveStatus.ITERATION_LIMIT

    @property
    def crept(self) -> bool:
        """The solve stopped creeping under weights far too tight for its residuals
        (:attr:`SolveStatus.MISWEIGHTED`): not a minimum, a point to read the noise at."""
        return self.status is SolveStatus.MISWEIGHTED

    @property
    def stopped_for_noise(self) -> bool:
        """The solve stopped short of its minimum at every solve's tolerance, where its
        caller reads the noise (:attr:`SolveStatus.MISWEIGHTED` or
        :attr:`SolveStatus.NOISE_READ`): its caller solves again, or it goes on."""
        return self.status in (SolveStatus.MISWEIGHTED, SolveStatus.NOISE_READ)

    @property
    def message(self) -> str:
        """One line: how the solve ended."""
        if self.status is SolveStatus.ITERATION_LIMIT:
            return f"stopped at its iteration limit ({self.max_iterations}) without converging"
        if self.crept:
            return f"stopped after {self.iterations} iteration(s) creeping under too tight weights"
        if self.status is SolveStatus.NOISE_READ:
            return (
                f"stopped after {self.iterations} iteration(s) where its noise is read "
                "for the next solve"
            )
        if self.status is SolveStatus.RUNAWAY:
            return (
                f"stopped after {self.iterations} iteration(s) running out of the plausible range"
            )
        how = "no step lowers the error" if self.status is SolveStatus.NOT_IMPROVING else ""
        return f"converged after {self.iterations} iteration(s)" + (f" ({how})" if how else "")

    def then(self, later: SolveOutcome) -> SolveOutcome:
        """This solve followed by ``later`` (from this one's result, under the same limit):
        ``later``'s status, the iterations of both."""
        return SolveOutcome(later.status, self.iterations + later.iterations, later.max_iterations)

    @classmethod
    def after(cls, iterations: int, options: SolveOptions, stopped: bool) -> SolveOutcome:
        """The outcome of a loop that ran ``iterations`` under ``options``'s limit and
        ``stopped`` (converged) or ran out."""
        status = SolveStatus.CONVERGED if stopped else SolveStatus.ITERATION_LIMIT
        return cls(status, iterations, options.max_iterations)
