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

The damped steps follow the rules of :func:`graphcal.graph.solve.solve_lm`'s Python driver on
the whole graph (the damping's scale: the largest Hessian diagonal seen at a damped
linearization); once a step at the first damping matched its prediction, the steps are
undamped (Gauss–Newton), and the last one, predicted to lower the error by at most the
tolerance, leaves its linearization for the covariance. The optimum is the same.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import multiprocessing
import multiprocessing.context
import time
from collections.abc import Callable, Iterator
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


def copy_value(
    target: gtsam.Values, source: gtsam.Values, key: int, target_key: int | None = None
) -> None:
    """Insert (or update) ``key``'s value from ``source`` into ``target``, as ``target_key``
    if given (a Pose2 or a vector: the variables of graphcal's segment graphs)."""
    try:
        value = source.atPose2(key)
    except RuntimeError:
        value = source.atVector(key)
    key = key if target_key is None else target_key
    if target.exists(key):
        target.update(key, value)
    else:
        target.insert(key, value)


#: Seconds after which :meth:`SegmentedGraph.optimize` reports each iteration.
PROGRESS_AFTER_S = 2.0
#: After a step whose error decrease is within this fraction of its linearization's
#: prediction, :meth:`SegmentedGraph.optimize` takes undamped (Gauss–Newton) steps.
GAUSS_NEWTON_FIDELITY = 0.1


@dataclass
class GraphPart:
    """One part: its factors, its own variables (``local``), a ``Values`` holding them with
    the shared variables, and its damping scale (the largest Hessian diagonal seen, per
    local key)."""

    graph: gtsam.NonlinearFactorGraph
    local: list[int]
    values: gtsam.Values
    scale: dict[int, np.ndarray] | None = None


@dataclass
class _Eliminated:
    """A part's damped system eliminated to the shared keys: what the step needs."""

    bayes_net: gtsam.GaussianBayesNet
    gradient: gtsam.VectorValues
    root: dict[int, np.ndarray]


class PartGroup:
    """Parts of a :class:`SegmentedGraph` and the messages the optimizer sends them; every
    answer is small (shared-size arrays and floats), so a group can live in another process.

    Between :meth:`eliminate` and :meth:`step` a group keeps each part's Bayes net (its
    conditionals given the shared keys), not its linear system: a rejected step
    re-linearizes, which Levenberg–Marquardt rarely needs, and the memory of the linear
    systems (two thirds of it on segment graphs) is not held for the whole log at once.
    """

    def __init__(self, parts: list[GraphPart], shared: list[int], dims: dict[int, int]):
        self.parts = parts
        self.shared = shared
        self.dims = dims
        self._eliminated: list[_Eliminated] = []
        self._deltas: list[gtsam.VectorValues] = []
        self._candidates: list[gtsam.Values] = []

    def errors(self) -> list[float]:
        """Each part's error at its values."""
        return [float(p.graph.error(p.values)) for p in self.parts]

    def eliminate(self, lam: float | None) -> list[tuple[np.ndarray, np.ndarray]]:
        """Linearize every part, damp its local keys by ``λ · scale`` (``None``: undamped)
        and eliminate them; per part, its reduced system as an augmented Hessian
        ``(n+1, n+1)`` on the shared keys and its Hessian diagonal on them ``(n,)`` (zeros
        when undamped: only damping needs it)."""
        out = []
        self._eliminated = []
        n = sum(self.dims[k] for k in self.shared)
        for part in self.parts:
            linear = part.graph.linearize(part.values)
            shared_diagonal, root = np.zeros(n), {}
            if lam is not None:  # the damping's scale: the largest diagonal seen (GTSAM's)
                dims = {k: self.dims[k] for k in (*part.local, *self.shared)}
                diagonal = _hessian_diagonal(linear, dims)
                local = {k: diagonal[k] for k in part.local}
                part.scale = local if part.scale is None else _maximum(part.scale, local)
                shared_diagonal = np.concatenate(
                    [diagonal[k] for k in self.shared] or [np.zeros(0)]
                )
                root = _root(part.scale, lam)
            gradient = linear.gradientAtZero()
            _add_damping(linear, self.dims, root)  # the linear system is not kept: damp it
            bayes_net, reduced = linear.eliminatePartialSequential(gtsam.KeyVector(part.local))
            out.append((augmented_hessian(reduced, self.shared, self.dims), shared_diagonal))
            self._eliminated.append(_Eliminated(bayes_net, gradient, root))
        return out

    def step(self, shared_step: dict[int, np.ndarray]) -> list[float]:
        """Back-substitute every part given the shared step; per part, what the step lowers
        its linearized error by (undamped). The steps are kept for :meth:`try_step`."""
        given = gtsam.VectorValues()
        for key, value in shared_step.items():
            given.insert(key, value)
        out = []
        self._deltas = []
        for part, done in zip(self.parts, self._eliminated, strict=True):
            delta = done.bayes_net.optimize(given)
            for key in self.shared:
                if not delta.exists(key):
                    delta.insert(key, given.at(key))
            keys = [*part.local, *self.shared]
            out.append(_predicted_decrease(done.gradient, delta, done.root, keys))
            self._deltas.append(delta)
        return out

    def try_step(self, evaluate: bool = True) -> list[float]:
        """Each part's error after the last :meth:`step` (with ``evaluate``; else 0); the
        candidate values are kept for :meth:`accept`."""
        out = []
        self._candidates = []
        for part, delta in zip(self.parts, self._deltas, strict=True):
            candidate = part.values.retract(delta)
            out.append(float(part.graph.error(candidate)) if evaluate else 0.0)
            self._candidates.append(candidate)
        return out

    def accept(self) -> None:
        """Move every part to its candidate values."""
        for part, candidate in zip(self.parts, self._candidates, strict=True):
            part.values = candidate
        self._candidates = []

    def release(self) -> None:
        """Drop the eliminations, steps and candidates (memory)."""
        self._eliminated, self._deltas, self._candidates = [], [], []

    def local_values(self) -> list[dict[int, tuple[str, np.ndarray]]]:
        """Each part's local variables, picklable: ``key -> ("pose2" | "vector", array)``."""
        return [{key: _portable(part.values, key) for key in part.local} for part in self.parts]


class _RemoteGroup:
    """A :class:`PartGroup` served by a forked process (it inherits the group, Python
    factors included, without pickling); calls are sent, then received, so that several
    groups work at once."""

    def __init__(self, group: PartGroup, context: multiprocessing.context.BaseContext):
        self.size = len(group.parts)
        parent, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, group), daemon=True)
        self.process.start()
        child.close()
        self.connection = parent

    def send(self, method: str, *args) -> None:
        self.connection.send((method, args))

    def receive(self):
        status, value = self.connection.recv()
        if status == "error":
            raise RuntimeError(value)
        return value

    def stop(self) -> list[dict[int, tuple[str, np.ndarray]]]:
        """End the process; returns its parts' local values."""
        self.send("stop")
        values = self.receive()
        self.process.join()
        self.connection.close()
        return values


def _serve(connection, group: PartGroup) -> None:
    """A worker's loop: call the group's methods until ``stop``."""
    while True:
        method, args = connection.recv()
        if method == "stop":
            connection.send(("ok", group.local_values()))
            return
        try:
            connection.send(("ok", getattr(group, method)(*args)))
        except Exception as exc:  # reported to the optimizer, which raises it
            connection.send(("error", f"{first_line(str(exc)) or type(exc).__name__}"))


def _portable(values: gtsam.Values, key: int) -> tuple[str, np.ndarray]:
    try:
        pose = values.atPose2(key)
    except RuntimeError:
        return "vector", np.asarray(values.atVector(key))
    return "pose2", np.array([pose.x(), pose.y(), pose.theta()])


def _restore(values: gtsam.Values, key: int, portable: tuple[str, np.ndarray]) -> None:
    kind, array = portable
    value = gtsam.Pose2(*array) if kind == "pose2" else array
    values.update(key, value)


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
        parts = []
        for root, part_graph in by_root.items():
            local = sorted(local_keys[root])
            part_values = gtsam.Values()
            for key in local + self.shared:
                copy_value(part_values, values, key)
            parts.append(GraphPart(part_graph, local, part_values))
        self.shared_values = gtsam.Values()
        for key in self.shared:
            copy_value(self.shared_values, values, key)
        self.dims = _dims(values)
        self._all = PartGroup(parts, self.shared, self.dims)
        self.group = self._all  # the parts this process works on (all, unless parallel)
        self._remote: list[_RemoteGroup] = []
        self._groups: list[PartGroup] = []  # while parallel: this process's, then the workers'
        self._pending = 0  # workers asked for by parallel() and not started yet
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
        return self._all.parts

    @contextlib.contextmanager
    def parallel(self, workers: int) -> Iterator[None]:
        """Within the block, the parts are shared out among this process and ``workers - 1``
        forked processes (contiguous runs of parts, balanced by factor count) that work at
        once; they start with the first call that needs the parts (a block that asks
        nothing of them forks nothing). The per-part answers are combined in part order, so
        the results do not depend on ``workers``. On leaving, the workers' values come back
        and they end."""
        if workers <= 1 or len(self.parts) < 2 or self._remote or self._pending:
            yield
            return
        self._pending = workers
        try:
            yield
        finally:
            self._pending = 0
            remote, self._remote = self._remote, []
            everything = self._all
            self.group = everything
            at = len(self._groups[0].parts) if self._groups else 0
            self._groups = []
            for worker in remote:
                mine = everything.parts[at : at + worker.size]
                for part, values in zip(mine, worker.stop(), strict=True):
                    for key, portable in values.items():
                        _restore(part.values, key, portable)
                    for key in self.shared:  # this copy of the part still has the old ones
                        copy_value(part.values, self.shared_values, key)
                at += worker.size

    def _start_workers(self) -> None:
        """Fork the workers :meth:`parallel` asked for."""
        workers, self._pending = self._pending, 0
        everything = self._all
        runs = _balanced_runs([p.graph.size() for p in everything.parts], workers)
        context = multiprocessing.get_context("fork")
        self._groups = [PartGroup(everything.parts[a:b], self.shared, self.dims) for a, b in runs]
        self._remote = [_RemoteGroup(g, context) for g in self._groups[1:]]
        self.group = self._groups[0]

    def _each(self, method: str, *args) -> list:
        """``method`` of every group (the workers' at once), per-part answers in part order."""
        if self._pending:
            self._start_workers()
        for worker in self._remote:
            worker.send(method, *args)
        failure: Exception | None = None
        try:
            answers = list(getattr(self.group, method)(*args) or [])
        except Exception as exc:  # raised below, once every worker's answer is read
            failure, answers = exc, []
        for worker in self._remote:  # every worker's answer is read, so the pipes stay in step
            try:
                answers += worker.receive() or []
            except RuntimeError as exc:
                failure = failure or exc
        if failure is not None:
            raise failure
        return answers

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
            self._error = shared + math.fsum(self._each("errors"))
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

    def _system(
        self, lam: float | None
    ) -> tuple[np.ndarray, np.ndarray, gtsam.GaussianFactorGraph]:
        """Every part eliminated to the shared keys with the shared factors added: the
        augmented Hessian on the shared keys, their Hessian diagonal and the shared factors'
        linearization."""
        reduced = self._each("eliminate", lam)
        total = sum((r for r, _ in reduced), np.zeros((self._n + 1, self._n + 1)))
        diagonal = sum((d for _, d in reduced), np.zeros(self._n))
        shared_linear = self.shared_graph.linearize(self.shared_values)
        total = total + augmented_hessian(shared_linear, self.shared, self.dims)
        own = _hessian_diagonal(shared_linear, {k: self.dims[k] for k in self.shared})
        diagonal = diagonal + np.concatenate([own[k] for k in self.shared] or [np.zeros(0)])
        return total, diagonal, shared_linear

    @property
    def _n(self) -> int:
        return sum(self.dims[k] for k in self.shared)

    def shared_information(self) -> np.ndarray:
        """The shared variables' information matrix at the current values (every part's
        variables marginalized), in the order of :attr:`shared`. After :meth:`optimize`
        stopped on a final Gauss–Newton step, that of its last linearization (one step, of at
        most the solve's tolerance, before the current values); else computed at them."""
        if self._information is None:
            total, _, _ = self._system(None)
            self._each("release")
            self._information = total[:-1, :-1].copy()
        return self._information.copy()

    def part_systems(self) -> tuple[list[np.ndarray], np.ndarray]:
        """At the current values, undamped: each part's linearized system eliminated down to
        the shared keys, as an augmented Hessian ``(n+1, n+1)`` in part order, and the shared
        factors' own augmented Hessian. The system of any subset of parts is the sum of its
        members' and the shared one (:mod:`graphcal.graph.segment_systems`)."""
        reduced = self._each("eliminate", None)
        self._each("release")
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
        total, _, shared_linear = self._system(None)
        step = self._by_key(self._solve(total, np.zeros(self._n)))
        predicted = math.fsum(self._each("step", step)) + _predicted_decrease(
            shared_linear.gradientAtZero(), _vector_values(step), {}, self.shared
        )
        self._each("release")
        return predicted

    def _solve(self, total: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """The shared step from the augmented Hessian and a diagonal damping."""
        if self._n == 0:
            return np.zeros(0)
        return np.linalg.solve(total[:-1, :-1] + np.diag(damping), total[:-1, -1])

    def _by_key(self, vector: np.ndarray) -> dict[int, np.ndarray]:
        return dict(zip(self.shared, _split(vector, self.shared, self.dims), strict=True))

    def optimize(
        self,
        max_iterations: int,
        relative_error_tol: float,
        progress: Callable[[str], None] | None = None,
        gauss_newton_first: bool = False,
    ) -> int:
        """Levenberg–Marquardt to convergence from the current values (updated in place);
        returns the iterations used. Raises ``RuntimeError`` from GTSAM (or numpy's
        ``LinAlgError``) if a system cannot be solved at any damping.

        Once a step at no more than the first damping lowered the error by what its
        linearization predicted (within :data:`GAUSS_NEWTON_FIDELITY`), the next steps are
        undamped Gauss–Newton steps; if one fails or is not accepted, the solve damps again
        and stays Levenberg–Marquardt (a log whose parameters are barely determined, such as
        t_r and d on a straight road, needs the damping). The solve stops when an undamped step
        would lower the error by at most ``relative_error_tol`` of it. That step is taken
        without evaluating the error (the error after it is the one predicted, exact to
        far below the tolerance), and its undamped linearization, a step this small from
        the solution, gives :meth:`shared_information` without linearizing again (at the
        sample drive's tolerance, within 5e-5 of the covariance at the solution itself).

        ``gauss_newton_first``: the first step is already undamped (values near the optimum,
        such as a warm start's: no damping to compute).

        ``progress`` gets a line per iteration (χ²/dof, damping λ, elapsed time) once the
        solve has run for :data:`PROGRESS_AFTER_S` (a long log's solve shows it is moving;
        a short one prints nothing)."""
        started = time.perf_counter()
        dof = max(1, self.factor_dims() - self.dim())
        error = self.error()
        shared_scale: np.ndarray | None = None
        lam = LAMBDA_INITIAL
        undamped = gauss_newton_first  # this iteration's step is a Gauss–Newton step
        gauss_newton = True  # until one fails
        iterations = 0
        while iterations < max_iterations:
            iterations += 1
            new_error = error
            at_minimum = False
            how = ""
            while True:
                try:
                    total, diagonal, shared_linear = self._system(None if undamped else lam)
                    shared_scale = (
                        diagonal if shared_scale is None else np.maximum(shared_scale, diagonal)
                    )
                    root = np.sqrt(lam * np.clip(shared_scale, MIN_DIAGONAL, MAX_DIAGONAL))
                    if undamped:
                        root = np.zeros_like(root)
                    shared_step = self._solve(total, root**2)
                    if not np.all(np.isfinite(shared_step)):
                        raise np.linalg.LinAlgError("non-finite step")
                except (RuntimeError, np.linalg.LinAlgError):
                    self._each("release")
                    if undamped:  # not determined without damping: damp, from now on
                        undamped = gauss_newton = False
                        continue
                    # indeterminate at this damping: damp more, as GTSAM does
                    if lam * LAMBDA_FACTOR >= LAMBDA_UPPER_BOUND:
                        raise
                    lam *= LAMBDA_FACTOR
                    continue
                step = self._by_key(shared_step)
                predicted = math.fsum(self._each("step", step)) + _predicted_decrease(
                    shared_linear.gradientAtZero(),
                    _vector_values(step),
                    {} if undamped else self._by_key(root),
                    self.shared,
                )
                small = max(relative_error_tol * error, 1e-12)
                # A Gauss–Newton step that lowers the error by at most the tolerance is the
                # last; its undamped linearization gives the covariance. It is taken without
                # evaluating the error: at that size its decrease is its prediction.
                if undamped and abs(predicted) <= small:  # (rounding: slightly below 0)
                    self._each("try_step", False)
                    self.shared_values = self.shared_values.retract(_vector_values(step))
                    self._each("accept")
                    new_error = error - predicted
                    self._error, self._information = new_error, total[:-1, :-1].copy()
                    at_minimum, how = True, "Gauss–Newton"
                    break
                errors = self._each("try_step")
                candidate_shared = self.shared_values.retract(_vector_values(step))
                new_error = float(self.shared_graph.error(candidate_shared)) + math.fsum(errors)
                change = error - new_error
                fidelity = change / predicted if predicted > 1e-20 else 1.0
                if predicted >= 0 and fidelity > MIN_MODEL_FIDELITY and change >= 0:
                    self.shared_values = candidate_shared
                    self._each("accept")
                    self._error, self._information = new_error, None
                    how = "Gauss–Newton" if undamped else f"λ {lam:.0e}"
                    # Gauss–Newton next if this step was (or needed no more damping than the
                    # first) and its linearization predicted its decrease well.
                    mild = undamped or lam <= LAMBDA_INITIAL
                    if not undamped:
                        lam = max(lam / LAMBDA_FACTOR, 1e-12)
                    undamped = (
                        gauss_newton and mild and abs(fidelity - 1.0) <= GAUSS_NEWTON_FIDELITY
                    )
                    break
                if undamped:  # the model was not good enough: damp, from now on
                    undamped = gauss_newton = False
                    continue
                if abs(change) < small or lam * LAMBDA_FACTOR >= LAMBDA_UPPER_BOUND:
                    new_error, at_minimum, how = error, True, f"λ {lam:.0e}"
                    break
                lam *= LAMBDA_FACTOR
            self._each("release")
            decrease = error - new_error
            # Undamped, the next linearization decides (and serves the covariance).
            small_decrease = decrease <= 1e-12 or decrease <= relative_error_tol * error
            converged = at_minimum or (small_decrease and not undamped)
            error = new_error
            elapsed = time.perf_counter() - started
            if progress is not None and elapsed >= PROGRESS_AFTER_S:
                progress(
                    f"  iteration {iterations}: χ²/dof {2.0 * error / dof:.4f}, {how} "
                    f"({elapsed:.0f} s)"
                )
            if converged:
                break
        return iterations


def _vector_values(by_key: dict[int, np.ndarray]) -> gtsam.VectorValues:
    out = gtsam.VectorValues()
    for key, value in by_key.items():
        out.insert(key, value)
    return out


def _balanced_runs(sizes: list[int], count: int) -> list[tuple[int, int]]:
    """``count`` contiguous runs ``[a, b)`` of items with about equal total size."""
    bounds = np.cumsum([0, *sizes])
    targets = bounds[-1] * np.arange(1, count) / count
    cuts = [0, *np.searchsorted(bounds, targets).tolist(), len(sizes)]
    cuts = sorted(set(min(max(c, 0), len(sizes)) for c in cuts))
    return [(a, b) for a, b in itertools.pairwise(cuts) if b > a]


def optimize_segmented(
    segmented: SegmentedGraph,
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
    progress: Callable[[str], None] | None = None,
    gauss_newton_first: bool = False,
) -> int:
    """:meth:`SegmentedGraph.optimize`, GTSAM's and numpy's exceptions turned into
    ``error_type`` with the message ``"<label> failed: <reason>"``; returns the iterations."""
    try:
        return segmented.optimize(max_iterations, relative_error_tol, progress, gauss_newton_first)
    except (RuntimeError, np.linalg.LinAlgError) as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise error_type(f"{label} failed: {reason}") from exc


def _split(vector: np.ndarray, keys: list[int], dims: dict[int, int]) -> list[np.ndarray]:
    """``vector`` cut into the blocks of ``keys``."""
    out, at = [], 0
    for key in keys:
        out.append(vector[at : at + dims[key]])
        at += dims[key]
    return out


def _predicted_decrease(
    gradient: gtsam.VectorValues,
    step: gtsam.VectorValues,
    root: dict[int, np.ndarray],
    keys: list[int],
) -> float:
    """This system's share of the decrease its linearization predicts for a step of the
    damped normal equations ``(H + Λ) δ = −g`` (``Λ = diag(root²)`` on its damped keys):
    ``−½ gᵀδ + ½ δᵀΛδ`` (as ``δᵀHδ = −gᵀδ − δᵀΛδ``)."""
    total = 0.0
    for key in keys:
        if gradient.exists(key):
            total -= 0.5 * float(np.dot(gradient.at(key), step.at(key)))
    for key, r in root.items():
        total += 0.5 * float(np.sum((r * step.at(key)) ** 2))
    return total


def augmented_hessian(
    linear: gtsam.GaussianFactorGraph, keys: list[int], dims: dict[int, int]
) -> np.ndarray:
    """``[AᵀA Aᵀb; bᵀA bᵀb]`` of ``linear`` on ``keys`` (zero blocks for keys it lacks)."""
    n = sum(dims[k] for k in keys)
    out = np.zeros((n + 1, n + 1))
    if linear.size() == 0:
        return out
    in_linear = set(linear.keyVector())
    present = [k for k in keys if k in in_linear]
    ordering = gtsam.Ordering()
    for key in present:
        ordering.push_back(key)
    hessian = linear.augmentedHessian(ordering)
    starts = dict(zip(keys, np.cumsum([0] + [dims[k] for k in keys])[:-1], strict=True))
    index = np.concatenate(
        [np.arange(starts[k], starts[k] + dims[k]) for k in present] + [np.array([n])]
    ).astype(int)
    out[np.ix_(index, index)] = hessian
    return out


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
