"""The per-part work of the part-by-part solve: linearize, damp and eliminate each part down
to the shared keys, back-substitute the shared step, try and accept the step."""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.graph.optimization.levenberg_marquardt import Damping, raised_scale
from graphcal.graph.optimization.linear_systems import (
    SharedBlock,
    add_damping,
    hessian_diagonal_by_key,
    predicted_decrease,
    shared_block,
    vector_values,
)
from graphcal.graph.optimization.partition import GraphPart
from graphcal.graph.optimization.rollout import LinearGap, chunk_links, linear_gaps, rolled_out
from graphcal.graph.optimization.values import Portable, portable


@dataclass
class _Eliminated:
    """A part's damped system eliminated to the shared keys: what the step needs."""

    bayes_net: gtsam.GaussianBayesNet
    gradient: gtsam.VectorValues
    root: dict[int, np.ndarray]
    gaps: list[LinearGap]


class PartGroup:
    """Parts of a :class:`~graphcal.graph.optimization.partitioned.PartitionedGraph` and the
    requests the optimizer sends them; every answer is small (shared-size arrays and floats), so a
    group can live in another process (:mod:`graphcal.graph.optimization.part_workers`).

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
        self._links = [chunk_links(part.graph) for part in parts]

    def errors(self) -> list[float]:
        """Each part's error at its values."""
        return [float(p.graph.error(p.values)) for p in self.parts]

    def eliminate(
        self, lam: float | None, keep: bool = True
    ) -> list[tuple[SharedBlock, np.ndarray]]:
        """Linearize every part, damp its local keys by ``λ · scale`` (``None``: undamped)
        and eliminate them; per part, its reduced system as the block of the augmented
        Hessian on the shared keys it touches and its Hessian diagonal on them ``(n,)``
        (zeros when undamped: only damping needs it). With ``keep``, what :meth:`step`
        needs is kept (each part's Bayes net, gradient and gaps); without, each part's is
        dropped as soon as its reduced system is out — a pass that wants the reduced systems
        alone (information, the segments' systems) then holds one part's at a time, not the
        whole log's."""
        out = []
        self._eliminated = []
        n = sum(self.dims[k] for k in self.shared)
        for part, links in zip(self.parts, self._links, strict=True):
            linear = part.graph.linearize(part.values)
            shared_diagonal, root = np.zeros(n), {}
            if lam is not None:
                shared_diagonal, root = self._damping(part, linear, Damping(lam))
            if keep:
                gradient = linear.gradientAtZero()
                gaps = linear_gaps(part.graph, linear, links, self.dims)
            add_damping(linear, self.dims, root)  # the linear system is not kept: damp it
            bayes_net, reduced = linear.eliminatePartialSequential(gtsam.KeyVector(part.local))
            out.append((shared_block(reduced, self.shared, self.dims), shared_diagonal))
            if keep:
                self._eliminated.append(_Eliminated(bayes_net, gradient, root, gaps))
        return out

    def _damping(
        self, part: GraphPart, linear: gtsam.GaussianFactorGraph, damping: Damping
    ) -> tuple[np.ndarray, dict[int, np.ndarray]]:
        """Raise ``part``'s damping scale to the Hessian diagonal of ``linear`` (the largest
        diagonal seen, GTSAM's); the diagonal on the shared keys and the damping's roots on
        the local ones."""
        dims = {k: self.dims[k] for k in (*part.local, *self.shared)}
        diagonal = hessian_diagonal_by_key(linear, dims)
        local = {k: diagonal[k] for k in part.local}
        if part.scale is None:
            part.scale = local
        else:
            part.scale = {k: raised_scale(part.scale[k], local[k]) for k in part.scale}
        shared_diagonal = np.concatenate([diagonal[k] for k in self.shared] or [np.zeros(0)])
        return shared_diagonal, {k: damping.roots(v) for k, v in part.scale.items()}

    def step(self, shared_step: dict[int, np.ndarray]) -> list[float]:
        """Back-substitute every part given the shared step; per part, what the step lowers
        its linearized error by (undamped). The steps are kept for :meth:`try_step`."""
        given = vector_values(shared_step)
        out = []
        self._deltas = []
        for part, done in zip(self.parts, self._eliminated, strict=True):
            delta = done.bayes_net.optimize(given)
            for key in self.shared:
                if not delta.exists(key):
                    delta.insert(key, given.at(key))
            keys = [*part.local, *self.shared]
            out.append(predicted_decrease(done.gradient, delta, done.root, keys))
            self._deltas.append(delta)
        return out

    def try_step(self, evaluate: bool = True) -> list[float]:
        """Each part's error after the last :meth:`step` (with ``evaluate``; else 0), its
        chunk-boundary poses rolled out onto the odometry of the step's values
        (:func:`~graphcal.graph.optimization.rollout.rolled_out`; not for a step taken unevaluated,
        too small to leave a gap); the candidate values are kept for :meth:`accept`."""
        out = []
        self._candidates = []
        parts = zip(self.parts, self._deltas, self._links, self._eliminated, strict=True)
        for part, delta, links, done in parts:
            candidate = part.values.retract(delta)
            if evaluate:
                gaps = [gap.at(delta) for gap in done.gaps]
                candidate = rolled_out(part.graph, candidate, links, gaps)
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

    def local_values(self) -> list[dict[int, Portable]]:
        """Each part's local variables, picklable
        (:func:`~graphcal.graph.optimization.values.portable`)."""
        return [{key: portable(part.values, key) for key in part.local} for part in self.parts]
