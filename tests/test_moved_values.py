"""A solution's values moved to another graph of the same log: a subset of its segments, and
wheel corrections that follow wheels shifted by whole samples."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gtsam
import numpy as np

from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.moved_values import renumbered, with_corrections_shifted
from graphcal.graph.optimization.values import tangent_dims
from graphcal.log.load import load_drive_log
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.solvers.joint_settings import JointSettings

SAMPLE = Path(__file__).resolve().parents[1] / "data" / "sample_drive.csv"


def _vector(values: gtsam.Values, key: int) -> np.ndarray:
    try:
        pose = values.atPose2(key)
    except RuntimeError:
        return np.asarray(values.atVector(key))
    return np.array([pose.x(), pose.y(), pose.theta()])


def test_a_subset_of_a_solution_holds_every_variable_of_the_graph_over_those_segments():
    log = load_drive_log(SAMPLE)
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0))).take(range(6))
    spec = dataclasses.replace(JointSettings().graph_spec(), tie_segments=False)
    whole = build_segment_graph(data, spec).values
    members = [4, 1]
    moved = renumbered(whole, members)
    subset = build_segment_graph(data.take(members), spec).values
    # the same variables, in the same dimensions, and nothing of the other segments
    assert tangent_dims(moved) == tangent_dims(subset)
    for key in subset.keys():
        letter = chr(gtsam.Symbol(key).chr())
        if letter in keys.SEGMENT_LETTERS:
            source = keys.in_segment(key, members[keys.segment_of(key)])
        else:
            source = key
        np.testing.assert_array_equal(_vector(moved, key), _vector(whole, source))


def test_wheel_corrections_stay_with_the_rotations_they_correct():
    # one segment of two chunks: 3 and 2 steps, (rear-left, rear-right) per step
    steps = np.arange(10.0).reshape(5, 2) + 1.0
    values = gtsam.Values()
    values.insert(keys.THETA, np.ones(4))
    values.insert(keys.segment_corrections(0, 0), steps[:3].reshape(-1))
    values.insert(keys.segment_corrections(0, 1), steps[3:].reshape(-1))

    def corrections(moved: gtsam.Values) -> np.ndarray:
        parts = [moved.atVector(keys.segment_corrections(0, k)) for k in (0, 1)]
        return np.concatenate(parts).reshape(5, 2)

    # wheels shifted so that step k reads what step k+1 read: its correction comes along
    later = corrections(with_corrections_shifted(values, 1, np.array([1])))
    np.testing.assert_array_equal(later[:4], steps[1:])
    np.testing.assert_array_equal(later[4], [0.0, 0.0])  # past the segment's end: none
    earlier = corrections(with_corrections_shifted(values, 1, np.array([-2])))
    np.testing.assert_array_equal(earlier[:2], np.zeros((2, 2)))
    np.testing.assert_array_equal(earlier[2:], steps[:3])
    unmoved = with_corrections_shifted(values, 1, np.array([0]))
    np.testing.assert_array_equal(corrections(unmoved), steps)
    np.testing.assert_array_equal(unmoved.atVector(keys.THETA), np.ones(4))


def test_values_are_copied_and_sent_whatever_kind_their_letter_held_before():
    # copy_value and portable read a key as the kind its letter held last (a failed read is
    # slow): a letter holding both kinds is still read right.
    from graphcal.graph.optimization.values import copy_value, portable, restore

    source = gtsam.Values()
    mixed = [gtsam.symbol("q", i) for i in range(4)]
    for i, key in enumerate(mixed):
        value = gtsam.Pose2(i, 2.0, 0.3) if i % 2 else np.array([i, 1.0])
        source.insert(key, value)
    target, sent = gtsam.Values(), gtsam.Values(source)
    for key in mixed:
        copy_value(target, source, key)
        restore(sent, key, portable(source, key))
    for i, key in enumerate(mixed):
        if i % 2:
            assert target.atPose2(key).equals(source.atPose2(key), 0.0)
            assert sent.atPose2(key).equals(source.atPose2(key), 0.0)
        else:
            assert np.array_equal(target.atVector(key), source.atVector(key))
            assert np.array_equal(sent.atVector(key), source.atVector(key))
