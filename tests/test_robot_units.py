"""Issue 35, reports: a robot's report in units that fit it, naming the pose it has.

A motion-capture robot's report printed ``lever arm 0.000 ± 0.000 m``, "mean position error
0.00 m" and "GNSS antenna" for a pose no GNSS measured."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from graphcal.cli import main
from graphcal.log.drive_log import DriveLog
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.configuration.settings_file import load_vehicle
from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.methods.sensor_estimates import SensorEstimate
from graphcal.pipeline.methods.whole_log_lines import estimate_lines
from graphcal.recording.importer import import_recording
from graphcal.report.figures import trajectory_figure, validation_figure
from graphcal.report.results import summary_text
from graphcal.report.tables import estimates_table, validation_table
from graphcal.simulate.robot import simulate_robot
from graphcal.units import METRES, MILLIMETRES, length_unit

ROOT = Path(__file__).resolve().parents[1]
ROBOT = ROOT / "data" / "vehicles" / "mocap_robot.toml"

#: A robot's lever arm: a few tenths of a mm, known to a tenth.
ARM = {
    "time_offset": SensorEstimate("time_offset", 2e-4, 2e-4, 0.1, True),
    "lever_arm_longitudinal": SensorEstimate("lever_arm_longitudinal", 4e-4, 1e-4, 0.01, True),
    "lever_arm_lateral": SensorEstimate("lever_arm_lateral", 0.0, 0.01, 0.01, False),
}


def test_a_robot_reads_lengths_in_mm_and_a_car_in_m():
    assert length_unit(0.2) is MILLIMETRES and length_unit(1.55) is METRES
    assert METRES.spread(2e-5) == "2e-05"  # never 0.000 for a σ that is not 0


def test_the_robot_s_lever_arm_is_in_mm_and_one_not_estimated_is_no_number():
    rows = {
        line.split("[")[0].strip(): line for line in estimates_table(ARM, MILLIMETRES).splitlines()
    }
    assert "[mm]" in rows["lever arm, ahead"] and "+0.4" in rows["lever arm, ahead"]
    assert "0.1" in rows["lever arm, ahead"]
    left = rows["lever arm, left"].split()
    assert left[-4:] == ["-", "-", "not", "observable"], left
    assert "0.000" not in estimates_table(ARM, MILLIMETRES)
    assert "validation error E_p [mm]" in validation_table({"calibrated": 0.0176}, MILLIMETRES)
    assert "17.6" in validation_table({"calibrated": 0.0176}, MILLIMETRES)


def test_progress_lines_name_the_pose_the_log_has():
    columns = ("px", "py", "psi", "n_rl", "n_rr", "beta", "ay")
    log = DriveLog.from_arrays(t=np.arange(3.0), **{c: np.zeros(3) for c in columns})
    lines = estimate_lines(ARM, log, MILLIMETRES)
    assert "position source ahead of the rear axle: +0.4 ± 0.1 mm" in lines[1]  # beta 0
    assert "position source left of the rear axle: not observable" in lines[2]
    assert not [line for line in lines if "GNSS" in line]
    fixes = estimate_lines(ARM, dataclasses.replace(log, pose_source="GNSS"), METRES)
    assert "GNSS antenna ahead" in fixes[1]


def test_the_import_knows_gnss_fixes_from_a_local_pose(tmp_path):
    robot = tmp_path / "robot"
    args = ["simulate", "--vehicle", str(ROBOT), "--runs", "3", "--streams", str(robot)]
    assert main(args) == 0
    vehicle = load_vehicle(ROBOT)
    imported = import_recording(
        robot / "manifest.toml", nominal=vehicle.theta_nominal, reverses=vehicle.reverses
    )
    assert imported.log.pose_source is None  # motion capture
    car = tmp_path / "car"
    assert main(["simulate", "--length-km", "0.5", "--streams", str(car)]) == 0
    assert import_recording(car / "manifest.toml").log.pose_source == "GNSS"  # lat/lon


@pytest.fixture(scope="module")
def robot_run() -> CalibrationRun:
    sim = simulate_robot(seed=0, runs=6)
    settings = apply_vehicle(
        Settings(batches=BatchingSettings(count=1, size=4)), load_vehicle(ROBOT)
    )
    return run_calibration(sim.drive.measured, settings, "joint", workers=1)


@pytest.mark.slow
def test_a_robot_s_summary_and_figures_say_mm(robot_run):
    text = summary_text(robot_run)
    assert "validation error E_p [mm]" in text
    assert "0.000 ± 0.000" not in text and "GNSS" not in text
    assert "[mm]" in next(line for line in text.splitlines() if line.startswith("lever arm, ahead"))
    labels = [t.get_text() for t in trajectory_figure(robot_run).legends[0].get_texts()]
    assert [t for t in labels if t.endswith(" mm")] and not [t for t in labels if "0.00 m" in t]
    assert "[mm]" in validation_figure(robot_run).axes[0].get_xlabel()
