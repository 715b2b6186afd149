"""The Cramér–Rao bounds a synthetic drive's evaluation reports: the whole log's, tied as the
whole-log solve ties its segments, and every batch's, each its own graph's."""

from __future__ import annotations

import numpy as np

from graphcal.evaluation import _own_systems, cramer_rao_bound, cramer_rao_systems
from graphcal.log.segments import gather_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings


def test_each_segments_own_information_is_its_graphs_alone(drive):
    # The evaluation takes a segment tied to none from the whole log's tied systems (the
    # same graph) and eliminates the chained ones alone: the same information as every
    # segment's own graph, and a batch holding chained segments is bounded as its own log.
    log = drive.measured
    segments = split_segments(log, 150.0)
    data, truth = gather_segments(log, segments), gather_segments(drive.truth, segments)
    some = np.array([0, 1, 2, 5, 9, 10])  # two chains, a lone segment between
    data, truth = data.take(some), truth.take(some)
    settings = JointSettings()
    starts = settings.graph_spec(theta_prior=False).tied(data)
    assert starts.any() and not starts.all()  # chains and lone segments both
    tied = cramer_rao_systems(data, truth, drive.theta_true, settings, tied=True)
    own = _own_systems(data, truth, drive.theta_true, settings, 1, tied)
    alone = cramer_rao_systems(data, truth, drive.theta_true, settings)
    np.testing.assert_allclose(own.segments, alone.segments, rtol=1e-12, atol=0.0)
    chained = np.flatnonzero(starts)[:1]
    batch = np.concatenate([chained - 1, chained, np.flatnonzero(~starts)[-1:]])
    bound = cramer_rao_bound(data.take(batch), truth.take(batch), drive.theta_true, settings)
    np.testing.assert_allclose(own.solve(batch[None]).covariance[0, :4, :4], bound, rtol=1e-9)
