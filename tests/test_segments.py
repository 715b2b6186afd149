"""Segmentation, yaw-rate selection and batching (paper §5.1)."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.log.drive_log import COLUMNS, DriveLog
from graphcal.log.segments import (
    gather_segments,
    make_batches,
    select_segments,
    split_segments,
    yaw_rate_statistic,
)
from graphcal.simulate.drive import simulate_drive


def test_disjoint_segments_cover_the_given_distance(drive):
    log = drive.measured
    segments = split_segments(log, 150.0)
    distance = log.travelled_distance()
    lengths = distance[segments.stop] - distance[segments.start]
    assert len(segments) == int(distance[-1] // 150.0)
    step = np.diff(distance).max()
    assert np.all(lengths > 150.0 - step) and np.all(lengths < 150.0 + step)
    assert np.all(segments.start[1:] >= segments.stop[:-1])  # disjoint


def test_stride_gives_overlapping_segments(drive):
    disjoint = split_segments(drive.measured, 150.0)
    overlapping = split_segments(drive.measured, 150.0, stride=50.0)
    assert len(overlapping) > 2.5 * len(disjoint)
    assert np.any(overlapping.start[1:] < overlapping.stop[:-1])


def test_selection_keeps_turning_segments(drive):
    log = drive.measured
    segments = split_segments(log, 150.0)
    selected = select_segments(log, segments, min_yaw_rate=0.15)
    assert 0 < len(selected) < len(segments)
    # Judged on the noise-free heading, the selected segments really do turn more.
    truth_yaw = yaw_rate_statistic(drive.truth, segments)
    picked = np.isin(segments.start, selected.start)
    assert truth_yaw[picked].min() > 0.12
    assert truth_yaw[picked].mean() > 1.5 * truth_yaw[~picked].mean()


@pytest.mark.parametrize("statistic", ["mean", "median", "rms"])
def test_statistics_agree_with_direct_computation(drive, statistic):
    from graphcal.log.segments import smoothed_yaw_rate

    log = drive.measured
    segments = split_segments(log, 150.0)
    values = yaw_rate_statistic(log, segments, statistic)
    rate = np.abs(smoothed_yaw_rate(log))
    for i in (0, len(segments) // 2, len(segments) - 1):
        r = rate[segments.start[i] : segments.stop[i] + 1]
        direct = {"mean": r.mean(), "median": np.median(r), "rms": np.sqrt((r**2).mean())}
        assert values[i] == pytest.approx(direct[statistic])


def test_straight_drive_has_no_selected_segment(straight_log):
    log = straight_log
    assert len(select_segments(log, split_segments(log, 150.0))) == 0


def test_batches_are_deterministic_and_distinct():
    a = make_batches(40, batch_size=9, n_batches=1000, seed=3)
    b = make_batches(40, batch_size=9, n_batches=1000, seed=3)
    c = make_batches(40, batch_size=9, n_batches=1000, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.shape == (1000, 9)
    assert all(len(set(row)) == 9 for row in a)
    assert len(np.unique(a, axis=0)) == 1000
    assert a.min() >= 0 and a.max() < 40
    # Every segment gets used, roughly uniformly.
    counts = np.bincount(a.ravel(), minlength=40)
    assert counts.min() > 0.6 * counts.mean()


def test_batches_are_never_repeated():
    batches = make_batches(10, batch_size=9, n_batches=1000, seed=0)
    assert len(batches) == 10  # C(10, 9): every distinct batch once
    assert len(np.unique(batches, axis=0)) == 10


def test_too_few_segments_for_a_batch():
    with pytest.raises(ValueError, match="only 5 segment"):
        make_batches(5, batch_size=9)


def test_gather_pads_without_moving_the_pose(drive):
    log = drive.measured
    segments = split_segments(log, 150.0)
    data = gather_segments(log, segments)
    k = data.n_steps
    assert data.poses.shape == (len(segments), k.max() + 1, 3)
    i = int(np.argmin(k))
    np.testing.assert_array_equal(
        data.poses[i, : k[i] + 1], log.poses[segments.start[i] : segments.stop[i] + 1]
    )
    assert np.all(data.inputs[i, k[i] :] == 0)
    assert data.valid.sum() == (k + 1).sum()


def test_segments_of_an_overlapping_route_are_numerous():
    # §5.1: overlap is how a 24 km route gives hundreds of selected segments.
    drive = simulate_drive(8.0, seed=11)
    disjoint = select_segments(drive.measured, split_segments(drive.measured, 150.0))
    overlapping = select_segments(
        drive.measured, split_segments(drive.measured, 150.0, stride=25.0)
    )
    assert len(overlapping) > 4 * len(disjoint) > 0


def _three_drives_on_one_clock(runs: bool) -> DriveLog:
    """Three 400 m drives at 10 m/s, each parked 5 s at its start and end, with 30 s
    between them masked (every stream stopped): the travelled distance is flat across each
    gap. With ``runs`` the drives are also numbered runs."""
    dt, speed, parked, gap = 0.025, 10.0, 5.0, 30.0
    moving = np.full(round(40.0 / dt), speed * dt / 2.0)  # rev per step at c_e 2 m
    rest = np.zeros(round(parked / dt))
    drive = np.concatenate([rest, moving, rest])
    pieces, masked, run = [], [], []
    for k in range(3):
        pieces.append(drive)
        masked.append(np.zeros(len(drive), bool))
        run.append(np.full(len(drive), k))
        if k < 2:
            pieces.append(np.zeros(round(gap / dt)))
            masked.append(np.ones(round(gap / dt), bool))
            run.append(np.full(round(gap / dt), k))
    n = np.concatenate(pieces)
    zeros = np.zeros(len(n))
    return DriveLog(
        np.arange(len(n)) * dt,
        zeros,
        zeros,
        zeros,
        n,
        n,
        zeros,
        zeros,
        masked=np.concatenate(masked),
        run=np.concatenate(run) if runs else None,
    )


@pytest.mark.parametrize("runs", [False, True])
@pytest.mark.parametrize("stride", [None, 50.0])
def test_segments_of_drives_on_one_clock_stay_inside_their_drive(runs, stride):
    log = _three_drives_on_one_clock(runs)
    segments = split_segments(log, 150.0, stride=stride)
    distance = log.travelled_distance()
    assert len(segments) == (6 if stride is None else 3 * 6)  # 400 m: 2 of 150 m, or 6 at 50 m
    for start, stop in zip(segments.start, segments.stop, strict=True):
        assert not log.masked[start : stop + 1].any()  # no masked sample, no gap spanned
        assert distance[stop] - distance[start] == pytest.approx(150.0, abs=0.3)


def test_segments_never_span_a_run_boundary_without_a_mask():
    log = _three_drives_on_one_clock(runs=True)
    unmasked = DriveLog(*(getattr(log, c) for c in COLUMNS), run=log.run)
    segments = split_segments(unmasked, 150.0, stride=50.0)
    assert len(segments) == 3 * 6
    spans = zip(segments.start, segments.stop, strict=True)
    assert all(np.ptp(log.run[a : b + 1]) == 0 for a, b in spans)


def test_a_log_without_a_heading_is_selected_by_its_wheels_yaw_rate(drive):
    """Where the heading was not measured, ``psi`` is the fixes' track, whose noise reads as
    turns (a robot's 2.5 Hz fixes of 1.5 m); the wheels turn as the vehicle does."""
    import dataclasses

    from graphcal.log.segments import smoothed_yaw_rate
    from graphcal.model import THETA_NOMINAL

    log = drive.measured
    measured = np.ones((len(log), 2), bool)
    measured[:, 1] = False
    noisy = np.random.default_rng(0).normal(0.0, 0.3, len(log))  # the track's course noise
    track = dataclasses.replace(log, psi=log.psi + noisy, measured=measured)
    truth = smoothed_yaw_rate(drive.truth)
    wheels = smoothed_yaw_rate(track, theta=drive.theta_true)
    assert np.sqrt(np.mean((wheels - truth) ** 2)) < 0.01  # rad/s
    from_track = dataclasses.replace(track, measured=None)  # read as a measured heading
    assert np.sqrt(np.mean((smoothed_yaw_rate(from_track) - truth) ** 2)) > 0.1
    default = smoothed_yaw_rate(track)  # the car's nominal theta
    assert np.sqrt(np.mean((default - truth) ** 2)) < 0.03  # c_d nominal 0: a small bias
    assert THETA_NOMINAL[2] != drive.theta_true[2]
