"""A lever arm names the point it is measured from, and two paths of one drive agree (issue 44,
row 4).

Without a logged sideslip the model's positions are those of the rear axle, not the centre of
gravity: a bag of a drive whose antenna sits at the centre of gravity found it "+1.19 m ahead
of the centre of gravity"; named, it was still 8σ short of the 1.35 m to the axle (the rear
tyres' slip read as the arm) until the slip gain was estimated."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

import graphcal
from graphcal.log.drive_log import DriveLog
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.methods.sensor_estimates import SensorEstimate, measured_from
from graphcal.pipeline.methods.whole_log_lines import estimate_lines
from graphcal.report.tables import estimates_table
from graphcal.simulate.drive import VehicleMotion, simulate_drive
from graphcal.units import METRES

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"

ARM = {
    "time_offset": SensorEstimate("time_offset", 2e-3, 1e-3, 0.5, True),
    "lever_arm_longitudinal": SensorEstimate("lever_arm_longitudinal", 1.19, 0.04, 2.0, True),
    "lever_arm_lateral": SensorEstimate("lever_arm_lateral", 0.01, 0.01, 2.0, True),
    "rear_slip_gain": SensorEstimate("rear_slip_gain", 4.7e-3, 0.5e-3, 0.01, True),
}


def _log(beta: float) -> DriveLog:
    columns = ("px", "py", "psi", "n_rl", "n_rr", "ay")
    arrays = {c: np.zeros(3) for c in columns}
    return DriveLog.from_arrays(t=np.arange(3.0), beta=np.full(3, beta), **arrays)


def test_the_reference_point_follows_the_sideslip():
    assert _log(0.0).position_reference() == "rear axle"
    assert _log(0.01).position_reference() == "centre of gravity"


def test_lines_tables_and_json_name_the_point():
    log = dataclasses.replace(_log(0.0), pose_source="GNSS")
    named = measured_from(ARM, log.position_reference())
    lines = estimate_lines(named, log, METRES)
    assert "GNSS antenna ahead of the rear axle: +1.190 ± 0.040 m" in lines[1], lines
    assert "GNSS antenna left of the rear axle" in lines[2], lines
    table = estimates_table(named, METRES)
    assert "lever arm, ahead of the rear axle [m]" in table, table
    assert named["lever_arm_longitudinal"].to_dict()["from"] == "rear axle"
    assert "from" not in named["time_offset"].to_dict()  # a time has no point
    slip = "rear axle's slip angle per lateral acceleration"
    assert f"{slip}: +4.70 ± 0.50 mrad per m/s²; detected, corrected" in lines[3], lines
    assert f"{slip} [mrad per m/s²]   +4.70   0.50" in table, table


def test_a_log_without_sideslip_reports_its_arm_from_the_rear_axle(tmp_path):
    log = graphcal.load_drive_log(SAMPLE)
    settings = Settings(batches=BatchingSettings(count=0))
    runs = {}
    for name, beta in (("cg", log.beta), ("rear axle", np.zeros_like(log.beta))):
        run = graphcal.run_calibration(dataclasses.replace(log, beta=beta), settings, workers=1)
        graphcal.write_results(run, tmp_path / name)
        runs[name] = json.loads((tmp_path / name / "calibration.json").read_text())
    assert runs["cg"]["estimated"]["lever_arm_longitudinal"]["from"] == "centre of gravity"
    assert runs["rear axle"]["estimated"]["lever_arm_lateral"]["from"] == "rear axle"


def test_a_drive_with_and_without_its_sideslip_puts_the_antenna_in_one_place():
    # The simulator's antenna sits at the centre of gravity, l_r = 1.35 m ahead of the rear
    # axle, whose tyres slip at -g a_y (g = 4.7 mrad per m/s²). Logged with its sideslip the
    # arm is measured from the centre of gravity; without, from the rear axle, with g
    # estimated. Both must name the same antenna, and g its truth, within 3σ.
    motion = VehicleMotion()
    log = simulate_drive(length_km=4.0, seed=5).measured
    settings = Settings(batches=BatchingSettings(count=0))
    found = {}
    for point, beta in (("cg", log.beta), ("rear axle", np.zeros_like(log.beta))):
        run = graphcal.run_calibration(dataclasses.replace(log, beta=beta), settings, workers=1)
        found[point] = run.estimated
    cg, rear = found["cg"]["lever_arm_longitudinal"], found["rear axle"]["lever_arm_longitudinal"]
    assert "rear_slip_gain" not in found["cg"]  # the sideslip logged is the slip
    gap = rear.value - cg.value - motion.rear_axle_to_cg
    assert abs(gap) < 3 * np.hypot(rear.sigma, cg.sigma), (rear, cg)
    gain = found["rear axle"]["rear_slip_gain"]
    assert gain.detected and abs(gain.value - motion.rear_slip_gain) < 3 * gain.sigma, gain


def test_a_detected_rear_slip_gain_becomes_the_logs_sideslip_and_an_undetected_one_does_not():
    from graphcal.pipeline.methods.sensor_estimates import correct_log

    log = dataclasses.replace(_log(0.0), ay=np.array([0.0, 2.0, -1.0]))
    found = {"rear_slip_gain": SensorEstimate("rear_slip_gain", 4e-3, 0.5e-3, 0.01, True)}
    np.testing.assert_allclose(correct_log(log, found).beta, [0.0, -8e-3, 4e-3])
    within_noise = {"rear_slip_gain": SensorEstimate("rear_slip_gain", 1e-3, 0.5e-3, 0.01, True)}
    assert np.all(correct_log(log, within_noise).beta == 0)
