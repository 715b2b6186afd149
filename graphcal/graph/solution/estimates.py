"""What a segment-graph solve estimates: theta with its covariance, the graph-wide nuisance
variables, and the solved graph's values."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.solve_options import SolveOutcome


@dataclass(frozen=True)
class NuisanceEstimate:
    """A graph-wide variable besides theta (time offset, lever arm) estimated with it (SI).

    Attributes:
        value: the estimate ``(n,)``.
        covariance: its marginal covariance ``(n, n)``.
        prior_sigma: the sigma of its zero-mean prior.
    """

    value: np.ndarray
    covariance: np.ndarray
    prior_sigma: float

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviation of each component."""
        return np.sqrt(np.diag(self.covariance))

    def observable(self, max_sigma_ratio: float) -> np.ndarray:
        """Per component: the data shrank the prior sigma to at most ``max_sigma_ratio`` of
        it (the rule theta's parameters follow, :mod:`graphcal.graph.solution.observability`)."""
        return self.sigma <= max_sigma_ratio * self.prior_sigma


@dataclass(frozen=True)
class ThetaEstimate:
    """Theta estimated from segments (SI).

    Attributes:
        theta: ``[c_e, c_d, t_r, d]`` (the fixed one if theta was not a variable).
        covariance: 4×4 marginal covariance of theta (every other variable marginalized),
            from the graph's information at the solution (or at the linearization of the
            solve's last Gauss–Newton step,
            :func:`graphcal.graph.optimization.partitioned_lm.optimize`); ``None`` if not computed.
        start_states: ``(S, 3)`` estimated (or held) start states.
        outcome: how the solve ended
            (:class:`~graphcal.graph.optimization.solve_options.SolveOutcome`: status,
            iterations).
        initial_error, final_error: of the solve (graph error is half the whitened squared
            residual; after a last Gauss–Newton step, the error it predicted, within far
            less than the solve's tolerance).
    """

    theta: np.ndarray
    covariance: np.ndarray | None
    start_states: np.ndarray
    outcome: SolveOutcome
    initial_error: float
    final_error: float
    #: Residual dimensions minus unknowns: the χ² of a solve that fits its noise model,
    #: ``2 * final_error``, is about this (0 when not known).
    degrees_of_freedom: int = field(default=0, kw_only=True)
    #: Graph-wide variables estimated with theta, by name (``"time_offset"``, ``"lever_arm"``).
    nuisance: dict[str, NuisanceEstimate] = field(default_factory=dict, kw_only=True)

    @property
    def chi2_per_dof(self) -> float | None:
        """``2 * final_error / degrees_of_freedom``: about 1 when the residuals fit the noise
        model, ``None`` when the degrees of freedom are not known."""
        if self.degrees_of_freedom <= 0:
            return None
        return 2.0 * self.final_error / self.degrees_of_freedom

    @property
    def iterations(self) -> int:
        """Iterations the solve used."""
        return self.outcome.iterations

    @property
    def theta_sigma(self) -> np.ndarray:
        """Standard deviation of each parameter (SI)."""
        return np.sqrt(np.diag(self.covariance))


@dataclass(frozen=True)
class SolvedGraph(ThetaEstimate):
    """A solved segment graph: the estimate with the solution's values (``result``), the
    graph that was solved (``built``) and its split into segments at the solution
    (``partitioned``, :class:`~graphcal.graph.optimization.partitioned.PartitionedGraph`)."""

    result: gtsam.Values
    built: BuiltGraph
    partitioned: PartitionedGraph | None = field(default=None, kw_only=True)

    def estimate(self) -> ThetaEstimate:
        """The estimate alone (picklable: no GTSAM objects)."""
        return ThetaEstimate(
            self.theta,
            self.covariance,
            self.start_states,
            self.outcome,
            self.initial_error,
            self.final_error,
            degrees_of_freedom=self.degrees_of_freedom,
            nuisance=self.nuisance,
        )
