"""The Python-driven Levenberg–Marquardt reaches the minimum GTSAM's optimizer reaches on a
problem whose linearization predicts its steps poorly."""

from __future__ import annotations

import gtsam
import numpy as np

from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions


def _curved_valley() -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """Rosenbrock's valley as a graph of one 2-vector: residuals (1 − x, 10 (y − x²)), from
    (−1.2, 1), where a linearization predicts the steps poorly."""

    def error(_, values, jacobians):
        x, y = values.atVector(0)
        if jacobians is not None:
            jacobians[0] = np.array([[-1.0, 0.0], [-20.0 * x, 10.0]])
        return np.array([1.0 - x, 10.0 * (y - x * x)])

    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(2), [0], error))
    values = gtsam.Values()
    values.insert(0, np.array([-1.2, 1.0]))
    return graph, values


def test_the_python_driver_finds_the_minimum_of_a_curved_valley_as_gtsam_does():
    graph, start = _curved_valley()
    options = SolveOptions(200, 1e-12, "curved valley")
    ours, outcome = solve_lm(graph, start, options, driver="python")
    theirs, _ = solve_lm(graph, start, options, driver="gtsam")
    assert outcome.converged
    np.testing.assert_allclose(ours.atVector(0), [1.0, 1.0], atol=1e-5)
    np.testing.assert_allclose(ours.atVector(0), theirs.atVector(0), atol=1e-5)
