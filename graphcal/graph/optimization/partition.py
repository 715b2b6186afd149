"""A graph cut into parts that meet only in shared variables (union-find over the factors'
keys, the shared keys left out)."""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.graph.optimization.values import copy_value


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
class Partition:
    """The parts of a graph (in the order their first factor appears) and the factors on
    the shared keys alone."""

    parts: list[GraphPart]
    shared_graph: gtsam.NonlinearFactorGraph


class _UnionFind:
    """Disjoint sets of keys, each named by its root key."""

    def __init__(self) -> None:
        self.parent: dict[int, int] = {}

    def find(self, key: int) -> int:
        parent = self.parent
        while parent.setdefault(key, key) != key:
            parent[key] = parent[parent[key]]
            key = parent[key]
        return key

    def join(self, keys: list[int]) -> None:
        for k in keys[1:]:
            self.parent[self.find(k)] = self.find(keys[0])
        if keys:
            self.find(keys[0])


def partition(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, shared: list[int]
) -> Partition:
    """``graph`` cut into its connected components once the ``shared`` keys are removed; each
    part gets a ``Values`` of its variables and the shared ones, copied from ``values``."""
    shared_set = set(shared)
    factors = [graph.at(i) for i in range(graph.size()) if graph.at(i) is not None]
    sets = _UnionFind()
    for factor in factors:
        sets.join([k for k in factor.keys() if k not in shared_set])
    shared_graph = gtsam.NonlinearFactorGraph()
    by_root: dict[int, gtsam.NonlinearFactorGraph] = {}
    for factor in factors:
        own = [k for k in factor.keys() if k not in shared_set]
        if not own:
            shared_graph.add(factor)
            continue
        by_root.setdefault(sets.find(own[0]), gtsam.NonlinearFactorGraph()).add(factor)
    local_keys: dict[int, list[int]] = {}
    for key in sets.parent:
        local_keys.setdefault(sets.find(key), []).append(key)
    parts = []
    for root, part_graph in by_root.items():
        local = sorted(local_keys[root])
        part_values = gtsam.Values()
        for key in local + shared:
            copy_value(part_values, values, key)
        parts.append(GraphPart(part_graph, local, part_values))
    return Partition(parts, shared_graph)
