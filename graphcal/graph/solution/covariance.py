"""Covariance from information: every way graphcal turns a graph's information into a
covariance, and theta's and the nuisance variables' covariance of a solved segment graph.

Two routes:

* :func:`covariance_from_information`: from an information matrix (or a stack of them):
  the shared variables of a part-by-part solve, every batch of
  :mod:`graphcal.graph.solution.reduced_systems`;
* :func:`marginal_covariance`: from a graph and its values, by GTSAM's ``Marginals`` (the
  whole-graph solves, where no information matrix is formed in Python).
"""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed, GraphcalError, exception_reason
from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.graph.construction.graph_spec import SegmentGraphSpec, shared_keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.solve import Driver
from graphcal.graph.solution.estimates import NuisanceEstimate, SolvedGraph

#: A batch's information counts as singular when its smallest eigenvalue is below this
#: fraction of its largest (a parameter the batch does not determine at all).
SINGULAR_RATIO = 1e-14


def covariance_from_information(information: np.ndarray) -> np.ndarray:
    """The covariance of a symmetric information matrix ``(n, n)``, or of each of a stack
    ``(B, n, n)``: its inverse, symmetrized. NaN where the information is not finite or is
    singular (its smallest eigenvalue at most :data:`SINGULAR_RATIO` of its largest: a
    variable the measurements do not determine at all)."""
    stack = information.reshape(-1, *information.shape[-2:])
    covariance = np.full(stack.shape, np.nan)
    finite = np.all(np.isfinite(stack), axis=(1, 2))  # eigvalsh raises on a NaN
    if stack.shape[-1] > 0 and np.any(finite):
        eigenvalues = np.linalg.eigvalsh(stack[finite])
        good = finite.copy()
        good[finite] = eigenvalues[:, 0] > SINGULAR_RATIO * np.abs(eigenvalues[:, -1])
        if np.any(good):
            inverse = np.linalg.inv(stack[good])
            covariance[good] = 0.5 * (inverse + inverse.transpose(0, 2, 1))
    covariance[~np.all(np.isfinite(covariance), axis=(1, 2))] = np.nan
    return covariance.reshape(information.shape)


def marginal_covariance(
    graph: gtsam.NonlinearFactorGraph,
    result: gtsam.Values,
    key: int | list[int],
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
    driver: Driver = "gtsam",
) -> np.ndarray:
    """Marginal covariance of ``key`` at ``result`` (all other variables marginalized); for a
    list of keys their joint marginal covariance, blocks in the list's order. ``driver``
    ``"python"`` linearizes on the Python side (see :func:`solve_lm`).

    Raises ``error_type`` (``"<label> failed: <reason>"``) if GTSAM cannot factor the
    information matrix or the covariance is not finite.
    """
    try:
        if driver == "python":
            marginals = gtsam.Marginals(graph.linearize(result), result)
        else:
            marginals = gtsam.Marginals(graph, result)
        if isinstance(key, list) and len(key) > 1:
            joint = marginals.jointMarginalCovariance(gtsam.KeyVector(key))
            covariance = np.block([[joint.at(a, b) for b in key] for a in key])
        else:
            covariance = marginals.marginalCovariance(key[0] if isinstance(key, list) else key)
    except RuntimeError as exc:
        reason = exception_reason(exc)
        raise error_type(f"{label} failed: covariance: {reason}") from exc
    if not np.all(np.isfinite(covariance)):
        raise error_type(f"{label} failed: non-finite covariance")
    return covariance


def with_covariance(solution: SolvedGraph, label: str, workers: int = 1) -> SolvedGraph:
    """``solution`` with theta's marginal covariance and the nuisance estimates computed
    (segment by segment, in ``workers`` processes)."""
    if solution.covariance is not None or not solution.built.spec.estimate_theta:
        return solution
    partitioned = solution.partitioned
    if partitioned is None:  # solved as one graph
        marginal, nuisance = whole_graph_marginals(solution.built, solution.result, label)
        return dataclasses.replace(solution, covariance=marginal, nuisance=nuisance)
    with partitioned.parallel(workers):
        marginal, nuisance = partitioned_marginals(partitioned, solution.built.spec, label)
    return dataclasses.replace(solution, covariance=marginal, nuisance=nuisance)


def whole_graph_marginals(
    built: BuiltGraph, result: gtsam.Values, label: str
) -> tuple[np.ndarray, dict[str, NuisanceEstimate]]:
    """Theta's marginal covariance and the nuisance estimates from GTSAM's marginals; where
    GTSAM's Cholesky of the whole graph fails, from the segments eliminated one part at a
    time down to the shared variables (:func:`partitioned_marginals`).

    The whole graph's information spans every scale at once: a parameter held at its nominal
    (a prior :data:`~graphcal.vehicle.HELD_SIGMA_SCALE` times its own, information ~10¹²)
    beside lateral positions a straight road's fixes sharing their error barely determine
    (~10⁻⁴): a car's 2.1 km straight at 5 Hz, its fixes sharing 6 m, failed "indeterminate"
    at a pivot; by parts the held parameter is met only in the small shared system."""
    shared = shared_keys(built.spec)
    try:
        joint = marginal_covariance(built.graph, result, shared, label, CalibrationFailed)
    except CalibrationFailed:
        return partitioned_marginals(
            PartitionedGraph(built.graph, result, shared), built.spec, label
        )
    return joint[:4, :4], _nuisance(built.spec, result, joint)


def partitioned_marginals(
    partitioned: PartitionedGraph, spec: SegmentGraphSpec, label: str
) -> tuple[np.ndarray, dict[str, NuisanceEstimate]]:
    """Theta's marginal covariance and the graph-wide nuisance estimates at ``partitioned``'s
    values: the inverse of the shared variables' information, every segment's variables
    marginalized."""
    try:
        information = partitioned.shared_information()
    except RuntimeError as exc:
        reason = exception_reason(exc)
        raise CalibrationFailed(f"{label} failed: covariance: {reason}") from exc
    joint = covariance_from_information(0.5 * (information + information.T))
    if not np.all(np.isfinite(joint)):
        raise CalibrationFailed(f"{label} failed: covariance: the information is singular")
    return joint[:4, :4], _nuisance(spec, partitioned.shared_values, joint)


def _nuisance(
    spec: SegmentGraphSpec, values: gtsam.Values, joint: np.ndarray
) -> dict[str, NuisanceEstimate]:
    """The graph-wide nuisance estimates from ``values`` and the joint covariance of theta
    and them (in :meth:`SegmentGraphSpec.nuisance_keys` order after theta)."""
    priors = {
        "time_offset": spec.time_offset_sigma,
        "lever_arm": spec.lever_arm_sigma,
        "rear_slip_gain": spec.rear_slip_gain_sigma,
    }
    nuisance, at = {}, 4
    for name, key in spec.nuisance_keys().items():
        value = np.asarray(values.atVector(key))
        n = len(value)
        nuisance[name] = NuisanceEstimate(value, joint[at : at + n, at : at + n], priors[name])
        at += n
    return nuisance
