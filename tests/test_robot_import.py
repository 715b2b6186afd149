"""A differential-drive robot's recording (graphcal.simulate.robot: motion capture at 50 Hz,
2797-count encoders, spins on the spot) imported and checked with its vehicle profile
(data/vehicles/mocap_robot.toml, ``reverses = true``): its spins and reversing are motion,
every mocap pose is kept, and the checks still catch a robot's mistakes (issue 27)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from graphcal.log.drive_log import DriveLogError
from graphcal.log.load import load_drive_log
from graphcal.log.segments import split_segments
from graphcal.pipeline.configuration.settings_file import load_vehicle
from graphcal.recording.import_output import write_import
from graphcal.recording.importer import import_recording, read_recording
from graphcal.recording.stream_grid import fixes_on_grid, grid_rate
from graphcal.recording.streams import PoseStream, StreamError
from graphcal.simulate.robot import ROBOT_THETA_TRUE, RobotSettings, simulate_robot
from graphcal.simulate.streams import write_streams

VEHICLES = Path(__file__).resolve().parents[1] / "data" / "vehicles"
ROBOT = load_vehicle(VEHICLES / "mocap_robot.toml")
NOMINAL = ROBOT.theta_nominal


def _simulate(seed: int, **overrides):
    return simulate_robot(seed, runs=10, settings=RobotSettings.from_vehicle(ROBOT, **overrides))


@pytest.fixture(scope="module", params=[0, 1])
def written(request, tmp_path_factory):
    """A robot recording (seed 0 or 1) as CSV streams and, where rosbags is installed, as a
    ROS 2 bag."""
    sim = _simulate(request.param)
    folder = tmp_path_factory.mktemp(f"robot{request.param}")
    write_streams(sim, folder / "streams")
    sources = {"csv": folder / "streams" / "manifest.toml"}
    try:
        from graphcal.simulate.bags import write_bag
    except ImportError:  # rosbags missing
        write_bag = None
    if write_bag is not None:
        sources["bag"] = write_bag(sim.recording, folder / "bag", "ros2")
    return sim, sources


def _import(source, **keywords):
    return import_recording(source, nominal=NOMINAL, **keywords)


def _pose_samples_on_grid(imported) -> int:
    """How many pose samples fall within the drive log's grid (those it can hold)."""
    pose_t = read_recording(imported.source).pose.t
    grid = imported.log.t + imported.resampled.overlap[0]
    return int(np.sum((pose_t >= grid[0] - 1e-6) & (pose_t <= grid[-1] + 1e-6)))


@pytest.mark.parametrize("kind", ["csv", "bag"])
@pytest.mark.slow
def test_the_robot_profile_keeps_spins_and_every_mocap_pose(written, kind):
    sim, sources = written
    if kind not in sources:
        pytest.skip("rosbags is not installed")
    imported = _import(sources[kind], reverses=True)
    log = imported.log
    assert log.masked is None and log.mask_notes == ()  # no reversing mask
    assert imported.warnings == ()
    # The spins' backwards wheels are kept: each wheel's rotations add up to its counter's
    # change over the log, none clipped to 0.
    assert (log.n_rl < -0.001).any() and (log.n_rr < -0.001).any()
    wheels = read_recording(sources[kind]).wheels
    grid = log.t + imported.resampled.overlap[0]
    for rotations, counts in ((log.n_rl, wheels.left), (log.n_rr, wheels.right)):
        turned = np.interp(grid[-1], wheels.t, counts) - np.interp(grid[0], wheels.t, counts)
        assert np.sum(rotations[:-1]) == pytest.approx(turned, abs=1e-9)
    # Every mocap pose on the grid is a measurement, none left out for sharing an interval.
    assert int(log.position_measured.sum()) == _pose_samples_on_grid(imported)
    assert not any("left out" in note for note in imported.resampled.notes)
    # The distance along the path is the runs' (true c_e): spins add next to nothing.
    path = log.travelled_distance(ROBOT_THETA_TRUE[0])
    assert np.all(np.diff(path) >= 0)
    assert path[-1] == pytest.approx(sim.total_distance, rel=0.01)


@pytest.mark.slow
def test_a_bag_without_a_rate_follows_the_50_hz_mocap(written):
    _, sources = written
    if "bag" not in sources:
        pytest.skip("rosbags is not installed")
    imported = _import(sources["bag"], reverses=True)
    assert 50.0 < 1.0 / imported.log.dt <= 50.01 + 1e-9  # not the 40 Hz default
    assert any("just faster than the pose stream" in n for n in imported.resampled.notes)


@pytest.mark.slow
def test_a_manifest_without_a_rate_follows_the_mocap_too(written, tmp_path):
    _, sources = written
    folder = sources["csv"].parent
    text = folder.joinpath("manifest.toml").read_text()
    assert "rate = 50.0\n" in text
    for name in ("pose.csv", "wheels.csv"):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    manifest = tmp_path / "manifest.toml"
    manifest.write_text(text.replace("rate = 50.0\n", "").replace('truth = "truth.json"', ""))
    imported = _import(manifest, reverses=True)
    assert 50.0 < 1.0 / imported.log.dt <= 50.01 + 1e-9
    assert int(imported.log.position_measured.sum()) == _pose_samples_on_grid(imported)


def _pose(rate: float, seconds: float = 60.0) -> PoseStream:
    t = 1.7e9 + np.arange(0.0, seconds, 1.0 / rate)
    zeros = np.zeros(len(t))
    return PoseStream(t, zeros, zeros, None, None, "<pose>")


@pytest.mark.parametrize("rate", [1.0, 10.0, 20.0, 40.0])
def test_a_pose_stream_no_faster_than_40_hz_keeps_the_default_grid(rate):
    assert grid_rate(_pose(rate)) == 40.0  # a car's GNSS: unchanged


@pytest.mark.parametrize("rate", [50.0, 100.0, 120.0])
def test_a_faster_pose_stream_gets_a_grid_that_drops_no_fix(rate):
    pose = _pose(rate)
    found = grid_rate(pose)
    assert rate < found <= rate * 1.001
    grid = pose.t[0] + np.arange(0.0, pose.t[-1] - pose.t[0], 1.0 / found)
    assert fixes_on_grid(pose.t, grid)[3] == 0


def test_the_imported_csv_loads_back_with_its_backwards_wheels(written, tmp_path):
    _, sources = written
    imported = _import(sources["csv"], reverses=True)
    csv = tmp_path / "robot.csv"
    write_import(imported, csv)
    log = load_drive_log(csv, nominal=NOMINAL, reverses=True)
    np.testing.assert_array_equal(log.n_rl, imported.log.n_rl)
    np.testing.assert_array_equal(log.n_rr, imported.log.n_rr)
    assert (log.n_rl < -0.001).any() and log.masked is None
    assert log.tick_resolution == pytest.approx(1 / 2797)
    # A car's loader refuses the backwards wheels, and says what a robot sets.
    with pytest.raises(DriveLogError, match=r"negative wheel rotation") as refused:
        load_drive_log(csv, nominal=NOMINAL)
    message = str(refused.value)
    assert "\n" not in message and "line " in message
    assert "reverses = true" in message and "vehicle profile" in message


def test_without_reverses_the_spins_are_masked_and_the_mask_says_what_to_set(written):
    sim, sources = written
    imported = _import(sources["csv"])  # reverses=False: a car's semantics
    log = imported.log
    assert (log.n_rl >= 0).all() and (log.n_rr >= 0).all()
    assert log.masked is not None and log.masked.any()
    spins = int((sim.manoeuvres["kind"] == "spin").sum())
    assert len(log.mask_notes) >= spins - 1  # adjacent spans may merge
    assert all("wheels turning backwards" in note for note in log.mask_notes)
    assert "reverses = true" in log.mask_notes[0]
    assert "vehicle profile" in log.mask_notes[0]


def test_reversing_is_motion_and_segments_stay_in_order(tmp_path):
    sim = _simulate(0, reversing=True)
    reverse = sim.manoeuvres[sim.manoeuvres["kind"] == "reverse"]
    assert len(reverse) > 0
    write_streams(sim, tmp_path)
    imported = _import(tmp_path / "manifest.toml", reverses=True)
    log = imported.log
    assert log.masked is None and imported.warnings == ()
    both_back = (log.n_rl < -0.001) & (log.n_rr < -0.001)
    assert both_back.sum() * log.dt > 0.8 * (reverse["end"] - reverse["start"]).sum()
    # Along the path: forwards and backwards both count, so the distance never decreases.
    path = log.travelled_distance(ROBOT_THETA_TRUE[0])
    assert np.all(np.diff(path) >= 0)
    runs = sim.manoeuvres.loc[sim.manoeuvres["kind"] == "run", "distance"].sum()
    expected = runs + reverse["distance"].abs().sum()
    assert path[-1] == pytest.approx(expected, rel=0.01)
    segments = split_segments(log, 5.0, None, float(NOMINAL[0]))
    assert len(segments) == math.floor(log.travelled_distance(NOMINAL[0])[-1] / 5.0)
    assert np.all(np.diff(segments.start) > 0) and np.all(segments.stop > segments.start)
    lengths = path[segments.stop] - path[segments.start]
    assert lengths == pytest.approx(5.0 * ROBOT_THETA_TRUE[0] / NOMINAL[0], abs=0.05)


def _copy_streams(written, tmp_path) -> Path:
    folder = written[1]["csv"].parent
    for name in ("pose.csv", "wheels.csv", "manifest.toml", "truth.json"):
        (tmp_path / name).write_bytes((folder / name).read_bytes())
    return tmp_path / "manifest.toml"


def test_a_wrong_tick_count_on_a_robot_is_caught(written, tmp_path):
    manifest = _copy_streams(written, tmp_path)
    text = manifest.read_text()
    manifest.write_text(text.replace("ticks_per_revolution = 2797", "ticks_per_revolution = 2000"))
    with pytest.raises(StreamError, match=r"ticks_per_revolution") as refused:
        _import(manifest, reverses=True)
    message = str(refused.value)
    assert "wheels.csv" in message and "the wheels travel 1.4" in message
    assert "\n" not in message


def _edit_pose(manifest: Path, edit) -> None:
    pose = manifest.with_name("pose.csv")
    frame = pd.read_csv(pose, dtype={"t": str})
    edit(frame)
    frame.to_csv(pose, index=False, float_format="%.17g")


def test_a_half_metre_mocap_glitch_is_an_outlying_fix(written, tmp_path):
    manifest = _copy_streams(written, tmp_path)
    glitch = 3000  # a lone pose 0.5 m off (a marker swapped for one frame)

    def edit(frame):
        frame.loc[glitch, "x"] += 0.5

    _edit_pose(manifest, edit)
    imported = _import(manifest, reverses=True)
    log = imported.log
    assert log.masked is None
    assert log.outlying is not None and log.outlying.sum() == 1
    pose_t = read_recording(manifest).pose.t
    row = int(np.flatnonzero(log.outlying)[0])
    fix_time = log.t[row] - (0.0 if log.fix_lag is None else log.fix_lag[row])
    assert fix_time + imported.resampled.overlap[0] == pytest.approx(pose_t[glitch], abs=1e-5)


def test_a_mocap_body_frame_turned_90_degrees_is_refused(written, tmp_path):
    manifest = _copy_streams(written, tmp_path)

    def edit(frame):
        frame["heading"] = np.angle(np.exp(1j * (frame["heading"] + np.pi / 2)))

    _edit_pose(manifest, edit)
    with pytest.raises(StreamError, match=r"differs from the direction of travel by \+90°"):
        _import(manifest, reverses=True)


@pytest.mark.parametrize("pose_rate", [20.0, 100.0])
@pytest.mark.slow
def test_mocap_at_20_and_100_hz_passes_with_every_pose(pose_rate, tmp_path):
    sim = simulate_robot(2, runs=4, settings=RobotSettings.from_vehicle(ROBOT, pose_rate=pose_rate))
    write_streams(sim, tmp_path / "streams")
    sources = [tmp_path / "streams" / "manifest.toml"]
    try:
        from graphcal.simulate.bags import write_bag
    except ImportError:  # rosbags missing
        write_bag = None
    if write_bag is not None:
        sources.append(write_bag(sim.recording, tmp_path / "bag", "ros2"))
    for source in sources:
        imported = _import(source, reverses=True)
        log = imported.log
        assert log.masked is None and log.outlying is None and imported.warnings == ()
        assert 1.0 / log.dt >= min(pose_rate, 40.0) - 1e-6
        assert int(log.position_measured.sum()) == _pose_samples_on_grid(imported)


@pytest.mark.slow
def test_a_backwards_rotation_beyond_any_speed_is_still_refused(written, tmp_path):
    _, sources = written
    imported = _import(sources["csv"], reverses=True)
    csv = tmp_path / "robot.csv"
    write_import(imported, csv)
    frame = pd.read_csv(csv)
    frame.loc[500, "n_rr"] = -50.0  # 13 m in 20 ms: a count, not a rotation
    frame.to_csv(csv, index=False)
    with pytest.raises(DriveLogError, match=r"column 'n_rr', line 502: implausible wheel rotation"):
        load_drive_log(csv, nominal=NOMINAL, reverses=True)
