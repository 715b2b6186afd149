"""Levenberg–Marquardt as every graphcal solve runs it."""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.errors import GraphcalError, first_line


def solve_lm(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
) -> tuple[gtsam.Values, int]:
    """Optimize ``graph`` from ``values``; return the result and the iterations used.

    Diagonal damping is on: odometry residuals are tight, so the Hessian's diagonal spans many
    orders of magnitude (``docs/performance.md``). GTSAM's exceptions (e.g. an indeterminate linear
    system) become ``error_type`` with the message ``"<label> failed: <reason>"``.
    """
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setDiagonalDamping(True)
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(1e-12)
    try:
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        result = optimizer.optimize()
    except RuntimeError as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise error_type(f"{label} failed: {reason}") from exc
    return result, int(optimizer.iterations())


def gauss_newton_decrement(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
) -> float:
    """How much one Gauss–Newton step from ``values`` would lower ``graph``'s error (half the
    whitened squared residual) on its linearization: ``½ gᵀ H⁻¹ g``.

    For variables that enter almost linearly this is what a full solve gains, at the cost of
    one linearization and one sparse solve (no optimizer, no nonlinear error evaluations).
    Raises ``error_type`` (``"<label> failed: <reason>"``) if the system cannot be solved.
    """
    try:
        linear = graph.linearize(values)
        step = linear.optimize()
    except RuntimeError as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise error_type(f"{label} failed: {reason}") from exc
    return float(linear.error(step.scale(0.0)) - linear.error(step))


def marginal_covariance(
    graph: gtsam.NonlinearFactorGraph,
    result: gtsam.Values,
    key: int | list[int],
    label: str,
    error_type: type[GraphcalError] = GraphcalError,
) -> np.ndarray:
    """Marginal covariance of ``key`` at ``result`` (all other variables marginalized); for a
    list of keys their joint marginal covariance, blocks in the list's order.

    Raises ``error_type`` (``"<label> failed: <reason>"``) if GTSAM cannot factor the
    information matrix or the covariance is not finite.
    """
    try:
        marginals = gtsam.Marginals(graph, result)
        if isinstance(key, list) and len(key) > 1:
            joint = marginals.jointMarginalCovariance(gtsam.KeyVector(key))
            covariance = np.block([[joint.at(a, b) for b in key] for a in key])
        else:
            covariance = marginals.marginalCovariance(key[0] if isinstance(key, list) else key)
    except RuntimeError as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise error_type(f"{label} failed: covariance: {reason}") from exc
    if not np.all(np.isfinite(covariance)):
        raise error_type(f"{label} failed: non-finite covariance")
    return covariance
