"""A differential-drive robot calibrated from its profile alone (issue 27): runs of a few
metres, spins on the spot, motion capture, 2797-tick encoders — through the command line, as
CSV streams and as a ROS 2 bag."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.graph.solution.observability import HELD_VERDICT, assess_observability
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.configuration.settings_file import load_vehicle
from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle

ROOT = Path(__file__).resolve().parents[1]
ROBOT = str(ROOT / "data" / "vehicles" / "mocap_robot.toml")


def _simulate(directory: Path, seed: int, *extra: str) -> Path:
    args = ["simulate", "--vehicle", ROBOT, "--seed", str(seed), "--streams", str(directory)]
    assert main([*args, *extra]) == 0
    return directory


def _calibrated(source: Path, out: Path, capsys) -> tuple[dict, str]:
    assert main(["calibrate", str(source), "--vehicle", ROBOT, "--out", str(out)]) == 0
    return json.loads((out / "calibration.json").read_text()), capsys.readouterr().err


def _check_within_3_sigma(result: dict, truth: dict) -> None:
    assert result["trust"]["trusted"]
    for name in ("c_e", "c_d", "t_r"):
        entry = result["parameters"][name]
        assert entry["status"] == "calibrated", entry
        error = result["theta"][name] - truth[name]
        assert abs(error) < 3 * entry["sigma"], (name, error / entry["sigma"])
    assert result["parameters"]["t_r"]["sigma"] <= 1e-3
    assert result["parameters"]["d"]["status"].startswith(HELD_VERDICT)
    assert result["theta"]["d"] == 0.0


@pytest.mark.slow
@pytest.mark.parametrize(("seed", "extra"), [(0, ()), (1, ("--reversing",))])
def test_a_robot_calibrates_from_its_profile_alone(tmp_path, capsys, seed, extra):
    streams = _simulate(tmp_path / "rec", seed, *extra)
    result, err = _calibrated(streams, tmp_path / "out", capsys)
    truth = json.loads((streams / "truth.json").read_text())["theta_true"]
    _check_within_3_sigma(result, truth)
    # The segment geometry the vehicle's size gave, printed and written.
    assert "segments of 19.4 m, validation segments of 38.7 m" in err
    assert result["settings"]["segments"]["length"] == 19.4
    assert "reversing" not in err  # spins (and reversing) are motion, not masked


@pytest.mark.slow
def test_a_robot_bag_calibrates(tmp_path, capsys):
    streams = _simulate(tmp_path / "rec", 2, "--runs", "6", "--bag", "ros2")
    result, _ = _calibrated(streams / "drive_ros2", tmp_path / "out", capsys)
    _check_within_3_sigma(result, json.loads((streams / "truth.json").read_text())["theta_true"])


def test_a_robot_log_without_its_profile_is_one_line_naming_vehicle(tmp_path, capsys):
    streams = _simulate(tmp_path / "rec", 0, "--runs", "3")
    capsys.readouterr()
    assert main(["calibrate", str(streams), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--vehicle" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_segments_too_short_for_the_vehicle_are_one_line(tmp_path, capsys):
    streams = _simulate(tmp_path / "rec", 0, "--runs", "3")
    capsys.readouterr()
    args = ["calibrate", str(streams), "--vehicle", ROBOT, "--segment-length", "0.5"]
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "shorter than 5 tracks" in err and "1 m" in err


def test_segment_lengths_follow_the_vehicle_and_the_car_keeps_the_papers():
    robot = apply_vehicle(Settings(), load_vehicle(ROBOT))
    assert (robot.segments.length, robot.segments.validation_length) == (19.4, 38.7)
    car = apply_vehicle(Settings(), load_vehicle(ROOT / "data" / "vehicles" / "car.toml"))
    assert (car.segments.length, car.segments.validation_length) == (150.0, 300.0)
    # A length the user set stays.
    custom = Settings(segments=Settings().segments.__class__(length=30.0))
    assert apply_vehicle(custom, load_vehicle(ROBOT)).segments.length == 30.0


def test_a_held_parameter_is_fixed_not_a_degeneracy():
    sigmas = np.array([0.01, 0.001, 0.01, 1e-7])
    covariance = np.diag((sigmas * [0.01, 0.02, 0.01, 1.0]) ** 2)
    held = np.array([False, False, False, True])
    observability = assess_observability(covariance, sigmas, held=held)
    assert not observability.degenerate and observability.not_calibrated == []
    assert observability.verdicts()["d"] == HELD_VERDICT
    plain = assess_observability(covariance, sigmas)
    assert plain.not_calibrated == ["d"] and plain.verdicts()["d"] == "not observable"
    assert set(observability.verdicts()) == set(PARAMETER_NAMES)
