"""Segment systems: one elimination per segment answers every batch (issue 14)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.evaluation import cramer_rao_bounds
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.solution.covariance import marginal_covariance
from graphcal.graph.solution.reduced_systems import ReducedSystems, reduced_systems
from graphcal.log.segments import gather_segments, make_batches, select_segments, split_segments
from graphcal.pipeline.methods.joint_batches import solve_joint_batches
from graphcal.pipeline.solvers.joint import solve_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings


@pytest.fixture(scope="module")
def segments(drive):
    log = drive.measured
    selected = select_segments(log, split_segments(log, 150.0, stride=50.0))  # 8 segments
    return gather_segments(log, selected), gather_segments(drive.truth, selected)


#: The batches' settings in a joint run: robust weights already found, slip as decided.
BATCH_SETTINGS = JointSettings(robust_threshold=0.0, slip="off")


def test_key_packing_gives_back_the_segment():
    assert keys.segment_of(keys.segment_pose(7, 3)) == 7
    assert keys.segment_of(keys.segment_corrections(12, 0)) == 12
    assert keys.segment_of(keys.segment_heading_bias(0)) == 0


def test_batch_bound_from_segment_systems_is_the_batch_graphs_own(drive, segments):
    """Summing the segments' reduced information is exact: the bound of each batch equals
    the marginal of the batch's own graph at the truth."""
    data, truth = segments
    batches = make_batches(len(data), 3, 3, seed=1)
    bounds = cramer_rao_bounds(data, truth, drive.theta_true, batches)
    spec = JointSettings().graph_spec(theta_prior=False)
    for bound, batch in zip(bounds, batches, strict=True):
        one, true_one = data.take(batch), truth.take(batch)
        built = build_segment_graph(one, spec)
        states = [true_one.segment(s)[0] for s in range(len(one))]
        corrections = [
            true_one.segment(s)[1][:, :2] - one.segment(s)[1][:, :2] for s in range(len(one))
        ]
        values = built.values_at(states, corrections, drive.theta_true)
        own = marginal_covariance(built.graph, values, keys.THETA, "bound")
        np.testing.assert_allclose(bound, own, rtol=1e-6, atol=1e-6 * np.abs(own).max())


@pytest.mark.slow
def test_all_segments_at_the_solution_give_the_whole_logs_covariance(segments):
    """At the whole-log solution the sum over every segment is the whole log's system: no
    step, and the covariance the solve reported (which the solve took from its last
    linearization, one step of at most its tolerance before: 5e-5 relative here); exactly
    the information at the solution."""
    data, _ = segments
    whole, values = solve_joint(data, BATCH_SETTINGS)
    spec = BATCH_SETTINGS.graph_spec()
    built = build_segment_graph(data, spec)
    segmented = PartitionedGraph(built.graph, values, shared_keys(spec))
    systems = reduced_systems(segmented, len(data))
    solution = systems.solve(np.arange(len(data))[None])
    np.testing.assert_allclose(solution.covariance[0, :4, :4], whole.covariance, rtol=1e-4)
    at_solution = np.linalg.inv(segmented.shared_information())
    np.testing.assert_allclose(solution.covariance[0], at_solution, rtol=1e-9)
    step = (solution.values[0, :4] - whole.theta) / whole.theta_sigma
    assert np.all(np.abs(step) < 1e-3)


@pytest.mark.slow
def test_linearized_batches_are_the_exact_solves(segments):
    """Linearized at the whole-log solution, each batch's theta is its own Levenberg–Marquardt
    solve's to a small fraction of its σ, with the same σ; linearized at the builder's
    start (nominal theta) instead, the same step is far off: the linearization point is
    what makes it right."""
    data, _ = segments
    batches = make_batches(len(data), 5, 3, seed=2)
    _, values = solve_joint(data, BATCH_SETTINGS)
    linearized = solve_joint_batches(data, batches, BATCH_SETTINGS, "linearized", values)
    exact = solve_joint_batches(data, batches, BATCH_SETTINGS, "exact")
    at_start = solve_joint_batches(data, batches, BATCH_SETTINGS, "linearized", None)
    far = 0.0
    for lin, ex, start in zip(linearized, exact, at_start, strict=True):
        sigma = np.sqrt(np.diag(ex.covariance))
        assert np.all(np.abs(lin.theta - ex.theta) < 0.02 * sigma)
        np.testing.assert_allclose(np.sqrt(np.diag(lin.covariance)), sigma, rtol=0.01)
        assert lin.observability.calibrated.all()
        if start is not None:
            far = max(far, float(np.max(np.abs(start.theta - ex.theta) / sigma)))
    assert far > 0.5


def test_a_batch_that_determines_nothing_is_not_solved():
    shared = np.zeros((3, 3))
    shared[:2, :2] = np.diag([1.0, 1.0])
    segments = np.zeros((2, 3, 3))
    segments[0, 0, 0] = 4.0  # segment 0 informs the first variable only
    segments[1, :2, :2] = [[4.0, 0.0], [0.0, 4.0]]
    segments[1, :2, 2] = segments[1, 2, :2] = [5.0, 5.0]
    systems = ReducedSystems((1, 2), np.array([1.0, 2.0]), segments, shared)
    solution = systems.solve(np.array([[0], [1], [0]]))
    assert solution.solved.tolist() == [True, True, True]
    np.testing.assert_allclose(solution.values[1], [2.0, 3.0])  # point + (I + 4I)⁻¹ [5, 5]
    np.testing.assert_allclose(solution.covariance[0], np.diag([0.2, 1.0]))
    broken = systems.segments.copy()
    broken[0, 0, 0] = np.nan  # one segment's system broken: only its batches fail
    nan_solution = dataclasses.replace(systems, segments=broken).solve(np.array([[0], [1]]))
    assert nan_solution.solved.tolist() == [False, True]
    singular = dataclasses.replace(systems, shared=np.zeros((3, 3)))
    unsolved = singular.solve(np.array([[0], [1]]))
    assert unsolved.solved.tolist() == [False, True]
    assert np.all(np.isnan(unsolved.values[0])) and np.all(np.isnan(unsolved.covariance[0]))


def test_unknown_joint_solve_is_refused():
    from graphcal.pipeline.configuration.settings import BatchingSettings

    with pytest.raises(ValueError, match="joint_solve"):
        BatchingSettings(joint_solve="approximate")


def test_batch_solve_from_the_command_line_and_the_config(tmp_path):
    from graphcal.cli import build_parser
    from graphcal.cli.options import settings_from_args

    parse = build_parser().parse_args
    assert settings_from_args(parse(["calibrate", "x.csv"])).batches.joint_solve == "linearized"
    args = parse(["calibrate", "x.csv", "--batch-solve", "exact"])
    assert settings_from_args(args).batches.joint_solve == "exact"
    config = tmp_path / "cfg.toml"
    config.write_text('[batches]\njoint_solve = "exact"\n')
    args = parse(["calibrate", "x.csv", "--config", str(config)])
    assert settings_from_args(args).batches.joint_solve == "exact"
