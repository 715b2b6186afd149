"""A graph whose parts meet only in a few shared variables, solved part by part.

Given theta (and the other graph-wide variables: time offset, lever arm), the segments of a
calibration graph are independent. :class:`PartitionedGraph` splits a graph into those parts
(:mod:`graphcal.graph.optimization.partition`) and solves it the way a Schur complement does:

* each part is linearized on a ``Values`` of its own variables and the shared ones. GTSAM
  hands every Python factor a copy of the ``Values`` it is evaluated on, so on one graph-wide
  ``Values`` each call costs time in proportion to the whole log (0.5 ms a call on a 24 km
  graph) and a linearization grows with the square of the log's length; per part it is
  linear;
* each part's damped linear system is eliminated down to the shared variables
  (``eliminatePartialSequential``), the reduced factors are summed with the shared
  variables' own factors and solved, and each part's step is recovered by back-substitution
  (:meth:`gtsam.GaussianBayesNet.optimize` given the shared step);
* the shared variables' marginal covariance is the inverse of the summed reduced information
  at the solution.

The Levenberg–Marquardt iterations are :mod:`graphcal.graph.optimization.partitioned_lm`'s; the
parts may be shared out among worker processes (:mod:`graphcal.graph.optimization.part_workers`).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import gtsam
import numpy as np

from graphcal.graph.optimization.linear_systems import (
    SharedBlock,
    augmented_hessian,
    hessian_diagonal_by_key,
    predicted_decrease,
    shared_block,
    split_by_key,
    vector_values,
)
from graphcal.graph.optimization.part_group import PartGroup
from graphcal.graph.optimization.part_workers import PartWorkers
from graphcal.graph.optimization.partition import GraphPart, partition
from graphcal.graph.optimization.values import copy_value, tangent_dims


class PartitionedGraph:
    """``graph`` split into parts that share only ``shared`` keys.

    Args:
        graph: the factors.
        values: a value of every variable of ``graph``.
        shared: the keys the parts have in common (e.g. theta, time offset, lever arm).
    """

    def __init__(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, shared: list):
        self.shared = [int(k) for k in shared if values.exists(int(k))]
        split = partition(graph, values, self.shared)
        self.shared_graph = split.shared_graph
        self.shared_values = gtsam.Values()
        for key in self.shared:
            copy_value(self.shared_values, values, key)
        self.dims = tangent_dims(values)
        self.workers = PartWorkers(PartGroup(split.parts, self.shared, self.dims))
        self._error: float | None = None  # at the current values, once known
        self._information: np.ndarray | None = None  # likewise (see shared_information)
        self._initial_error: float | None = None

    @property
    def initial_error(self) -> float:
        """The error at the values the graph was made with (computed once, in the workers
        if asked first within :meth:`parallel`)."""
        if self._initial_error is None:
            self._initial_error = self.error()
        return self._initial_error

    @property
    def parts(self) -> list[GraphPart]:
        """All parts (also while some are worked on in other processes)."""
        return self.workers.everything.parts

    @contextlib.contextmanager
    def parallel(self, workers: int) -> Iterator[None]:
        """Within the block, the parts are shared out among this process and ``workers - 1``
        forked processes (contiguous runs of parts, balanced by factor count) that work at
        once; they start with the first call that needs the parts (a block that asks
        nothing of them forks nothing). The per-part answers are combined in part order, so
        the results do not depend on ``workers``. On leaving, the workers' values come back
        and they end."""
        if workers <= 1 or len(self.parts) < 2 or self.workers.active:
            yield
            return
        self.workers.share_out(workers)
        try:
            yield
        except Exception:
            self.workers.stop(self.shared_values)
            raise
        except BaseException:  # Ctrl-C: the workers are gone or going; the run ends
            self.workers.abandon()
            raise
        self.workers.stop(self.shared_values)

    def values_by_key(self) -> dict[int, gtsam.Values]:
        """For every local key, the ``Values`` of its part."""
        return {key: part.values for part in self.parts for key in part.local}

    def values(self) -> gtsam.Values:
        """Every variable's current value in one ``Values``."""
        merged = gtsam.Values(self.shared_values)
        for part in self.parts:
            for key in part.local:
                copy_value(merged, part.values, key)
        return merged

    def error(self) -> float:
        """The graph's error (half the whitened squared residual) at the current values."""
        if self._error is None:
            shared = float(self.shared_graph.error(self.shared_values))
            self._error = shared + math.fsum(self.workers.errors())
            if self._initial_error is None:  # nothing has moved the values yet
                self._initial_error = self._error
        return self._error

    def dim(self) -> int:
        """Dimension of all variables."""
        return int(self.shared_values.dim()) + sum(
            int(p.values.dim()) - int(self.shared_values.dim()) for p in self.parts
        )

    def factor_dims(self) -> int:
        """Total residual dimension of the factors."""
        graphs = [self.shared_graph, *(p.graph for p in self.parts)]
        return sum(g.at(i).dim() for g in graphs for i in range(g.size()))

    def system(
        self, lam: float | None, keep: bool = True
    ) -> tuple[np.ndarray, np.ndarray, gtsam.GaussianFactorGraph]:
        """Every part eliminated to the shared keys at damping ``lam`` (``None``: undamped)
        with the shared factors added: the augmented Hessian on the shared keys, their
        Hessian diagonal and the shared factors' linearization; with ``keep``, the parts
        keep what a step needs."""
        reduced = self.workers.eliminate(lam, keep)
        total = np.zeros((self.n + 1, self.n + 1))
        for block, _ in reduced:
            block.add_to(total)
        diagonal = sum((d for _, d in reduced), np.zeros(self.n))
        shared_linear = self.shared_graph.linearize(self.shared_values)
        shared_block(shared_linear, self.shared, self.dims).add_to(total)  # in place
        own = hessian_diagonal_by_key(shared_linear, {k: self.dims[k] for k in self.shared})
        diagonal = diagonal + np.concatenate([own[k] for k in self.shared] or [np.zeros(0)])
        return total, diagonal, shared_linear

    @property
    def n(self) -> int:
        """The shared variables' total dimension."""
        return sum(self.dims[k] for k in self.shared)

    def shared_information(self) -> np.ndarray:
        """The shared variables' information matrix at the current values (every part's
        variables marginalized), in the order of :attr:`shared`. After
        :func:`graphcal.graph.optimization.partitioned_lm.optimize` stopped on a final Gauss–Newton
        step, that of its last linearization (one step before the current values, of at most
        the solve's tolerance: no variable moved by more than ``last_step_sigmas`` of its σ);
        else computed at them."""
        if self._information is None:
            total, _, _ = self.system(None, keep=False)
            self._information = total[:-1, :-1].copy()
        return self._information.copy()

    def known_information(self) -> np.ndarray | None:
        """:meth:`shared_information` if it is known without linearizing (the solve's last
        Gauss–Newton step left it), else ``None``."""
        return None if self._information is None else self._information.copy()

    def moved(self, error: float, information: np.ndarray | None) -> None:
        """Record the graph's ``error`` at values a step moved it to and the shared
        variables' ``information`` there (``None``: not known)."""
        self._error, self._information = error, information

    def part_systems(self) -> tuple[list[SharedBlock], np.ndarray]:
        """At the current values, undamped: each part's linearized system eliminated down to
        the shared keys, as the block of the augmented Hessian ``(n+1, n+1)`` on the shared
        keys it touches (:class:`~graphcal.graph.optimization.linear_systems.SharedBlock`),
        in part order, and the shared factors' own augmented Hessian. The system of any
        subset of parts is the sum of its members' and the shared one
        (:mod:`graphcal.graph.solution.reduced_systems`)."""
        reduced = self.workers.eliminate(None, keep=False)
        shared_linear = self.shared_graph.linearize(self.shared_values)
        return [r for r, _ in reduced], augmented_hessian(shared_linear, self.shared, self.dims)

    def shared_vector(self) -> np.ndarray:
        """The shared variables' current values stacked ``(n,)`` in the order of
        :attr:`shared` (they are vectors in graphcal's graphs)."""
        blocks = [np.asarray(self.shared_values.atVector(k), float) for k in self.shared]
        return np.concatenate(blocks or [np.zeros(0)])

    def gauss_newton_decrement(self) -> float:
        """How much one Gauss–Newton step from the current values would lower the error on
        the linearization: ``½ gᵀ H⁻¹ g``. For variables that enter almost linearly this is
        what a full solve gains, at the cost of one linearization and one elimination."""
        total, _, shared_linear = self.system(None)
        step = self.by_key(self.solve_shared(total, np.zeros(self.n)))
        predicted = math.fsum(self.workers.step(step)) + predicted_decrease(
            shared_linear.gradientAtZero(), vector_values(step), {}, self.shared
        )
        self.workers.release()
        return predicted

    def solve_shared(self, total: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """The shared step from the augmented Hessian and a diagonal damping."""
        if self.n == 0:
            return np.zeros(0)
        return np.linalg.solve(total[:-1, :-1] + np.diag(damping), total[:-1, -1])

    def by_key(self, vector: np.ndarray) -> dict[int, np.ndarray]:
        """A shared-size ``vector`` cut into the shared keys' blocks."""
        return dict(zip(self.shared, split_by_key(vector, self.shared, self.dims), strict=True))
