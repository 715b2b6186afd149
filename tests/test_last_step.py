"""The part-by-part solve ends at a Gauss–Newton step that moves no variable by more than
``SolveOptions.last_step_sigmas`` of its σ (its predicted decrease ½ δᵀHδ bounds every
variable's move: |δᵢ| ≤ √(δᵀHδ) σᵢ)."""

from __future__ import annotations

import numpy as np

from graphcal.graph.optimization.levenberg_marquardt import last_step_tolerance
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.simulate.drive import simulate_drive


def test_the_last_step_tolerance_is_a_move_of_a_share_of_sigma_or_the_relative_one():
    # ½ s²: a step predicted to lower ½χ² by 0.005 moves no variable by more than 0.1 σ.
    assert last_step_tolerance(1e3, 1e-7, 0.1) == 0.5 * 0.1**2
    assert last_step_tolerance(1e6, 1e-7, 0.1) == 1e6 * 1e-7  # a long log's is larger
    assert last_step_tolerance(1e3, 1e-7, 0.0) == 1e3 * 1e-7


def test_a_solve_ends_where_its_step_moves_no_variable_by_a_tenth_of_its_sigma():
    log = simulate_drive(2.0, seed=4).measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    spec = JointSettings(slip="off", robust_threshold=0.0, tie_segments=False).graph_spec()
    exact = solve_segment_graph(data, spec, SolveOptions(50, 1e-14, "exact", last_step_sigmas=0))
    solved = solve_segment_graph(data, spec, SolveOptions(50, 1e-14, "to a tenth of σ"))
    assert solved.partitioned is not None  # the part-by-part solve
    assert solved.outcome.converged
    assert solved.outcome.iterations < exact.outcome.iterations
    sigma = np.sqrt(np.diag(exact.covariance))
    # Its last step moved theta by at most 0.1 σ, and was taken: near the minimum each
    # Gauss–Newton step leaves about the square of the last one's share (here 6e-5 σ).
    assert np.all(np.abs(solved.theta - exact.theta) < 1e-3 * sigma)
    np.testing.assert_allclose(solved.covariance, exact.covariance, rtol=1e-3)
