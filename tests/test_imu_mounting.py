"""A mounted IMU (issue 28, item 4): 3-axis columns in the IMU's frame rotated into the
vehicle frame by a given or estimated mounting, and what is refused."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.evaluation import Truth, evaluate
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.recording.importer import import_recording
from graphcal.recording.imu.estimate import estimate_mounting
from graphcal.recording.imu.frame import angles, rotation, to_sensor, to_vehicle
from graphcal.recording.imu.mounting import parse_mounting
from graphcal.recording.manifest_recording import read_manifest
from graphcal.simulate.mounted_imu import mount_imu, vehicle_frame_imu
from graphcal.simulate.streams import EPOCH, simulate_streams, write_streams

#: The acceptance's mounting: roll, pitch, yaw [deg].
MOUNTING = (5.0, 0.0, 90.0)
#: mount_imu's default noise [m/s², rad/s] per sample.
ACCELERATION_NOISE, ANGULAR_VELOCITY_NOISE = 0.05, 0.002


@pytest.fixture(scope="module")
def synthetic():
    """A 4 km synthetic recording (seed 1) with a vehicle-frame IMU (noise-free)."""
    return simulate_streams(4.0, 1)


@pytest.fixture(scope="module")
def plain_dir(tmp_path_factory, synthetic):
    directory = tmp_path_factory.mktemp("plain")
    write_streams(synthetic, directory)
    return directory


@pytest.fixture(scope="module")
def mounted_dir(tmp_path_factory, synthetic):
    """The recording with its IMU mounted at :data:`MOUNTING`, the manifest giving it."""
    directory = tmp_path_factory.mktemp("mounted")
    write_streams(mount_imu(synthetic, *MOUNTING), directory)
    return directory


@pytest.fixture(scope="module")
def estimate_dir(tmp_path_factory, synthetic):
    """The same, the manifest saying ``mounting = "estimate"``."""
    directory = tmp_path_factory.mktemp("estimate")
    write_streams(mount_imu(synthetic, *MOUNTING, estimate=True), directory)
    return directory


@pytest.fixture()
def recording(mounted_dir, tmp_path):
    """A private copy of the mounted recording, to edit."""
    shutil.copytree(mounted_dir, tmp_path / "rec")
    return tmp_path / "rec"


def _edit(path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new))


def _one_line_exit_2(manifest, capsys) -> str:
    assert main(["check", str(manifest)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_the_rotation_is_z_y_x_intrinsic_and_its_angles_round_trip():
    # yaw 90°: the IMU's x axis points to the vehicle's left (y), its y axis backwards
    np.testing.assert_allclose(
        to_vehicle(rotation(0.0, 0.0, np.pi / 2), np.eye(3)),
        [[0, 1, 0], [-1, 0, 0], [0, 0, 1]],
        atol=1e-12,
    )
    # any angles: vehicle = Rz(yaw)·Ry(pitch)·Rx(roll)·IMU
    r, p, y = np.radians([5.0, -20.0, 135.0])
    expected = (
        np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
        @ np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
        @ np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    )
    np.testing.assert_allclose(rotation(r, p, y), expected, atol=1e-12)
    rng = np.random.default_rng(3)
    for triple in rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (20, 3)):
        np.testing.assert_allclose(angles(rotation(*triple)), triple, atol=1e-12)
    vectors = rng.standard_normal((5, 3))
    np.testing.assert_allclose(to_vehicle(expected, to_sensor(expected, vectors)), vectors)
    # the manifest's forms: degrees, a matrix, "estimate"
    np.testing.assert_allclose(parse_mounting([5, -20, 135], "m"), expected, atol=1e-12)
    np.testing.assert_allclose(parse_mounting(expected.tolist(), "m"), expected)
    assert parse_mounting("estimate", "m") == "estimate"


@pytest.mark.slow
def test_a_given_mounting_gives_the_vehicle_frame_signals_to_noise_level(
    synthetic, mounted_dir, plain_dir
):
    imu = read_manifest(mounted_dir / "manifest.toml").imu
    truth = synthetic.imu
    ay_error = imu.lateral_acceleration - truth["ay"].to_numpy()
    wz_error = imu.yaw_rate - truth["wz"].to_numpy()
    # white noise per axis, rotated: the same σ on each vehicle axis
    assert abs(ay_error.std() / ACCELERATION_NOISE - 1) < 0.05 and abs(ay_error.mean()) < 2e-3
    assert abs(wz_error.std() / ANGULAR_VELOCITY_NOISE - 1) < 0.05 and abs(wz_error.mean()) < 1e-4
    # the IMU's own y column is not the lateral acceleration (the test can fail)
    raw = pd.read_csv(mounted_dir / "imu.csv")
    assert np.std(raw["ay"] - truth["ay"]) > 10 * ACCELERATION_NOISE
    # and the drive log's ay equals the vehicle-frame IMU's, to the noise of 2.5 samples' mean
    mounted = import_recording(mounted_dir / "manifest.toml").log
    plain = import_recording(plain_dir / "manifest.toml").log
    assert np.std(mounted.ay - plain.ay) < ACCELERATION_NOISE / np.sqrt(2.5) * 1.2
    np.testing.assert_array_equal(mounted.n_rl, plain.n_rl)


@pytest.mark.slow
def test_the_estimated_mounting_is_within_1_degree_and_calibrates_within_3_sigma(
    synthetic, estimate_dir, capsys
):
    manifest = estimate_dir / "manifest.toml"
    recording = read_manifest(manifest)
    raw = pd.read_csv(estimate_dir / "imu.csv")
    found = estimate_mounting(
        raw["t"].to_numpy(),
        raw[["ax", "ay", "az"]].to_numpy(),
        raw[["wx", "wy", "wz"]].to_numpy(),
        recording.pose,
        recording.wheels,
    )
    error = np.degrees(found.angles) - MOUNTING
    assert np.all(np.abs(error) < 1.0), error
    assert np.all(np.abs(error) < 3 * np.degrees(found.sigma) + 0.05), (error, found.sigma)
    # the import used it: its ay and yaw rate are the vehicle frame's, its note says the angles
    ay_error = recording.imu.lateral_acceleration - synthetic.imu["ay"].to_numpy()
    assert ay_error.std() < 1.1 * ACCELERATION_NOISE
    note = next(n for n in recording.notes if "estimate" in n)
    said = json.loads(note.split("set mounting = ")[1])
    np.testing.assert_allclose(said, np.degrees(found.angles), atol=0.006)
    imported = import_recording(manifest)
    run = run_calibration(imported.log, method="whole", workers=1)
    theta_error = evaluate(run, Truth(imported.truth)).theta_error
    sigma = np.sqrt(np.diag(run.covariance))
    assert np.all(np.abs(theta_error) < 3 * sigma), theta_error / sigma
    assert main(["check", str(manifest)]) == 0
    assert 'mounting = "estimate": roll +' in capsys.readouterr().out


def _estimate_manifest(directory) -> None:
    _edit(directory / "manifest.toml", "mounting = [5.0, 0.0, 90.0]", 'mounting = "estimate"')


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            'acceleration = ["ax", "ay", "az"]',
            'acceleration = ["ax", "ay"]',
            '[imu] acceleration = ["ax", "ay"] names 2 column(s) but needs 3',
        ),
        (
            "mounting = [5.0, 0.0, 90.0]",
            "mounting = [5.0, 90.0]",
            "[imu] mounting = [5.0, 90.0] has 2 value(s); give [roll, pitch, yaw] in degrees",
        ),
        ("mounting = [5.0, 0.0, 90.0]", "", "add mounting = [roll, pitch, yaw]"),
        (
            "mounting = [5.0, 0.0, 90.0]",
            'mounting = "guess"',
            '[imu] mounting = "guess" is not known',
        ),
        (
            "mounting = [5.0, 0.0, 90.0]",
            "mounting = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]",
            "a reflection",
        ),
        # upside down: gravity points down once rotated
        ("mounting = [5.0, 0.0, 90.0]", "mounting = [185.0, 0.0, 90.0]", "° from the vehicle's up"),
        # yaw off by 180° (gravity as right as before): the lateral acceleration turns against
        # the track
        (
            "mounting = [5.0, 0.0, 90.0]",
            "mounting = [5.0, 0.0, -90.0]",
            "opposite sign to the turns of the GNSS track",
        ),
        (
            'angular_velocity = ["wx", "wy", "wz"]',
            'angular_velocity = ["wx", "wy", "wz"]\nyaw_rate_unit = "deg/s"',
            "[imu] yaw_rate_unit applies to yaw_rate; with angular_velocity use "
            "angular_velocity_unit",
        ),
        # the gyro's columns in another order than the accelerometer's
        (
            'angular_velocity = ["wx", "wy", "wz"]',
            'angular_velocity = ["wz", "wy", "wx"]',
            "puts the gyro's turn axis 90° from the vehicle's z",
        ),
        (
            'acceleration = ["ax", "ay", "az"]',
            'acceleration = ["ax", "ay", "az"]\nlateral_acceleration = "ay"',
            "[imu] has both lateral_acceleration (vehicle frame) and acceleration",
        ),
    ],
)
@pytest.mark.slow
def test_a_bad_imu_section_is_one_line(recording, capsys, old, new, expected):
    _edit(recording / "manifest.toml", old, new)
    err = _one_line_exit_2(recording / "manifest.toml", capsys)
    assert expected in err, err
    assert "manifest.toml" in err or "imu.csv" in err, err


def test_the_wrong_mounting_names_the_mounting_key(recording, capsys):
    _edit(recording / "manifest.toml", "mounting = [5.0, 0.0, 90.0]", "mounting = [5, 0, -90]")
    err = _one_line_exit_2(recording / "manifest.toml", capsys)
    assert "column 'ax, ay, az' ([imu] acceleration" in err, err
    assert "check [imu] acceleration_unit" in err and "mounting (now [5, 0, -90]" in err, err


@pytest.mark.slow
def test_units_name_the_3_axis_keys(recording, capsys):
    # an accelerometer in g
    frame = pd.read_csv(recording / "imu.csv")
    in_g = frame.copy()
    in_g[["ax", "ay", "az"]] /= 9.80665
    in_g.to_csv(recording / "imu.csv", index=False)
    err = _one_line_exit_2(recording / "manifest.toml", capsys)
    assert 'apparently in g: set [imu] acceleration_unit = "g"' in err, err
    _edit(recording / "manifest.toml", "mounting =", 'acceleration_unit = "g"\nmounting =')
    assert main(["check", str(recording / "manifest.toml")]) == 0
    capsys.readouterr()
    # a gyro in deg/s declared rad/s (the default)
    in_degrees = frame.copy()
    in_degrees[["wx", "wy", "wz"]] = np.degrees(in_degrees[["wx", "wy", "wz"]])
    in_degrees.to_csv(recording / "imu.csv", index=False)
    _edit(recording / "manifest.toml", 'acceleration_unit = "g"\n', "")
    err = _one_line_exit_2(recording / "manifest.toml", capsys)
    assert 'set [imu] angular_velocity_unit = "deg/s"' in err, err


@pytest.mark.slow
def test_an_estimate_the_data_cannot_give_is_refused(tmp_path, capsys):
    sim = mount_imu(simulate_streams(3.0, 2, route="straight"), *MOUNTING, estimate=True)
    write_streams(sim, tmp_path)
    # the whole straight road: its start and its stop give the yaw (and no turn is needed)
    assert main(["check", str(tmp_path / "manifest.toml")]) == 0
    assert "yaw +90.0" in capsys.readouterr().out
    # an IMU that logged only the cruise at the speed limit: nothing gives the yaw
    imu = pd.read_csv(tmp_path / "imu.csv")
    start = imu["t"].iloc[0]
    imu[(imu["t"] > start + 30) & (imu["t"] < start + 100)].to_csv(
        tmp_path / "imu.csv", index=False
    )
    err = _one_line_exit_2(tmp_path / "manifest.toml", capsys)
    assert '[imu] mounting = "estimate": the drive has ' in err, err
    assert int(err.split("the drive has ")[1].split(" s of")[0]) < 20, err
    assert "set mounting = [roll, pitch, yaw] (degrees)" in err, err


def test_an_estimate_needs_gravity_and_both_sensors(recording, capsys):
    _estimate_manifest(recording)
    _edit(recording / "manifest.toml", 'angular_velocity = ["wx", "wy", "wz"]  # rad/s\n', "")
    err = _one_line_exit_2(recording / "manifest.toml", capsys)
    assert 'mounting = "estimate" needs both acceleration and angular_velocity' in err, err


def test_the_simulated_vehicle_frame_signals_are_the_drive_s(synthetic):
    t = synthetic.imu["t"].to_numpy()
    force, rates = vehicle_frame_imu(synthetic, t)
    np.testing.assert_allclose(force[:, 1], synthetic.imu["ay"], atol=1e-9)
    np.testing.assert_allclose(rates[:, 2], synthetic.imu["wz"], atol=1e-9)
    # in the body's frame a_x = du/dt - ω v_y (u, v_y: the centre of gravity's velocity
    # along and across the heading): a_x + ω v_y integrates to u's change; gravity is up
    truth = synthetic.drive.truth
    velocity = np.gradient(np.column_stack([truth.px, truth.py]), truth.t, axis=0)
    cos, sin = np.cos(truth.psi), np.sin(truth.psi)
    along = velocity[:, 0] * cos + velocity[:, 1] * sin
    across = -velocity[:, 0] * sin + velocity[:, 1] * cos
    since = t - EPOCH
    rate = force[:, 0] + rates[:, 2] * np.interp(since, truth.t, across)
    gained = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    u = np.interp(since, truth.t, along)
    np.testing.assert_allclose(gained, u - u[0], atol=0.05)
    np.testing.assert_array_equal(force[:, 2], 9.80665)
    np.testing.assert_array_equal(rates[:, :2], 0.0)


def test_help_manifest_prints_the_3_axis_keys(capsys):
    with pytest.raises(SystemExit):
        main(["import", "--help-manifest"])
    printed = capsys.readouterr().out
    for key in ("acceleration = [", "angular_velocity_unit", "acceleration_unit", "mounting = ["):
        assert key in printed, key
    assert "Rz(yaw)·Ry(pitch)" in printed
