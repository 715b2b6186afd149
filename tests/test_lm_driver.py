"""The Python-driven Levenberg–Marquardt reaches the minimum GTSAM's optimizer reaches on a
problem whose linearization predicts its steps poorly."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

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


def test_the_gain_ratios_damping_reaches_the_valleys_minimum_in_fewer_iterations_than_gtsams():
    """λ follows the gain ratio (Nielsen's rule): 17 iterations where GTSAM's ×10 / ÷10
    rejects steps on the way and takes 24."""
    graph, start = _curved_valley()
    options = SolveOptions(200, 1e-12, "curved valley")
    _, ours = solve_lm(graph, start, options, driver="python")
    _, theirs = solve_lm(graph, start, options, driver="gtsam")
    assert ours.converged and theirs.converged
    assert ours.iterations < theirs.iterations


def test_the_damping_follows_the_gain_ratio():
    from graphcal.graph.optimization.levenberg_marquardt import Damping

    damping = Damping(lam=1e-4)
    damping.decrease(1.0)  # a perfect prediction: ÷10, as GTSAM
    assert damping.lam == pytest.approx(1e-5)
    damping.decrease(0.5)  # half the predicted decrease: λ kept
    assert damping.lam == pytest.approx(1e-5)
    damping.increase()  # rejected: ×2, then ×4 …
    damping.increase()
    assert damping.lam == pytest.approx(8e-5)
    damping.decrease(0.9)  # a good step: λ × (1 − 0.8³), and the next rejection ×2 again
    assert damping.lam == pytest.approx(8e-5 * (1 - 0.8**3))
    damping.increase()
    assert damping.lam == pytest.approx(2 * 8e-5 * (1 - 0.8**3))
