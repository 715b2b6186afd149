"""Vehicle profiles: the example files, one-line errors, the settings that follow a vehicle,
and a delivery robot's drive checked and calibrated with its own nominal theta."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

import graphcal
from graphcal.errors import GraphcalError
from graphcal.graph.solution.plausibility import PLAUSIBLE_THETA, plausible_ranges
from graphcal.log.drive_log import DriveLogError
from graphcal.log.load import load_drive_log
from graphcal.log.validation import validate_frame
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS
from graphcal.pipeline.configuration.settings import SegmentSettings, Settings, settings_to_dict
from graphcal.pipeline.configuration.settings_file import (
    load_settings,
    load_vehicle,
    settings_from_dict,
)
from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.solvers.batch_calibration import BatchSettings
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.report.document import results_document
from graphcal.report.results import summary_text
from graphcal.simulate.drive import NoiseLevels, VehicleMotion, simulate_drive
from graphcal.vehicle import VehicleProfile

VEHICLES = Path(__file__).resolve().parents[1] / "data" / "vehicles"
ROBOT_THETA_TRUE = np.array([0.49, 0.3e-3, 0.205, 0.0])


@pytest.fixture(scope="module")
def robot() -> VehicleProfile:
    return load_vehicle(VEHICLES / "delivery_robot.toml")


def test_the_car_file_is_the_default_vehicle():
    car = load_vehicle(VEHICLES / "car.toml")
    assert settings_to_dict(car) == settings_to_dict(VehicleProfile())
    assert car.pose_weights() == (1.0, 1.0, 50.0)
    assert car.white_wheel_noise() == 0.0005 and car.tick_quantization() == 0.0


def test_the_robot_file(robot):
    assert robot.name == "delivery robot"
    np.testing.assert_array_equal(robot.theta_nominal, [0.5, 0.0, 0.2, 0.0])
    assert robot.ticks_per_revolution == 64
    assert robot.pose_weights()[2] == pytest.approx((0.05 / 0.0175) ** 2)
    # 64 counts per revolution: each count rounded by up to half a tick.
    assert robot.tick_quantization() == pytest.approx(1 / (64 * np.sqrt(12)))
    assert robot.white_wheel_noise() == 0.0005


def test_the_default_vehicle_gives_todays_defaults():
    car = VehicleProfile()
    np.testing.assert_array_equal(car.theta_nominal, THETA_NOMINAL)
    np.testing.assert_array_equal(car.theta_prior_sigmas, THETA_PRIOR_SIGMAS)
    for section in (BatchSettings(), JointSettings()):
        assert section.pose_weights == car.pose_weights()
        assert section.position_sigma == car.position_sigma
    assert JointSettings().wheel_noise == car.white_wheel_noise()
    assert JointSettings().tick_quantization == car.tick_quantization()
    default = Settings()
    assert settings_to_dict(apply_vehicle(default, car)) == settings_to_dict(default)
    assert default.to_dict()["vehicle"]["name"] == "paper car"


def test_a_vehicle_file_may_hold_a_vehicle_table(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_text('[vehicle]\nname = "r"\ntheta_nominal = [0.5, 0.0, 0.2, 0.0]\n')
    assert load_vehicle(path).theta_nominal[2] == 0.2
    path.write_text('[vehicle]\nname = "r"\n\n[joint]\nwheel_noise = 0.001\n')
    with pytest.raises(GraphcalError, match=r"also found \['joint'\]; give a settings file"):
        load_vehicle(path)
    with pytest.raises(GraphcalError, match="no such vehicle file"):
        load_vehicle(tmp_path / "missing.toml")


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("tyre_pressure = 2.2", "unknown key(s) ['tyre_pressure'] in [vehicle]"),
        ("theta_nominal = [0.5, 0.0, 0.2]", "[vehicle] theta_nominal must be a list of 4"),
        ("theta_nominal = [0.5, 0.0, -0.2, 0.0]", "vehicle.theta_nominal: t_r (rear track)"),
        ("theta_nominal = [0.0, 0.0, 0.2, 0.0]", "vehicle.theta_nominal: c_e (wheel"),
        ("theta_prior_sigmas = [0.1, 0.0, 0.2, 0.01]", "vehicle.theta_prior_sigmas must be"),
        ("position_sigma = 'small'", "[vehicle] position_sigma must be a number"),
        ("heading_sigma = 0", "vehicle.heading_sigma must be a positive number"),
        ("wheel_noise = -0.001", "vehicle.wheel_noise must be a number >= 0"),
        ("wheel_noise = 0.0", "vehicle.wheel_noise must be positive unless ticks_per_rev"),
        ("ticks_per_revolution = 0", "vehicle.ticks_per_revolution must be a whole number >= 1"),
        ("ticks_per_revolution = 64.5", "[vehicle] ticks_per_revolution must be a whole number"),
        ("name = ''", "vehicle.name must be non-empty text"),
    ],
)
def test_bad_vehicle_keys_are_one_line_errors(tmp_path, text, fragment):
    path = tmp_path / "v.toml"
    path.write_text(text + "\n")
    for load in (load_vehicle, load_settings):
        if load is load_settings:
            path.write_text("[vehicle]\n" + text + "\n")
        with pytest.raises(GraphcalError) as info:
            load(path)
        message = str(info.value)
        assert message.startswith(f"{path}: ") and fragment in message and "\n" not in message


def test_the_vehicle_section_gives_defaults_and_explicit_keys_win(robot):
    data = {
        "vehicle": settings_to_dict(robot),
        "joint": {"wheel_noise": 0.002, "position_sigma": 0.2},  # 0.2: the car's, yet explicit
        "calibration": {"pose_weights": [1.0, 1.0, 50.0]},
    }
    settings = settings_from_dict(data)
    assert settings.vehicle.name == "delivery robot"
    for section in (settings.calibration, settings.joint):
        np.testing.assert_array_equal(section.theta_initial, robot.theta_nominal)
        np.testing.assert_array_equal(section.theta_prior_sigmas, robot.solve_prior_sigmas())
    assert settings.calibration.position_sigma == 0.05
    assert settings.calibration.pose_weights == (1.0, 1.0, 50.0)  # explicit
    assert settings.joint.pose_weights == robot.pose_weights()
    assert settings.joint.position_sigma == 0.2  # explicit
    assert settings.joint.wheel_noise == 0.002  # explicit
    assert settings.calibration.max_iterations == 5  # not the vehicle's: unchanged
    # The whole settings round-trip (every key explicit) and without [vehicle] nothing moves.
    assert settings_to_dict(settings_from_dict(settings.to_dict())) == settings.to_dict()
    plain = settings_from_dict({"joint": {"wheel_noise": 0.002}})
    assert settings_to_dict(plain.calibration) == settings_to_dict(Settings().calibration)


def test_apply_vehicle_keeps_what_was_changed(robot):
    custom = dataclasses.replace(
        Settings(), joint=dataclasses.replace(JointSettings(), wheel_noise=0.003)
    )
    settings = apply_vehicle(custom, robot)
    assert settings.vehicle is robot
    assert settings.joint.wheel_noise == 0.003  # not the car's value: the user's choice
    np.testing.assert_array_equal(settings.joint.theta_initial, robot.theta_nominal)
    assert settings.calibration.pose_weights == robot.pose_weights()
    kept = apply_vehicle(Settings(), robot, keep={"calibration.theta_initial"})
    np.testing.assert_array_equal(kept.calibration.theta_initial, THETA_NOMINAL)
    np.testing.assert_array_equal(kept.joint.theta_initial, robot.theta_nominal)
    with pytest.raises(ValueError, match=r"keep names \['joint.wheelnoise'\]"):
        apply_vehicle(Settings(), robot, keep={"joint.wheelnoise"})
    # A second vehicle replaces the first wherever the first one's values still stand.
    back = apply_vehicle(settings, VehicleProfile())
    assert back.joint.wheel_noise == 0.003
    assert settings_to_dict(back.calibration) == settings_to_dict(Settings().calibration)


def test_plausible_ranges_scale_with_the_vehicle(robot):
    np.testing.assert_array_equal(plausible_ranges(), PLAUSIBLE_THETA)
    ranges = plausible_ranges(robot.theta_nominal)
    assert ranges[0, 0] < 0.5 < ranges[0, 1] and ranges[2, 0] < 0.2 < ranges[2, 1]
    assert not ranges[2, 0] < 0.2 * 10 < ranges[2, 1]  # a car-sized track is not a robot's


def test_the_vehicle_module_stays_light():
    tree = ast.parse(Path(graphcal.vehicle.__file__).read_text())
    imported = {
        node.module if isinstance(node, ast.ImportFrom) else alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.Import | ast.ImportFrom)
        for alias in node.names
    }
    assert imported <= {"__future__", "math", "dataclasses", "numpy", "graphcal.errors",
                        "graphcal.model"}  # fmt: skip


def test_public_names():
    assert {"VehicleProfile", "load_vehicle", "apply_vehicle"} <= set(graphcal.__all__)
    assert graphcal.VehicleProfile is VehicleProfile


@pytest.fixture(scope="module")
def robot_frame(robot):
    """A 1.5 km drive of a robot with 0.49 m wheel circumference and 0.205 m track: noise as
    its profile says, rotations counted by a 64-count encoder (car-sized route and speeds)."""
    noise = NoiseLevels(
        position=robot.position_sigma,
        heading=robot.heading_sigma,
        wheel_rotation=robot.wheel_noise,
    )
    drive = simulate_drive(
        length_km=1.5,
        seed=3,
        theta_true=ROBOT_THETA_TRUE,
        noise=noise,
        motion=VehicleMotion(lateral_acceleration_limit=0.5, start_speed=1.0),
    )
    frame = drive.measured.to_dataframe()
    ticks = robot.ticks_per_revolution
    for column in ("n_rl", "n_rr"):
        true = getattr(drive.truth, column)
        counts = np.floor(np.concatenate([[0.0], np.cumsum(true)]) * ticks)
        noise_only = getattr(drive.measured, column) - true
        frame[column] = np.diff(counts) / ticks + noise_only
    return frame


def test_a_robot_log_needs_the_robots_nominal_theta(robot, robot_frame, tmp_path):
    with pytest.raises(DriveLogError, match=r"positions travel 0.2\d+x .* with c_e = 2 m"):
        validate_frame(robot_frame, "robot.csv")
    log = validate_frame(robot_frame, "robot.csv", nominal=robot.theta_nominal)
    assert log.masked is None
    path = tmp_path / "robot.csv"
    robot_frame.to_csv(path, index=False)
    with pytest.raises(DriveLogError, match="shorter than one 2000 m segment"):
        load_drive_log(path, min_distance=2000.0, nominal=robot.theta_nominal)
    assert len(load_drive_log(path, min_distance=1000.0, nominal=robot.theta_nominal)) == len(log)


@pytest.mark.slow
def test_a_robot_drive_calibrates_with_its_profile(robot, robot_frame):
    log = validate_frame(robot_frame, "robot.csv", nominal=robot.theta_nominal)
    settings = dataclasses.replace(
        apply_vehicle(Settings(), robot),
        segments=SegmentSettings(length=50.0, validation_length=100.0),
    )
    run = run_calibration(log, settings, method="whole", workers=1)
    sigma = np.sqrt(run.covariance[0, 0])
    assert abs(run.theta[0] - ROBOT_THETA_TRUE[0]) < 3 * sigma
    assert sigma < 0.002  # 0.4 %: the data, not the 25 mm prior, determine c_e
    assert "c_e" not in run.observability.not_calibrated
    # Segments are cut by the robot's wheel distance, and the nominal row is the robot's.
    assert run.segments.length == 50.0 and len(run.validation_segments) >= 14
    assert run.validation_error("calibrated") < run.validation_error("nominal")
    assert "nominal      0.5000" in summary_text(run)
    doc = results_document(run)
    assert doc["theta_nominal"]["c_e"] == 0.5 and doc["theta_nominal"]["t_r"] == 0.2
    assert doc["settings"]["vehicle"]["ticks_per_revolution"] == 64
    # The wheels' distance with the robot's 0.5 m circumference, not the car's 2 m.
    assert doc["log"]["distance_m"] == pytest.approx(log.travelled_distance(2.0)[-1] / 4.0)


def test_a_vehicle_on_the_command_line_keeps_what_the_config_sets(tmp_path):
    from graphcal.cli import build_parser
    from graphcal.cli.options import settings_from_args

    config = tmp_path / "cfg.toml"
    config.write_text("[joint]\nwheel_noise = 0.0005\n")  # the car's value, set explicitly
    robot = str(VEHICLES / "delivery_robot.toml")
    args = ["calibrate", "x.csv", "--config", str(config), "--vehicle", robot]
    settings = settings_from_args(build_parser().parse_args(args))
    assert settings.joint.wheel_noise == 0.0005
    np.testing.assert_allclose(settings.joint.theta_initial, [0.5, 0.0, 0.2, 0.0])
