"""A first solve that creeps under weights far tighter than its misfit stops there
(``SolveOptions.misweighted_chi2``, ``CreepWatch``), for its caller to read the noise and
solve again; where the caller would not, it goes on to the minimum."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.graph.optimization.levenberg_marquardt import (
    CREEP_ITERATIONS,
    FAR_OFF_CHI2,
    CreepWatch,
    noise_read,
)
from graphcal.graph.optimization.solve_options import SolveOptions, SolveStatus
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.robust import FirstRound, solve_segment_graph_robust
from graphcal.simulate.drive import simulate_drive


def test_a_creep_is_several_slow_iterations_in_a_row_far_above_the_noise():
    watch = CreepWatch(limit=25.0, dof=100)  # χ²/dof = error / 50
    # Fast iterations far above the limit are no creep; nor is one slow one.
    assert not watch.creeping(100_000.0, 20_000.0)
    assert not watch.creeping(20_000.0, 19_000.0)
    assert not watch.creeping(19_000.0, 5_000.0)  # a fast one starts the count again
    slow = [watch.creeping(e, 0.95 * e) for e in (5_000.0, 4_750.0, 4_512.5)]
    assert slow == [False] * (CREEP_ITERATIONS - 1) + [True]
    # Slow iterations near the noise (χ²/dof 1.2, an ordinary solve's convergence) are not.
    near = CreepWatch(limit=25.0, dof=100)
    assert not any(near.creeping(e, 0.99 * e) for e in (62.0, 61.0, 60.0, 59.0, 58.0))
    assert not any(CreepWatch(0.0, 100).creeping(e, 0.99 * e) for e in (1e6, 1e6, 1e6, 1e6))


def _first_round_solved(data, spec, options, head, reweights: bool):
    """A robust solve without rounds whose first solve runs under ``head``, its caller
    solving again (``reweights``) or not."""
    first = FirstRound(lambda *_: reweights, head, lambda *_: reweights)
    return solve_segment_graph_robust(
        data, spec, options, 0.0, covariance=False, first_round=first
    )[0]


@pytest.fixture(scope="module", params=["one-graph", "segment-by-segment"])
def segments(request):
    """Segments and their joint graph's shape: a 1 km drive's, tied into one chain (one
    graph's Levenberg–Marquardt), or a 2 km drive's, each on its own (the partitioned one)."""
    one_graph = request.param == "one-graph"
    log = simulate_drive(1.0 if one_graph else 2.0, seed=2 if one_graph else 4).measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    settings = JointSettings(slip="off", robust_threshold=0.0, tie_segments=one_graph)
    return data, settings.graph_spec(), one_graph


def test_a_creeping_first_solve_stops_only_for_a_caller_that_reweights(segments):
    data, spec, one_graph = segments
    # Near its minimum every solve lowers its error slowly: with no χ²/dof too low to
    # watch, and a tolerance that keeps it iterating there, that is a creep.
    options = SolveOptions(50, 1e-14, "creep test", last_step_sigmas=0.0)
    watched = SolveOptions(50, 1e-14, "creep test", misweighted_chi2=1e-9, last_step_sigmas=0.0)
    full = solve_segment_graph(data, spec, options, covariance=False)
    assert (full.partitioned is None) == one_graph
    assert full.outcome.converged and full.outcome.status is not SolveStatus.MISWEIGHTED

    stopped = solve_segment_graph(data, spec, watched, covariance=False)
    assert stopped.outcome.status is SolveStatus.MISWEIGHTED
    assert stopped.outcome.iterations < full.outcome.iterations
    assert "creeping" in stopped.outcome.message

    def solved(reweights: bool):
        return _first_round_solved(data, spec, options, watched, reweights)

    kept = solved(reweights=True)  # the caller reads the noise at the stop
    assert kept.outcome.status is SolveStatus.MISWEIGHTED
    went_on = solved(reweights=False)  # no caller to reweight: on to the minimum
    assert went_on.outcome.converged and went_on.outcome.status is not SolveStatus.MISWEIGHTED
    assert went_on.outcome.iterations > stopped.outcome.iterations
    assert went_on.final_error <= full.final_error * (1 + 1e-9)
    sigma = np.sqrt(np.diag(solve_segment_graph(data, spec, options).covariance))
    assert np.all(np.abs(went_on.theta - full.theta) < 1e-3 * sigma)


def test_a_solve_far_from_its_weights_reads_its_noise_at_a_looser_tolerance():
    # χ²/dof above FAR_OFF_CHI2: stops at the looser tolerance; near 1, or without one, never
    # — unless its caller reads the noise anywhere (``above_chi2`` 0).
    dof = 1000
    far, near = 0.5 * 10.0 * dof, 0.5 * 1.07 * dof  # ½χ² at χ²/dof 10 and 1.07
    assert noise_read(0.5e-3 * far, far * 1.0005, far, dof, 1e-3)
    assert not noise_read(5e-3 * far, far * 1.005, far, dof, 1e-3)
    assert not noise_read(0.5e-3 * near, near * 1.0005, near, dof, 1e-3)
    assert not noise_read(0.5e-3 * far, far * 1.0005, far, dof, 0.0)
    assert 2.0 * far / dof > FAR_OFF_CHI2 > 2.0 * near / dof
    assert noise_read(0.5e-3 * near, near * 1.0005, near, dof, 1e-3, above_chi2=0.0)
    assert not noise_read(5e-3 * near, near * 1.005, near, dof, 1e-3, above_chi2=0.0)


def test_a_first_solve_under_far_too_tight_weights_stops_where_its_noise_is_read(segments):
    data, spec, _ = segments
    # The fixes and headings weighted as a third of their noise: χ²/dof about 9.
    tight = dataclasses.replace(spec, tracking_sigmas=np.asarray(spec.tracking_sigmas) / 3.0)
    options = SolveOptions(50, 1e-14, "noise read test", last_step_sigmas=0.0)
    reading = SolveOptions(
        50, 1e-14, "noise read test", noise_read_tolerance=1e-3, last_step_sigmas=0.0
    )
    full = solve_segment_graph(data, tight, options, covariance=False)
    read = solve_segment_graph(data, tight, reading, covariance=False)
    assert read.outcome.status is SolveStatus.NOISE_READ
    assert read.outcome.iterations < full.outcome.iterations
    assert read.final_error <= full.final_error * (1 + 1e-3)

    def solved(reweights: bool):
        return _first_round_solved(data, tight, options, reading, reweights)

    assert solved(reweights=True).outcome.status is SolveStatus.NOISE_READ
    went_on = solved(reweights=False)  # no caller to reweight: on to the minimum
    assert went_on.outcome.converged and went_on.outcome.status is not SolveStatus.NOISE_READ
    assert went_on.final_error <= full.final_error * (1 + 1e-9)
    # ... going on from where it stopped (undamped where its steps were): at most the one
    # step more than the solve without a stop that restarting its damping may take
    assert went_on.outcome.iterations <= full.outcome.iterations + 1
