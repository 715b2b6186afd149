"""The Levenberg–Marquardt damping follows each step's gain ratio (Nielsen's rule with
GTSAM's tenth as its largest decrease), and the Python driver reaches the minimum GTSAM's
optimizer reaches."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from graphcal.graph.optimization.levenberg_marquardt import (
    LAMBDA_INITIAL,
    LAMBDA_UPPER_BOUND,
    Damping,
)
from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions


def test_a_well_predicted_step_lowers_the_damping_tenfold_a_half_right_one_keeps_it():
    for ratio, factor in ((1.0, 0.1), (1.5, 0.1), (0.95, 1 - 0.9**3), (0.5, 1.0), (0.75, 0.875)):
        damping = Damping(1.0)
        damping.decrease(ratio)
        assert damping.lam == pytest.approx(factor)
    poor = Damping(1.0)
    poor.decrease(0.1)  # accepted, but predicted poorly: damp more, not less
    assert poor.lam == pytest.approx(1.0 + 0.8**3)


def test_rejections_in_a_row_raise_the_damping_ever_faster_until_a_step_is_taken():
    damping = Damping()
    for _ in range(3):
        damping.increase()
    assert damping.lam == pytest.approx(LAMBDA_INITIAL * 2 * 4 * 8)
    damping.decrease(1.0)
    damping.increase()  # the count starts again after an accepted step
    assert damping.lam == pytest.approx(LAMBDA_INITIAL * 64 / 10 * 2)
    while damping.can_increase():
        damping.increase()
    assert damping.lam < LAMBDA_UPPER_BOUND


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
