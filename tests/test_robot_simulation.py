"""The simulated differential-drive robot (graphcal.simulate.robot): what its truth, its
manoeuvres and its streams guarantee, and that its files read back (reading, not calibrating)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from graphcal.model import PARAMETER_NAMES, integrate
from graphcal.pipeline.configuration.settings_file import load_vehicle
from graphcal.recording.importer import read_recording
from graphcal.simulate.robot import ROBOT_THETA_TRUE, RobotSettings, simulate_robot
from graphcal.simulate.robot_manoeuvres import FINE_DT
from graphcal.simulate.streams import EPOCH, write_streams

VEHICLES = Path(__file__).resolve().parents[1] / "data" / "vehicles"


@pytest.fixture(scope="module")
def sim():
    return simulate_robot(seed=4)


def _inputs(log):
    return np.column_stack([log.n_rl, log.n_rr, log.beta, log.ay])[:-1]


def _rows(sim, kind):
    return sim.manoeuvres[sim.manoeuvres["kind"] == kind]


def _steps(sim, row):
    """Fine-grid step indices of a manoeuvre."""
    return slice(round(row.start / FINE_DT), round(row.end / FINE_DT))


def _states(sim, row):
    """Fine-grid state indices of a manoeuvre, its start and end included."""
    return slice(round(row.start / FINE_DT), round(row.end / FINE_DT) + 1)


def test_same_seed_same_recording_another_seed_another():
    a, b, c = simulate_robot(7, runs=3), simulate_robot(7, runs=3), simulate_robot(8, runs=3)
    for name in ("gnss", "wheels", "manoeuvres"):
        pd.testing.assert_frame_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.drive.measured.px, b.drive.measured.px)
    assert not a.manoeuvres["distance"].equals(c.manoeuvres["distance"])


def test_the_truth_is_the_model_integrated_from_the_true_rotations(sim):
    fine = sim.fine
    np.testing.assert_array_equal(sim.drive.theta_true, ROBOT_THETA_TRUE)
    start = np.array([fine.px[0], fine.py[0], fine.psi[0]])
    states = integrate(start, _inputs(fine), ROBOT_THETA_TRUE)
    np.testing.assert_allclose(states, np.column_stack([fine.px, fine.py, fine.psi]), atol=1e-12)
    np.testing.assert_array_equal(fine.beta, 0.0)  # the axle midpoint does not slip sideways
    # The drive-log view's true rows are the fine truth's states at the same instants.
    truth = sim.drive.truth
    every = round(1.0 / (sim.robot.rate * FINE_DT))
    np.testing.assert_allclose(truth.px, fine.px[::every], atol=1e-9)
    np.testing.assert_allclose(truth.psi, fine.psi[::every], atol=1e-9)
    total = np.cumsum(truth.n_rl[:-1])[-1]
    assert total == pytest.approx(np.sum(fine.n_rl[:-1]), abs=1e-9)


def test_spins_turn_the_wheels_opposite_ways_on_the_spot(sim):
    spins = _rows(sim, "spin")
    assert len(spins) == 9  # between 10 runs
    fine = sim.fine
    for row in spins.itertuples():
        k = _steps(sim, row)
        left, right = fine.n_rl[k], fine.n_rr[k]
        moving = (np.abs(left) > 1e-9) | (np.abs(right) > 1e-9)
        assert moving.mean() > 0.9
        assert np.all(np.sign(left[moving]) == -np.sign(right[moving]))
        # The centre stays put: the wheels' rotations cancel to within c_d's 0.04 %.
        x = _states(sim, row)
        travel = np.hypot(fine.px[x] - fine.px[x.start], fine.py[x] - fine.py[x.start])
        assert travel.max() < 1e-9
        assert np.pi / 2 - 1e-9 <= abs(row.yaw) <= 2 * np.pi + 1e-9
        assert fine.psi[x.stop - 1] - fine.psi[x.start] == pytest.approx(row.yaw, abs=1e-9)
        yaw_rate = np.abs(np.diff(fine.psi[x])) / FINE_DT
        assert 0.5 - 1e-6 <= yaw_rate.max() <= 1.5 + 1e-6


def test_runs_are_5_to_15_m_forward_from_rest_to_rest(sim):
    runs = _rows(sim, "run")
    assert len(runs) == 10
    assert runs["distance"].between(5.0, 15.0).all()
    fine = sim.fine
    c_e, t_r = ROBOT_THETA_TRUE[0], ROBOT_THETA_TRUE[2]
    radii = []
    for row in runs.itertuples():
        k = _steps(sim, row)
        assert (fine.n_rl[k] >= 0).all() and (fine.n_rr[k] >= 0).all()
        x = _states(sim, row)
        path = np.hypot(np.diff(fine.px[x]), np.diff(fine.py[x]))
        assert np.sum(path) == pytest.approx(row.distance, rel=1e-9)
        speed = path / FINE_DT
        assert speed.max() <= 1.5 + 1e-6 and speed[0] < 0.1 and speed[-1] < 0.1
        yaw = np.abs(np.diff(fine.psi[x]))
        turning = yaw > 1e-6
        radii.append(np.min(path[turning] / yaw[turning]))
    assert min(radii) < 1.0  # some arcs of small radius
    assert min(radii) > t_r  # ... but no wheel turns backwards while driving
    # Total distance: the runs, as the wheels measure it.
    assert sim.total_distance == pytest.approx(runs["distance"].sum())
    wheels = 0.5 * np.sum(np.abs(fine.n_rl + fine.n_rr)) * c_e
    assert wheels == pytest.approx(sim.total_distance, rel=1e-3)
    assert sim.drive.length_km == pytest.approx(sim.total_distance / 1000)
    # Stops separate every manoeuvre and start and end the recording.
    kinds = sim.manoeuvres["kind"].tolist()
    assert kinds[::2] == ["stop"] * (len(kinds) // 2 + 1) and kinds[-1] == "stop"
    assert "stop" not in kinds[1::2]


def test_reversing_is_off_by_default_and_short_when_on(sim):
    assert _rows(sim, "reverse").empty
    backwards = simulate_robot(4, runs=4, settings=RobotSettings(reversing=True))
    reverses = _rows(backwards, "reverse")
    assert len(reverses) == 2  # after every second run
    assert reverses["distance"].between(-2.0, -0.5).all()
    for row in reverses.itertuples():
        k = _steps(backwards, row)
        assert (backwards.fine.n_rl[k] <= 0).all() and (backwards.fine.n_rr[k] <= 0).all()


@pytest.mark.parametrize("rate", [20.0, 50.0, 100.0])
def test_poses_at_their_rate_with_their_noise(rate):
    sim = simulate_robot(2, runs=4, settings=RobotSettings(pose_rate=rate))
    pose, fine = sim.gnss, sim.fine
    t = pose["t"].to_numpy() - EPOCH
    assert np.diff(t) == pytest.approx(1.0 / rate, abs=1e-6)  # a regular clock
    assert t[0] > 0.0 and t[-1] < fine.t[-1]  # its own clock, within the truth's span
    heading = pose["heading"].to_numpy()
    assert (heading >= -np.pi).all() and (heading < np.pi).all()  # wrapped, as mocap gives it
    dx = pose["x"].to_numpy() - np.interp(t, fine.t, fine.px)
    dy = pose["y"].to_numpy() - np.interp(t, fine.t, fine.py)
    dpsi = np.angle(np.exp(1j * (heading - np.interp(t, fine.t, fine.psi))))
    for error, sigma in ((dx, 0.001), (dy, 0.001), (dpsi, np.deg2rad(0.2))):
        assert np.std(error) == pytest.approx(sigma, rel=0.1)
        assert abs(np.mean(error)) < 0.1 * sigma
    assert sim.drive.measured.t[1] == pytest.approx(1.0 / rate)  # the log view: a row per pose


def test_encoder_counts_at_their_rate_within_one_tick(sim):
    wheels, fine = sim.wheels, sim.fine
    t = wheels["t"].to_numpy() - EPOCH
    assert wheels["rl"].dtype.kind == "i" and wheels["rr"].dtype.kind == "i"
    # 100 Hz with ±0.5 ms of uniform jitter: off a regular grid by at most 0.5 ms each way.
    off_grid = t - np.arange(len(t)) / 100.0
    assert 0.0009 < off_grid.max() - off_grid.min() <= 0.001 + 1e-6
    tpr = 2797
    for side, rotations in (("rl", fine.n_rl), ("rr", fine.n_rr)):
        cumulative = np.concatenate([[0.0], np.cumsum(rotations[:-1])])
        residual = wheels[side].to_numpy() - np.interp(t, fine.t, cumulative) * tpr
        # Floored counts: within one tick (and 0.01 for the Unix times' 0.2 µs resolution).
        assert residual.max() - residual.min() < 1.01
    log = sim.drive.measured
    assert log.tick_resolution == pytest.approx(1 / tpr)
    counted = np.sum(log.n_rl[:-1])
    assert counted == pytest.approx(np.sum(sim.drive.truth.n_rl[:-1]), abs=1.0 / tpr)


def test_written_streams_read_back(sim, tmp_path):
    written = {path.name for path in write_streams(sim, tmp_path)}
    assert written == {"pose.csv", "wheels.csv", "manifest.toml", "truth.json"}
    manifest = tomllib.loads((tmp_path / "manifest.toml").read_text())
    assert manifest["rate"] == 50.0 and "imu" not in manifest
    assert manifest["pose"]["x"] == "x" and manifest["wheels"]["ticks_per_revolution"] == 2797
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["theta_true"] == dict(zip(PARAMETER_NAMES, ROBOT_THETA_TRUE, strict=True))
    assert truth["route"] == "robot" and truth["manoeuvres"]["spin"] == 9

    recording = read_recording(tmp_path / "manifest.toml")
    assert recording.imu is None and recording.pose.origin is None
    np.testing.assert_allclose(recording.pose.t, sim.gnss["t"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(recording.pose.x, sim.gnss["x"], atol=1e-12)
    np.testing.assert_allclose(recording.pose.heading, sim.gnss["heading"], atol=1e-12)
    np.testing.assert_allclose(recording.wheels.left, sim.wheels["rl"] / 2797, atol=1e-12)
    assert recording.wheels.cumulative and recording.wheels.resolution == pytest.approx(1 / 2797)


def test_a_ros2_bag_reads_back(tmp_path):
    pytest.importorskip("rosbags")
    from graphcal.simulate.bags import write_bag

    sim = simulate_robot(1, runs=2)
    bag = write_bag(sim.recording, tmp_path / "robot_ros2", "ros2")
    recording = read_recording(bag)
    assert recording.imu is None
    np.testing.assert_allclose(recording.pose.t, sim.recording.pose.t, rtol=0, atol=1e-6)
    np.testing.assert_allclose(recording.pose.x, sim.gnss["x"], atol=1e-9)
    np.testing.assert_allclose(recording.pose.y, sim.gnss["y"], atol=1e-9)
    np.testing.assert_allclose(
        np.angle(np.exp(1j * (recording.pose.heading - sim.gnss["heading"]))), 0.0, atol=1e-9
    )
    np.testing.assert_allclose(recording.wheels.left, sim.wheels["rl"] / 2797, atol=1e-9)
    np.testing.assert_allclose(recording.wheels.right, sim.wheels["rr"] / 2797, atol=1e-9)


def test_settings_from_the_mocap_robot_profile():
    robot = load_vehicle(VEHICLES / "mocap_robot.toml")
    np.testing.assert_allclose(robot.theta_nominal, [0.267, 0.0, 0.2, 0.0])
    assert robot.theta_nominal[0] == pytest.approx(np.pi * 0.085, rel=2e-3)
    settings = RobotSettings.from_vehicle(robot, pose_rate=100.0)
    assert settings.position_noise == 0.001 and settings.ticks_per_revolution == 2797
    assert settings.heading_noise == pytest.approx(np.deg2rad(0.2))
    assert settings.pose_rate == 100.0 and settings.rate == 100.0


@pytest.mark.parametrize(
    "bad",
    [
        {"pose_rate": 0.0},
        {"run_length": (15.0, 5.0)},
        {"ticks_per_revolution": 0},
        {"clock_jitter": 0.01},
        {"pose_rate": 400.0},
    ],
)
def test_impossible_settings_are_refused(bad):
    with pytest.raises(ValueError):
        RobotSettings(**bad)
    with pytest.raises(ValueError, match="runs"):
        simulate_robot(0, runs=0)
