"""A solve whose theta runs out of its plausible range stops there (``SolveOptions.runaway``,
``RunawayWatch``) for its caller to judge the runaway at once, instead of creeping on to its
iteration limit; a solve that stays in range is not touched."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.levenberg_marquardt import RUNAWAY_ITERATIONS, RunawayWatch
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.optimization.partitioned_lm import optimize
from graphcal.graph.optimization.solve_options import SolveOptions, SolveOutcome, SolveStatus
from graphcal.graph.solution.plausibility import BeyondPlausible, plausible_ranges
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.simulate.drive import simulate_drive


def test_a_runaway_is_several_iterations_in_a_row_each_farther_out():
    distances = iter([0.0, 0.2, 0.1, 0.3, 0.4, 0.5])
    watch = RunawayWatch(lambda _: next(distances))
    seen = [watch.running_away(None) for _ in range(6)]
    # out at 0.2, back towards the range at 0.1 (the count starts again), then farther 3×
    assert seen == [False] * 5 + [True]
    assert RUNAWAY_ITERATIONS == 3
    assert not RunawayWatch(None).running_away(None)
    # Far above the noise (weights far too tight) theta wanders: not counted, and the count
    # starts again.
    distances = iter([0.1, 0.2, 0.3, 0.4, 0.5])
    wandering = RunawayWatch(lambda _: next(distances))
    judged = [True, True, False, True, True]
    assert [wandering.running_away(None, j) for j in judged] == [False] * 5


def test_a_solve_out_of_range_that_creeps_back_is_a_runaway_one_that_returns_is_not():
    # Campaign seed 40's shape 160: a first step took t_r to -0.05 m (0.55 m out of its
    # range), whence it crept back by 0.1-1 % of the way per iteration for 50 iterations.
    creeping = iter([0.55, 0.572, 0.531, 0.520, 0.516, 0.514])
    watch = RunawayWatch(lambda _: next(creeping))
    assert [watch.running_away(None) for _ in range(6)] == [False, False] + [True] * 4
    # A solve that comes back does so in a few steps: never a runaway.
    returning = iter([0.55, 0.3, 0.1, 0.0, 0.0])
    back = RunawayWatch(lambda _: next(returning))
    assert not any(back.running_away(None) for _ in range(5))


def test_distance_beyond_the_plausible_range_in_its_widths():
    ranges = np.array([[0.5, 5.0], [-0.1, 0.1], [0.5, 3.0], [-0.05, 0.05]])

    class Theta:
        def __init__(self, theta):
            self.theta = np.asarray(theta, float)

        def atVector(self, _key):
            return self.theta

    beyond = BeyondPlausible(ranges)
    assert beyond(Theta([2.0, 0.0, 1.5, 0.0])) == 0.0
    assert beyond(Theta([2.0, 0.0, 0.25, 0.0])) == pytest.approx(0.1)  # 0.25 m below, of 2.5
    assert beyond(Theta([2.0, 0.3, 0.25, 0.0])) == pytest.approx(1.0)  # the farthest counts


@pytest.fixture(scope="module")
def straight_road():
    """A 2 km straight road's segments, t_r under a prior of 5 m: it drifts from 1.55 m to
    about 2.3 m in 50 iterations (nothing turns to hold it)."""
    log = simulate_drive(length_km=2.0, seed=5, route="straight").measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0), min_yaw_rate=0))
    spec = JointSettings(slip="off", robust_threshold=0.0, tie_segments=False).graph_spec()
    spec = dataclasses.replace(spec, theta_prior_sigmas=np.array([0.5, 0.05, 5.0, 0.05]))
    return data, spec


def _solved(straight_road, runaway):
    data, spec = straight_road
    built = build_segment_graph(data, spec)
    graph = PartitionedGraph(built.graph, built.values, shared_keys(spec))
    with graph.parallel(1):
        return optimize(graph, SolveOptions(50, 1e-7, "runaway test", runaway=runaway))


def test_a_solve_stops_where_its_theta_runs_out_of_range(straight_road):
    # The drift of t_r above 1.6 m is a runaway from a range that ends there.
    narrow = np.array([[0.5, 5.0], [-0.1, 0.1], [0.5, 1.6], [-0.05, 0.05]])
    stopped = _solved(straight_road, BeyondPlausible(narrow))
    assert stopped.status is SolveStatus.RUNAWAY
    assert stopped.iterations <= 5
    assert "plausible range" in stopped.message
    # Within the vehicle's own ranges (its prior widens them) it is no runaway.
    spec = straight_road[1]
    wide = plausible_ranges(np.asarray(spec.theta, float), spec.theta_prior_sigmas)
    full = _solved(straight_road, BeyondPlausible(wide))
    assert full.status is not SolveStatus.RUNAWAY and full.iterations > stopped.iterations


def _held_solves(monkeypatch, in_turn):
    """:func:`runaways._holding_a_runaway` of t_r with a whole-log solve that raises each
    of ``in_turn`` (parameter names) in turn, then solves: the held names of each call."""
    from types import SimpleNamespace

    import graphcal.pipeline.methods.runaways as runaways
    from graphcal.graph.solution.plausibility import ImplausibleTheta

    held = []
    pending = list(in_turn)

    def solve(prepared, settings, workers=1, start=None, rounds=4, solved=None, stop_if=None):
        held.append(settings.held_at_prior)
        if pending:
            names = pending.pop(0)
            raise ImplausibleTheta(f"{', '.join(names)} out of range", names)
        return "solved"

    monkeypatch.setattr(runaways, "solve_with_time_offset", solve)
    prepared = SimpleNamespace(
        data=SimpleNamespace(has_heading=lambda: False), log=SimpleNamespace(dt=0.025)
    )
    runaway = ImplausibleTheta("t_r out of range", ("t_r",))
    outcome = runaways._holding_a_runaway(prepared, JointSettings(), runaway, workers=1)
    return held, outcome


def test_a_parameter_running_away_in_the_held_solve_is_held_with_the_others(monkeypatch):
    # Campaign seed 41's shape 103 (17-tick wheels, fixes sharing 2 m): t_r ran out, then c_d
    # in the solve holding t_r — exit 2 "check the units" for a recording that shows neither.
    held, (runaway, settings, solved) = _held_solves(monkeypatch, [("c_d",)])
    assert held == [("t_r",), ("c_d", "t_r")]
    assert runaway.names == settings.held_at_prior == ("c_d", "t_r")
    assert solved == "solved"


def test_a_held_parameter_out_of_range_is_not_held_again(monkeypatch):
    from graphcal.graph.solution.plausibility import ImplausibleTheta

    with pytest.raises(ImplausibleTheta, match="t_r out of range"):
        _held_solves(monkeypatch, [("t_r",)])


def test_a_held_solve_that_crept_under_too_tight_weights_is_no_verdict_on_units(monkeypatch):
    """Campaign seed 44's shape 162 (a robot's fixes sharing 0.23 m over 46 s): t_r ran
    out, the solve holding it crept at χ²/dof 26 under weights far too tight and stopped,
    and t_r read as determined there was refused as wrong units (exit 2). Such a held solve
    is no solution: the free solve runs again under the noise it shows."""
    from types import SimpleNamespace

    import graphcal.pipeline.methods.runaways as runaways
    from graphcal.graph.solution.plausibility import ImplausibleTheta
    from graphcal.pipeline.configuration.configure import configure_settings

    free_solves = []

    def solve(prepared, settings, workers=1, start=None, rounds=4, solved=None, stop_if=None):
        free_solves.append(settings.held_at_prior)
        if len(free_solves) == 1:
            raise ImplausibleTheta("t_r out of range", ("t_r",))
        return "solved free again"

    crept = SimpleNamespace(outcome=SolveOutcome(SolveStatus.MISWEIGHTED, 12, 50))

    def holding(prepared, settings, runaway, workers, shift=None):
        return runaway, settings.holding(runaway.names), (crept, None, None, None)

    monkeypatch.setattr(runaways, "solve_with_time_offset", solve)
    monkeypatch.setattr(runaways, "_holding_a_runaway", holding)
    monkeypatch.setattr(runaways, "data_determine", lambda whole, settings, names: [True])
    monkeypatch.setattr(runaways, "with_noise_levels", lambda whole, settings, *a, **k: settings)
    prepared = SimpleNamespace(
        data=SimpleNamespace(has_heading=lambda: False), log=SimpleNamespace(dt=0.025)
    )
    settings = configure_settings()
    _, solved = runaways.holding_runaways(prepared, settings, {}, workers=1)
    assert solved == "solved free again" and free_solves == [(), ()]
    # a held solve that is a solution, with the data determining t_r: the units
    crept.outcome = SolveOutcome(SolveStatus.CONVERGED, 12, 50)
    free_solves.clear()
    with pytest.raises(ImplausibleTheta, match="t_r out of range"):
        runaways.holding_runaways(prepared, settings, {}, workers=1)
