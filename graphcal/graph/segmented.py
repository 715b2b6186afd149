"""A graph whose parts meet only in a few shared variables, solved part by part.

Given theta (and the other graph-wide variables: time offset, lever arm), the segments of a
calibration graph are independent. :class:`SegmentedGraph` splits a graph into those parts
(connected components once the shared keys are removed) and runs Levenberg–Marquardt the way
a Schur complement does:

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

The steps are those of :func:`graphcal.graph.solve.solve_lm`'s Python driver on the whole graph
(the same damping, acceptance and stopping rules), so the result is the same optimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import GraphcalError, first_line
from graphcal.graph.solve import (
    LAMBDA_FACTOR,
    LAMBDA_INITIAL,
    LAMBDA_UPPER_BOUND,
    MAX_DIAGONAL,
    MIN_DIAGONAL,
    MIN_MODEL_FIDELITY,
    unit_noise,
)


def copy_value(target: gtsam.Values, source: gtsam.Values, key: int) -> None:
    """Insert (or update) ``key``'s value from ``source`` into ``target`` (a Pose2 or a
    vector: the variables of graphcal's segment graphs)."""
    try:
        value = source.atPose2(key)
    except RuntimeError:
        value = source.atVector(key)
    if target.exists(key):
        target.update(key, value)
    else:
        target.insert(key, value)


@dataclass
class GraphPart:
    """One part: its factors, its own variables (``local``) and a ``Values`` holding them
    with the shared variables."""

    graph: gtsam.NonlinearFactorGraph
    local: list[int]
    values: gtsam.Values


@dataclass
class PartStep:
    """A part's linearization and, for one damping, its elimination to the shared keys."""

    linear: gtsam.GaussianFactorGraph
    diagonal: dict[int, np.ndarray]
    bayes_net: gtsam.GaussianBayesNet | None = None
    reduced: gtsam.GaussianFactorGraph | None = None


class SegmentedGraph:
    """``graph`` split into parts that share only ``shared`` keys.

    Args:
        graph: the factors.
        values: a value of every variable of ``graph``.
        shared: the keys the parts have in common (e.g. theta, time offset, lever arm).
    """

    def __init__(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, shared: list):
        self.shared = [int(k) for k in shared if values.exists(int(k))]
        shared_set = set(self.shared)
        factors = [graph.at(i) for i in range(graph.size()) if graph.at(i) is not None]
        parent: dict[int, int] = {}

        def find(key: int) -> int:
            while parent.setdefault(key, key) != key:
                parent[key] = parent[parent[key]]
                key = parent[key]
            return key

        for factor in factors:
            own = [k for k in factor.keys() if k not in shared_set]
            for k in own[1:]:
                parent[find(k)] = find(own[0])
            if own:
                find(own[0])
        self.shared_graph = gtsam.NonlinearFactorGraph()
        by_root: dict[int, gtsam.NonlinearFactorGraph] = {}
        for factor in factors:
            own = [k for k in factor.keys() if k not in shared_set]
            if not own:
                self.shared_graph.add(factor)
                continue
            by_root.setdefault(find(own[0]), gtsam.NonlinearFactorGraph()).add(factor)
        local_keys: dict[int, list[int]] = {}
        for key in parent:
            local_keys.setdefault(find(key), []).append(key)
        self.parts = []
        for root, part_graph in by_root.items():
            local = sorted(local_keys[root])
            part_values = gtsam.Values()
            for key in local + self.shared:
                copy_value(part_values, values, key)
            self.parts.append(GraphPart(part_graph, local, part_values))
        self.shared_values = gtsam.Values()
        for key in self.shared:
            copy_value(self.shared_values, values, key)
        self.dims = _dims(values)
        self.initial_error = self.error()

    def values(self) -> gtsam.Values:
        """Every variable's current value in one ``Values``."""
        merged = gtsam.Values(self.shared_values)
        for part in self.parts:
            for key in part.local:
                copy_value(merged, part.values, key)
        return merged

    def error(self) -> float:
        """The graph's error (half the whitened squared residual) at the current values."""
        return float(self.shared_graph.error(self.shared_values)) + sum(
            float(p.graph.error(p.values)) for p in self.parts
        )

    def dim(self) -> int:
        """Dimension of all variables."""
        return int(self.shared_values.dim()) + sum(
            int(p.values.dim()) - int(self.shared_values.dim()) for p in self.parts
        )

    def factor_dims(self) -> int:
        """Total residual dimension of the factors."""
        graphs = [self.shared_graph, *(p.graph for p in self.parts)]
        return sum(g.at(i).dim() for g in graphs for i in range(g.size()))

    def linearize(self) -> tuple[gtsam.GaussianFactorGraph, list[PartStep]]:
        """The shared factors' and each part's linearization at the current values."""
        shared_linear = self.shared_graph.linearize(self.shared_values)
        steps = []
        for part in self.parts:
            linear = part.graph.linearize(part.values)
            steps.append(PartStep(linear, _hessian_diagonal(linear, self._part_dims(part))))
        return shared_linear, steps

    def _part_dims(self, part: GraphPart) -> dict[int, int]:
        return {k: self.dims[k] for k in (*part.local, *self.shared)}

    def eliminate(
        self, steps: list[PartStep], damping: list[dict[int, np.ndarray]] | None = None
    ) -> gtsam.GaussianFactorGraph:
        """Eliminate each part's (damped) linear system to the shared keys; returns the
        reduced factors of all parts."""
        reduced = gtsam.GaussianFactorGraph()
        for i, (part, step) in enumerate(zip(self.parts, steps, strict=True)):
            system = step.linear
            if damping is not None:
                system = system.clone()
                _add_damping(system, self.dims, damping[i])
            step.bayes_net, step.reduced = system.eliminatePartialSequential(
                gtsam.KeyVector(part.local)
            )
            for j in range(step.reduced.size()):
                reduced.push_back(step.reduced.at(j))
        return reduced

    def shared_information(self) -> np.ndarray:
        """The shared variables' information matrix at the current values (every part's
        variables marginalized), in the order of :attr:`shared`."""
        shared_linear, steps = self.linearize()
        total = self.eliminate(steps)
        for j in range(shared_linear.size()):
            total.push_back(shared_linear.at(j))
        ordering = gtsam.Ordering()
        for key in self.shared:
            ordering.push_back(key)
        hessian = total.augmentedHessian(ordering)
        return hessian[:-1, :-1]

    def gauss_newton_decrement(self) -> float:
        """How much one Gauss–Newton step from the current values would lower the error on
        the linearization: ``½ gᵀ H⁻¹ g``. For variables that enter almost linearly this is
        what a full solve gains, at the cost of one linearization and one elimination."""
        shared_linear, steps = self.linearize()
        _, predicted, _ = self._step(shared_linear, steps, None)
        return predicted

    def _step(
        self,
        shared_linear: gtsam.GaussianFactorGraph,
        steps: list[PartStep],
        damping: tuple[dict[int, np.ndarray], list[dict[int, np.ndarray]]] | None,
    ) -> tuple[list[gtsam.VectorValues], float, gtsam.VectorValues]:
        """Solve the (damped) linear system: each part's step (with the shared step), the
        decrease the linearization predicts and the shared step."""
        total = self.eliminate(steps, None if damping is None else damping[1])
        for j in range(shared_linear.size()):
            total.push_back(shared_linear.at(j))
        if damping is not None:
            _add_damping(total, self.dims, damping[0])
        shared_step = total.optimize()
        predicted = _decrease(shared_linear, shared_step)
        part_steps = []
        for step in steps:
            delta = step.bayes_net.optimize(shared_step)
            for key in self.shared:
                if not delta.exists(key):
                    delta.insert(key, shared_step.at(key))
            predicted += _decrease(step.linear, delta)
            part_steps.append(delta)
        return part_steps, predicted, shared_step

    def optimize(self, max_iterations: int, relative_error_tol: float) -> int:
        """Levenberg–Marquardt to convergence from the current values (updated in place);
        returns the iterations used. Raises ``RuntimeError`` from GTSAM if a system cannot
        be solved at any damping."""
        error = self.error()
        shared_scale: dict[int, np.ndarray] | None = None
        part_scales: list[dict[int, np.ndarray]] = []
        lam = LAMBDA_INITIAL
        iterations = 0
        while iterations < max_iterations:
            shared_linear, steps = self.linearize()
            shared_dims = {k: self.dims[k] for k in self.shared}
            diagonal = _hessian_diagonal(shared_linear, shared_dims)
            for step in steps:
                for key in self.shared:
                    diagonal[key] = diagonal[key] + step.diagonal[key]
            local = [
                {k: s.diagonal[k] for k in p.local} for p, s in zip(self.parts, steps, strict=True)
            ]
            if shared_scale is None:
                shared_scale, part_scales = diagonal, local
            else:
                shared_scale = _maximum(shared_scale, diagonal)
                part_scales = [_maximum(a, b) for a, b in zip(part_scales, local, strict=True)]
            iterations += 1
            new_error = error
            while True:
                damping = (_root(shared_scale, lam), [_root(s, lam) for s in part_scales])
                try:
                    part_steps, predicted, shared_step = self._step(shared_linear, steps, damping)
                except RuntimeError:  # indeterminate at this damping: damp more
                    if lam * LAMBDA_FACTOR >= LAMBDA_UPPER_BOUND:
                        raise
                    lam *= LAMBDA_FACTOR
                    continue
                candidate_shared = self.shared_values.retract(shared_step)
                candidates = [
                    p.values.retract(d) for p, d in zip(self.parts, part_steps, strict=True)
                ]
                new_error = float(self.shared_graph.error(candidate_shared)) + sum(
                    float(p.graph.error(c)) for p, c in zip(self.parts, candidates, strict=True)
                )
                change = error - new_error
                fidelity = change / predicted if predicted > 1e-20 else 1.0
                if predicted >= 0 and fidelity > MIN_MODEL_FIDELITY and change >= 0:
                    self.shared_values = candidate_shared
                    for part, candidate in zip(self.parts, candidates, strict=True):
                        part.values = candidate
                    lam = max(lam / LAMBDA_FACTOR, 1e-12)
                    break
                small = max(relative_error_tol * error, 1e-12)
                if abs(change) < small or lam * LAMBDA_FACTOR >= LAMBDA_UPPER_BOUND:
                    new_error = error
                    break
                lam *= LAMBDA_FACTOR
            decrease = error - new_error
            converged = decrease <= 1e-12 or decrease <= relative_error_tol * error
            error = new_error
            if converged:
                break
        return iterations


def solve_segmented(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    shared: list[int],
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
) -> tuple[SegmentedGraph, int]:
    """Split ``graph`` at the ``shared`` keys (:class:`SegmentedGraph`) and optimize it from
    ``values``; returns the solved graph (its values are the solution) and the iterations.

    GTSAM's exceptions become ``error_type`` with the message ``"<label> failed: <reason>"``.
    """
    segmented = SegmentedGraph(graph, values, shared)
    try:
        iterations = segmented.optimize(max_iterations, relative_error_tol)
    except RuntimeError as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise error_type(f"{label} failed: {reason}") from exc
    return segmented, iterations


def _decrease(linear: gtsam.GaussianFactorGraph, step: gtsam.VectorValues) -> float:
    """The decrease of ``linear``'s error from zero to ``step``."""
    return float(linear.error(step.scale(0.0)) - linear.error(step))


def _maximum(a: dict[int, np.ndarray], b: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    return {k: np.maximum(a[k], b[k]) for k in a}


def _root(scale: dict[int, np.ndarray], lam: float) -> dict[int, np.ndarray]:
    """Square roots of the damping ``λ · clamp(diag, 1e-6, 1e32)`` per key."""
    return {k: np.sqrt(lam * np.clip(v, MIN_DIAGONAL, MAX_DIAGONAL)) for k, v in scale.items()}


def _add_damping(
    system: gtsam.GaussianFactorGraph, dims: dict[int, int], root: dict[int, np.ndarray]
) -> None:
    """Add the rows ``diag(root[key])`` on every key of ``root`` to ``system``."""
    for key, r in root.items():
        dim = dims[key]
        system.add(gtsam.JacobianFactor(key, np.diag(r), np.zeros(dim), unit_noise(dim)))


def _dims(values: gtsam.Values) -> dict[int, int]:
    """Tangent dimension of every variable of ``values``."""
    zero = values.zeroVectors()
    return {int(k): len(zero.at(k)) for k in values.keys()}


def _hessian_diagonal(
    linear: gtsam.GaussianFactorGraph, dims: dict[int, int]
) -> dict[int, np.ndarray]:
    """Diagonal of ``JᵀJ`` of the whitened ``linear``, per key of ``dims`` (zero for keys
    ``linear`` does not have)."""
    diagonal = {k: np.zeros(dim) for k, dim in dims.items()}
    for i in range(linear.size()):
        factor = linear.at(i)
        matrix, _ = factor.jacobian()
        squares = np.einsum("ij,ij->j", matrix, matrix)
        at = 0
        for key in factor.keys():
            dim = dims[key]
            diagonal[key] += squares[at : at + dim]
            at += dim
    return diagonal
