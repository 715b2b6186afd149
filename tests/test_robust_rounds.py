"""The robust reweighting of the fixes (graphcal.pipeline.solvers.robust): its rounds go on
from where an earlier solve of the same segments stopped, and stop once theta has settled."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.segment_solve import ValuesStart, solve_segment_graph
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.pipeline.solvers.robust import RoundsStart, solve_robust
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


@pytest.fixture(scope="module")
def outlying():
    """A 2 km drive with 0.5 % of its fixes 10–50 m off, its segments and joint graph."""
    log = degrade(simulate_drive(2.0, seed=4), parse_defects("outliers"), seed=3).measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    return data, JointSettings(slip="off", tie_segments=False).graph_spec()


def _counted_solve(data, spec, calls):
    options = SolveOptions(50, 1e-7, "robust test")

    def solve(segments, initial):
        calls.append(1)
        start = None if initial is None else ValuesStart(initial)
        return solve_segment_graph(segments, spec, options, start=start, covariance=False)

    return solve


def test_rounds_from_an_earlier_solve_stop_once_theta_settles(outlying):
    data, spec = outlying
    first_calls: list[int] = []
    first, weights, _ = solve_robust(data, spec, _counted_solve(data, spec, first_calls), 3.0)
    assert weights is not None and (weights < 0.5).sum() >= 3  # the outliers found
    weighted = dataclasses.replace(data, fix_weights=weights)
    covariance = solve_segment_graph(weighted, spec, SolveOptions(50, 1e-7)).covariance
    sigma = np.sqrt(np.diag(covariance))
    again_calls: list[int] = []
    again, _, _ = solve_robust(
        data,
        spec,
        _counted_solve(data, spec, again_calls),
        3.0,
        start=RoundsStart(weights, sigma),
    )
    assert len(again_calls) < len(first_calls)
    assert np.all(np.abs(again.theta - first.theta) <= 0.1 * sigma)


def test_rounds_whose_weights_keep_trading_stop_when_theta_has_settled(outlying, monkeypatch):
    """Fixes in a spike trade weight from round to round (here: any change counts); with an
    earlier solve's σ, or the σ the first solve's last linearization gives, the rounds stop
    once one moves theta by less than 0.05σ."""
    import graphcal.pipeline.solvers.robust as robust

    monkeypatch.setattr(robust, "WEIGHT_TOLERANCE", 0.0)
    data, spec = outlying
    calls: list[int] = []
    with monkeypatch.context() as unknown:  # no σ at all: only the limit stops them
        unknown.setattr(robust, "_known_theta_sigma", lambda solution: None)
        full, weights, _ = solve_robust(data, spec, _counted_solve(data, spec, calls), 3.0)
    assert len(calls) == 5  # the limit: the weights never stop changing by "0"
    weighted = dataclasses.replace(data, fix_weights=weights)
    sigma = np.sqrt(np.diag(solve_segment_graph(weighted, spec, SolveOptions(50, 1e-7)).covariance))
    settled: list[int] = []
    early, _, _ = solve_robust(
        data, spec, _counted_solve(data, spec, settled), 3.0, start=RoundsStart(None, sigma)
    )
    assert len(settled) < 5
    assert np.all(np.abs(early.theta - full.theta) <= 0.1 * sigma)
    own: list[int] = []  # no earlier solve: the first solve's own σ
    first, _, _ = solve_robust(data, spec, _counted_solve(data, spec, own), 3.0)
    assert len(own) < 5
    assert np.all(np.abs(first.theta - full.theta) <= 0.1 * sigma)


def test_rounds_end_at_the_first_where_a_solve_under_other_settings_follows(outlying):
    """A first solve whose residuals change the noise levels is solved again under them:
    its rounds end at the first, handing on the weights its residuals give (the outliers
    already down-weighted, for the noise to be judged without them and the next solve to
    go on from)."""
    data, spec = outlying
    calls: list[int] = []
    asked: list[np.ndarray] = []

    def ends(solution, weights) -> bool:
        asked.append(weights)
        return True

    _, weights, residuals = solve_robust(
        data, spec, _counted_solve(data, spec, calls), 3.0, stop_after_first=ends
    )
    assert len(calls) == 1 and len(asked) == 1
    assert weights is asked[0] and (weights < 0.5).sum() >= 3
    assert residuals is None  # not computed under the weights handed on
    going_on: list[int] = []
    solve_robust(
        data, spec, _counted_solve(data, spec, going_on), 3.0, stop_after_first=lambda *_: False
    )
    assert len(going_on) > 1  # asked, and not ended: the rounds go on


def test_the_down_weighted_line_counts_fixes_not_samples():
    """1 Hz fixes on a 40 Hz log: "1 of 4575 fixes" was the samples of a log of 60 fixes,
    and a town car's 19 outliers at 5 Hz read "142 of 1770 fixes down-weighted" (the samples
    between fixes carry the weights too)."""
    from graphcal.pipeline.methods.sensor_estimates import DownWeightedFixes

    log = simulate_drive(1.0, seed=4).measured
    measured = np.ones((len(log.t), 2), bool)
    measured[np.arange(len(measured)) % 40 != 0, 0] = False  # a fix each 40th sample
    sparse = dataclasses.replace(log, measured=measured)
    data = gather_segments(sparse, split_segments(sparse, 150.0))
    weights = np.ones(data.valid.shape)
    fixes_of_log = np.unique(data.sample_index[data.valid & data.measured[..., 0]])
    weights[0, 40] = 0.01  # one fix down-weighted
    weights[0, 41:60] = 0.01  # the samples after it, no fixes (a robust weight between fixes)
    found = DownWeightedFixes.from_solve(data, weights, np.arange(len(log.t)) * 0.025)
    assert found.total == len(fixes_of_log) < data.valid.sum() / 30
    assert found.summary().startswith(f"1 of {len(fixes_of_log)} fixes down-weighted")
