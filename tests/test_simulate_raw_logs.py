"""Issue 35: ``graphcal simulate --streams DIR --can --nmea`` makes a sample of a car's raw logs
— the wheels and IMU as a candump log of the bus with its DBC, the GNSS as an NMEA 0183 log —
whose manifest reads them: ``check`` says valid and ``calibrate`` finds the truth."""

from __future__ import annotations

import importlib.util
import json
import tomllib

import numpy as np
import pytest

pytest.importorskip("cantools")
pytest.importorskip("can")
pytest.importorskip("pynmea2")

from graphcal.cli import main


def _simulate(directory, *flags: str, length_km: str = "1") -> None:
    assert main(["simulate", "--streams", str(directory), "--length-km", length_km, *flags]) == 0


def _one_line_exit_2(args: list[str], capsys) -> str:
    """``graphcal ARGS``: exit 2, one line on stderr, no traceback."""
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("graphcal: error: "), err
    return err


@pytest.mark.parametrize(
    "flags, files, absent",
    [
        (
            ("--can", "--nmea"),
            {"drive.log", "car.dbc", "receiver.nmea"},
            {"gnss.csv", "wheels.csv", "imu.csv"},
        ),
        (("--can",), {"drive.log", "car.dbc", "gnss.csv"}, {"wheels.csv", "imu.csv"}),
        (("--nmea",), {"receiver.nmea", "wheels.csv", "imu.csv"}, {"gnss.csv", "drive.log"}),
    ],
)
def test_can_and_nmea_write_the_logs_their_manifest_reads_and_check_passes(
    tmp_path, capsys, flags, files, absent
):
    directory = tmp_path / "rec"
    _simulate(directory, *flags)
    names = {path.name for path in directory.iterdir()}
    assert files | {"manifest.toml", "truth.json"} <= names and not names & absent, names
    manifest = tomllib.loads((directory / "manifest.toml").read_text())
    if "--can" in flags:
        assert manifest["wheels"]["can"] == "drive.log" and manifest["wheels"]["dbc"] == "car.dbc"
        assert manifest["wheels"]["rear_left"] == "WHEEL_SPEED_RL" and "file" not in manifest["imu"]
        assert (directory / "drive.log").read_text().startswith("(1763855999.")  # candump -L
    if "--nmea" in flags:
        assert manifest["gnss"] == {"nmea": "receiver.nmea"}
        assert (directory / "receiver.nmea").read_text().startswith("$GNGGA,")
    capsys.readouterr()
    assert main(["check", str(directory)]) == 0
    out = capsys.readouterr().out
    assert "valid recording" in out, out
    if "--can" in flags:
        assert "wheels " + str(directory / "drive.log") + ": " in out, out
    if "--nmea" in flags:
        assert "pose   " + str(directory / "receiver.nmea") + ": " in out, out


def test_the_can_sample_is_the_csv_sample_in_the_dbcs_encoding(tmp_path):
    """The same seed with and without --can: the same drive log but for the DBC's steps
    (wheel speeds 0.01 km/h, lateral acceleration 0.002 m/s²)."""
    from graphcal.recording.importer import import_recording

    _simulate(tmp_path / "csv", "--seed", "1")
    _simulate(tmp_path / "can", "--seed", "1", "--can")
    csv = import_recording(tmp_path / "csv" / "manifest.toml").log.to_dataframe()
    can = import_recording(tmp_path / "can" / "manifest.toml").log.to_dataframe()
    assert list(csv.columns) == list(can.columns) and len(csv) == len(can) > 5000
    for column, tolerance in (("px", 0), ("py", 0), ("psi", 0), ("n_rl", 3e-5), ("ay", 0.0011)):
        x, y = csv[column].to_numpy(), can[column].to_numpy()
        assert np.array_equal(np.isnan(x), np.isnan(y)), column  # the rows without a fix
        assert np.nanmax(np.abs(x - y)) <= tolerance, (column, np.nanmax(np.abs(x - y)))


@pytest.mark.parametrize("flag", ["--can", "--nmea"])
def test_can_and_nmea_without_streams_are_refused(tmp_path, capsys, flag):
    out = tmp_path / "q.csv"
    err = _one_line_exit_2(["simulate", flag, "--out", str(out)], capsys)
    assert f"{flag} applies to --streams DIR" in err and f"remove {flag}" in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "flag, others, expected",
    [
        ("--can", ["--bag", "ros2"], "--can and --bag ros2: a bag holds the streams as ROS"),
        ("--nmea", ["--bag", "mcap"], "--nmea and --bag mcap"),
        ("--can", ["--wheel-kind", "ticks"], "--wheel-kind ticks has no message in its DBC"),
        (
            "--nmea",
            ["--vehicle", "data/vehicles/mocap_robot.toml"],
            "a robot (--vehicle data/vehicles/mocap_robot.toml) logs motion-capture poses",
        ),
    ],
)
def test_can_and_nmea_with_what_they_cannot_go_with_are_refused(
    tmp_path, capsys, flag, others, expected
):
    directory = tmp_path / "rec"
    err = _one_line_exit_2(["simulate", "--streams", str(directory), flag, *others], capsys)
    assert expected in err, err
    assert not directory.exists()


@pytest.mark.parametrize(
    "flag, missing, extra", [("--can", "cantools", "can"), ("--nmea", "pynmea2", "nmea")]
)
def test_a_missing_extra_is_named(tmp_path, capsys, monkeypatch, flag, missing, extra):
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == missing else find_spec(name)
    )
    directory = tmp_path / "rec"
    err = _one_line_exit_2(["simulate", "--streams", str(directory), flag], capsys)
    assert f'pip install -e ".[{extra}]"' in err and missing in err, err
    assert not directory.exists()


@pytest.mark.slow
def test_a_3_km_can_and_nmea_sample_calibrates_within_3_sigma_of_its_truth(tmp_path, capsys):
    """``calibrate DIR --method whole``: every parameter within 3σ of truth.json."""
    directory, results = tmp_path / "rec", tmp_path / "results"
    _simulate(directory, "--can", "--nmea", "--seed", "1", length_km="3")
    assert main(["calibrate", str(directory), "--method", "whole", "--out", str(results)]) == 0
    calibration = json.loads((results / "calibration.json").read_text())
    truth = json.loads((directory / "truth.json").read_text())["theta_true"]
    for name, parameter in calibration["parameters"].items():
        error = parameter["value"] - truth[name]
        assert parameter["status"] == "calibrated", (name, parameter)
        assert abs(error) < 3 * parameter["sigma"], (name, error / parameter["sigma"])
    assert np.isclose(calibration["theta_true"]["c_e"], truth["c_e"])
