"""A long log's whole-log solve starts from theta solved on a spread-out sample of its
segments: the same optimum, reached from closer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import graphcal.pipeline.solvers.warm_start as warm
from graphcal.graph.construction import keys
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.log.load import load_drive_log
from graphcal.log.segments import (
    SegmentData,
    gather_segments,
    select_segments,
    split_segments,
    spread,
)
from graphcal.model import integrate
from graphcal.pipeline.solvers.joint import solve_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "sample_drive.csv"


def _segments():
    log = load_drive_log(SAMPLE)
    return gather_segments(log, select_segments(log, split_segments(log, 150.0)))


def test_spread_takes_the_first_and_last_and_evenly_between():
    assert spread(10, 4).tolist() == [0, 3, 6, 9]
    assert spread(3, 8).tolist() == [0, 1, 2]


def test_a_short_log_without_ties_starts_from_the_nominal_theta():
    data = _segments()
    spec = JointSettings(tie_segments=False).graph_spec()
    assert len(data) < warm.WARM_START_MIN_SEGMENTS
    assert warm.warm_start(data, spec, SolveOptions(50, 1e-7)) is None


def test_a_short_log_whose_segments_are_tied_starts_from_their_step_1_theta(monkeypatch):
    """A chain of tied segments integrated with the nominal theta drifts metres from its
    fixes: the sample drive's first tied solve took 11 iterations from χ²/dof 7087. With a
    measured heading its theta comes from the segments each held at its measured start (the
    paper's Step 1, no corrections: biased by the wheels' noise, 3 mm in c_e here) — near
    enough for the tied solve, which reaches the optimum it reaches from the segments each
    solved on its own (the start without a heading) in as few iterations."""
    data = _segments()
    spec = JointSettings().graph_spec()
    assert spec.tied(data).any()
    start = warm.warm_start(data, spec, SolveOptions(50, 1e-7))
    step1 = warm._held_start_theta(data, spec, SolveOptions(50, 1e-7), warm.BuilderStart(), ())
    assert start is not None
    np.testing.assert_array_equal(start[keys.THETA], step1)
    settings = JointSettings(slip="off")
    solved, _ = solve_joint(data, settings)
    monkeypatch.setattr(warm, "_held_start_theta", lambda *args: None)
    untied, _ = solve_joint(data, settings)
    sigma = np.sqrt(np.diag(untied.covariance))
    assert np.all(np.abs(solved.theta - untied.theta) < 0.01 * sigma)
    assert solved.outcome.iterations <= 3 and untied.outcome.iterations <= 3


@pytest.mark.slow
def test_the_warm_started_solve_reaches_the_same_optimum(monkeypatch):
    data = _segments()
    settings = JointSettings(slip="off", tie_segments=False)  # untied: no start of its own
    cold, _ = solve_joint(data, settings)
    monkeypatch.setattr(warm, "WARM_START_SEGMENTS", 4)
    monkeypatch.setattr(warm, "WARM_START_MIN_SEGMENTS", 5)
    start = warm.warm_start(data, settings.graph_spec(), SolveOptions(50, 1e-7))
    assert start is not None
    sigma = np.sqrt(np.diag(cold.covariance))
    assert np.all(np.abs(start[keys.THETA] - cold.theta) < 10 * sigma)
    warmed, _ = solve_joint(data, settings)
    assert warmed.initial_error < 0.5 * cold.initial_error  # it did start there
    # The same optimum: within the solve's tolerance, a few thousandths of σ.
    assert np.all(np.abs(warmed.theta - cold.theta) < 0.01 * sigma)
    np.testing.assert_allclose(warmed.covariance, cold.covariance, rtol=1e-3)


def _turning_robot(truth: np.ndarray, segments: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact poses ``(S, K+1, 3)`` and sprocket rotations per 20 ms ``(S, K, 4)`` of a robot
    at 1 m/s whose turns come and go, in ``segments`` of ``steps``, under ``truth``."""
    turn = 0.6 * np.sin(np.arange(segments * steps) * 0.02 / 7.0)
    left = (1.0 - 0.5 * truth[2] * turn) * 0.02 / (truth[0] + 0.5 * truth[1])
    right = (1.0 + 0.5 * truth[2] * turn) * 0.02 / (truth[0] - 0.5 * truth[1])
    inputs = np.zeros((segments, steps, 4))
    inputs[..., 0] = left.reshape(segments, steps)
    inputs[..., 1] = right.reshape(segments, steps)
    return integrate(np.zeros((segments, 3)), inputs, truth), inputs


def test_a_coarse_search_finds_a_track_twice_the_nominal():
    """A skid-steer robot's effective track is about twice its datasheet's: on the nominal's
    odometry it turns twice too fast, a path a local solver did not untangle (100
    iterations, χ²/dof 18). The coarse search starts the solve from the scales that fit."""
    rng = np.random.default_rng(3)
    nominal = np.array([0.8, 0.0, 0.55, 0.0])
    truth = np.array([0.78, 0.0006, 1.1, 0.0])
    steps, segments = 2500, 4
    poses, inputs = _turning_robot(truth, segments, steps)
    poses[..., :2] += rng.normal(0.0, 1.0, poses[..., :2].shape)
    data = SegmentData(poses, inputs, np.full(segments, steps), np.ones(poses.shape[:2], bool))
    coarse = warm.coarse_theta(data, nominal)
    assert coarse is not None
    assert abs(coarse[2] / truth[2] - 1.0) < 0.1 and abs(coarse[0] / truth[0] - 1.0) < 0.05
    assert warm.coarse_theta(data, truth) is None  # the nominal that fits is kept


def test_a_measured_heading_shows_the_track_where_sparse_noisy_fixes_do_not():
    """Seed 32's shape 198 of the campaign: a skid-steer robot, two 53 m segments of 1 Hz
    fixes of 0.85 m with a heading. Its fixes alone did not move the coarse search off the
    nominal; the solve stayed at t_r 0.52 m (truth 1.08) with the heading 7° off, "not to be
    trusted". Weighed by their sigmas, the measured headings show how fast the odometry
    turns, c_e / t_r (the fixes, what c_e is)."""
    rng = np.random.default_rng(5)
    nominal = np.array([0.8, 0.0, 0.55, 0.0])
    truth = np.array([0.785, 0.0006, 1.08, 0.0])
    steps, segments, every = 2500, 2, 50
    poses, inputs = _turning_robot(truth, segments, steps)
    poses[..., :2] += rng.normal(0.0, 5.0, poses[..., :2].shape)
    poses[..., 2] += rng.normal(0.0, 0.005, poses.shape[:2])
    measured = np.zeros((*poses.shape[:2], 2), bool)
    measured[:, ::every] = True
    valid = np.ones(poses.shape[:2], bool)
    data = SegmentData(poses, inputs, np.full(segments, steps), valid, 0.02, measured=measured)
    sigmas = np.array([5.0, 5.0, 0.005])

    def turning_off(theta: np.ndarray | None) -> float:
        theta = nominal if theta is None else theta
        return abs((theta[0] / theta[2]) / (truth[0] / truth[2]) - 1.0)

    assert turning_off(warm.coarse_theta(data, nominal)) > 0.3  # the fixes alone: no
    assert turning_off(warm.coarse_theta(data, nominal, sigmas)) < 0.05
    assert warm.coarse_theta(data, truth, sigmas) is None  # the nominal that fits is kept
