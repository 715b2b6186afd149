"""The segment-by-segment solve gives the single graph's estimate and covariance."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest

from graphcal.errors import CalibrationFailed
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.part_group import PartGroup
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.partitioned_lm import optimize
from graphcal.graph.optimization.solve import solve_lm
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.optimization.values import portable, restore
from graphcal.graph.solution import covariance
from graphcal.graph.solution.covariance import marginal_covariance
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.load import load_drive_log
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "sample_drive.csv"


def _sample_segments():
    log = load_drive_log(SAMPLE)
    return gather_segments(log, select_segments(log, split_segments(log, 150.0)))


@pytest.mark.slow
def test_segmented_solve_matches_the_single_graph_on_the_sample_drive():
    data = _sample_segments()
    spec = JointSettings(slip="on").graph_spec()  # theta, time offset, lever arm and slip
    built = build_segment_graph(data, spec)
    shared = shared_keys(spec)
    # The two solvers take different steps, so they agree to their tolerance. 1e-6 of c_d
    # (1.05 σ from 0 here) or of d (5.9 σ) is a few millionths of a σ: a point 1e-15 of this
    # graph's error above the minimum. At a tolerance of 1e-9 they differ by 3e-6 of d (and
    # GTSAM's own solve moves d by 2e-6 from 1e-9 to 1e-12); at 1e-14, by 1.4e-7.
    single, _ = solve_lm(built.graph, built.values, SolveOptions(50, 1e-14, "single graph"))
    single_covariance = marginal_covariance(built.graph, single, shared, "single graph")

    solution = solve_segment_graph(
        data, spec, SolveOptions(50, 1e-14, "segmented", last_step_sigmas=0.0)
    )

    theta = solution.theta
    reference = single.atVector(keys.THETA)
    assert np.max(np.abs(theta - reference) / np.abs(reference)) < 1e-6
    segmented = np.linalg.inv(solution.partitioned.shared_information())
    scale = np.sqrt(np.outer(np.diag(single_covariance), np.diag(single_covariance)))
    assert np.max(np.abs(segmented - single_covariance) / scale) < 1e-4
    assert np.allclose(solution.covariance, single_covariance[:4, :4], rtol=1e-4, atol=0)
    # Every chain of tied segments (a segment not tied to the one before starts one) is its
    # own part; the error is the single graph's at the same values.
    chains = len(data) - int(np.count_nonzero(spec.tied(data)))
    assert 1 < chains < len(data)  # the sample drive's stretches hold several segments
    assert len(solution.partitioned.parts) == chains
    assert np.isclose(solution.final_error, built.graph.error(solution.result), rtol=1e-12)


def test_segmented_graph_splits_at_the_shared_keys_only():
    # Two chains a-b and c-d tied by a shared key s: two parts; the prior on s alone is shared.
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    a, b, c, d, s = (gtsam.symbol("x", i) for i in range(5))
    noise = gtsam.noiseModel.Isotropic.Sigma(1, 1.0)
    for key in (a, b, c, d, s):
        values.insert(key, np.array([float(key % 7)]))
    graph.add(gtsam.BetweenFactorVector(a, b, np.array([1.0]), noise))
    graph.add(gtsam.BetweenFactorVector(b, s, np.array([1.0]), noise))
    graph.add(gtsam.BetweenFactorVector(c, d, np.array([2.0]), noise))
    graph.add(gtsam.BetweenFactorVector(d, s, np.array([-1.0]), noise))
    graph.add(gtsam.PriorFactorVector(s, np.array([0.5]), noise))
    graph.add(gtsam.PriorFactorVector(a, np.array([0.0]), noise))
    segmented = PartitionedGraph(graph, values, [s])
    assert sorted(sorted(p.local) for p in segmented.parts) == [[a, b], [c, d]]
    assert segmented.shared_graph.size() == 1
    outcome = optimize(segmented, SolveOptions(20, 1e-12))
    result = segmented.values()
    # The linear problem's exact optimum, solved as one graph.
    exact = graph.linearize(values).optimize()
    for key in (a, b, c, d, s):
        expected = values.atVector(key) + exact.at(key)
        assert np.allclose(result.atVector(key), expected, atol=1e-9)
    assert outcome.converged and outcome.iterations <= 3


@pytest.mark.slow
def test_segments_shared_out_among_workers_give_the_same_result():
    data = _sample_segments()
    spec = JointSettings().graph_spec()
    one = solve_segment_graph(data, spec, SolveOptions(50, 1e-7, "one process"))
    two = solve_segment_graph(data, spec, SolveOptions(50, 1e-7, "two processes", workers=2))
    # Per-segment answers are combined in segment order: bit-identical, whatever the workers.
    assert np.array_equal(one.theta, two.theta)
    assert np.array_equal(one.covariance, two.covariance)
    assert one.iterations == two.iterations
    assert one.final_error == two.final_error
    assert one.degrees_of_freedom == two.degrees_of_freedom
    assert np.array_equal(one.start_states, two.start_states)
    for name, estimate in one.nuisance.items():
        assert np.array_equal(estimate.value, two.nuisance[name].value)
    # the segments' own values come back from the workers to the bit (the fixes' residuals,
    # and the position noise from them, differed in the last digits with 2 workers)
    residuals_one = one.built.fix_residuals(one.result, one.partitioned)
    residuals_two = two.built.fix_residuals(two.result, two.partitioned)
    assert np.array_equal(residuals_one, residuals_two)


def test_a_pose_sent_to_another_process_comes_back_to_the_bit():
    rng = np.random.default_rng(3)
    values = gtsam.Values()
    for key in range(500):
        values.insert(key, gtsam.Pose2(*rng.normal(size=3)).retract(rng.normal(size=3)))
    back = gtsam.Values(values)
    for key in range(500):
        restore(back, key, portable(values, key))
        a, b = values.atPose2(key), back.atPose2(key)
        assert (a.x(), a.y(), a.rotation().c(), a.rotation().s()) == (
            b.x(),
            b.y(),
            b.rotation().c(),
            b.rotation().s(),
        )


@pytest.mark.slow
def test_a_failed_call_in_one_process_leaves_the_workers_in_step():
    # An elimination that fails in this process (as an indeterminate system does, which the
    # optimizer answers with more damping) must still read the workers' answers to the same
    # call, or every later answer would belong to the call before it.
    data = _sample_segments()
    spec = JointSettings().graph_spec()
    one = solve_segment_graph(data, spec, SolveOptions(50, 1e-10, "one process"))
    built = build_segment_graph(data, spec)
    segmented = PartitionedGraph(built.graph, built.values, shared_keys(spec))
    with segmented.parallel(2):
        segmented.error()  # the workers start with the first call
        local = segmented.workers.local
        original = local.eliminate
        calls = []

        def failing_once(lam, keep=True):
            calls.append(lam)
            if len(calls) == 1:
                raise RuntimeError("indeterminate linear system")
            return original(lam, keep)

        local.eliminate = failing_once
        optimize(segmented, SolveOptions(50, 1e-10))
    theta = segmented.shared_values.atVector(keys.THETA)
    assert len(calls) > 1 and calls[1] > calls[0]  # damped more after the failure
    # The same optimum from another damping path: within a thousandth of a sigma.
    assert np.all(np.abs(theta - one.theta) < 1e-3 * one.theta_sigma)


def _cubic_graph() -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, int]:
    """Two parts ``x³ = 1`` tied to a shared key s, started at x = 0.1, where an undamped
    step overshoots to x ≈ 33."""
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    s = gtsam.symbol("s", 0)
    values.insert(s, np.array([1.0]))
    graph.add(gtsam.PriorFactorVector(s, np.array([1.0]), gtsam.noiseModel.Unit.Create(1)))

    def cubic(_factor, v, H):
        x = v.atVector(_factor.keys()[0])[0]
        if H is not None:
            H[0] = np.array([[3.0 * x * x]])
        return np.array([x**3 - 1.0])

    for i in range(2):
        x = gtsam.symbol("x", i)
        values.insert(x, np.array([0.1]))
        graph.add(gtsam.CustomFactor(gtsam.noiseModel.Unit.Create(1), [x], cubic))
        graph.add(
            gtsam.BetweenFactorVector(x, s, np.zeros(1), gtsam.noiseModel.Isotropic.Sigma(1, 10.0))
        )
    return graph, values, s


def test_a_failed_gauss_newton_step_falls_back_to_damping(monkeypatch):
    graph, values, s = _cubic_graph()
    damped = PartitionedGraph(graph, values, [s])
    optimize(damped, SolveOptions(100, 1e-12))
    dampings = []
    eliminate = PartGroup.eliminate

    def recording(self, lam, keep=True):
        dampings.append(lam)
        return eliminate(self, lam, keep)

    monkeypatch.setattr(PartGroup, "eliminate", recording)
    first = PartitionedGraph(graph, values, [s])
    optimize(first, SolveOptions(100, 1e-12), gauss_newton_first=True)
    # The undamped first step overshoots and is not taken; every later step is damped.
    assert dampings[0] is None and all(lam is not None for lam in dampings[1:])
    for solved in (damped, first):
        x = solved.values().atVector(gtsam.symbol("x", 0))[0]
        assert abs(x - 1.0) < 1e-3


def test_where_gtsams_cholesky_fails_the_covariance_comes_by_parts(monkeypatch):
    # A car's straight road whose fixes share 6 m of error, d held at its nominal: GTSAM's
    # Cholesky of the whole graph met information from 1e-4 to 1e12 and failed. By parts the
    # same marginal comes out (here on the sample drive, where both routes work).
    data = _sample_segments()
    spec = JointSettings().graph_spec()  # theta, time offset and lever arm
    built = build_segment_graph(data, spec)
    expected, expected_nuisance = covariance.whole_graph_marginals(built, built.values, "whole")

    def indeterminate(*args, **kwargs):
        raise CalibrationFailed("whole failed: covariance: Indeterminate linear system")

    monkeypatch.setattr(covariance, "marginal_covariance", indeterminate)
    by_parts, nuisance = covariance.whole_graph_marginals(built, built.values, "whole")

    assert np.allclose(by_parts, expected, rtol=1e-6, atol=0)
    assert nuisance.keys() == expected_nuisance.keys() and nuisance
    for name, estimate in nuisance.items():
        assert np.array_equal(estimate.value, expected_nuisance[name].value)
        assert np.allclose(
            estimate.covariance, expected_nuisance[name].covariance, rtol=1e-6, atol=1e-18
        )
