"""Issue 35: an option that does not apply to what it is given with says so, and a usage error
is one line, not the usage of every option.

Each refusal is one line on stderr, exit status 2, nothing written; no test here runs a
calibration (the checks come before any work).
"""

from __future__ import annotations

import pytest

from graphcal.cli import main
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive


@pytest.fixture(scope="module")
def drive_csv(tmp_path_factory):
    """A 1 km drive-log CSV (seed 1)."""
    path = tmp_path_factory.mktemp("drive") / "drive.csv"
    write_synthetic_drive(simulate_drive(1.0, 1), path)
    return path


def _one_line_exit_2(args: list[str], capsys) -> str:
    """``graphcal ARGS``: exit 2 (returned or by SystemExit), one line on stderr, no usage."""
    try:
        status = main(args)
    except SystemExit as exited:
        status = exited.code
    assert status == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.count("\n") == 1 and "Traceback" not in err and "usage:" not in err, err
    assert err.startswith("graphcal: error: "), err
    return err


# --- argparse's errors: one line and where the options are -------------------------------


@pytest.mark.parametrize(
    ("args", "expected", "hint"),
    [
        (["calibrate", "x.csv", "--batches", "-1"], "argument --batches", "graphcal calibrate"),
        (["calibrate", "x.csv", "--batchs", "3"], "unrecognized arguments: --batchs", "calibrate"),
        (["import", "--rate"], "argument --rate: expected one argument", "graphcal import"),
        (["simulate", "--route", "hills"], "invalid choice: 'hills'", "graphcal simulate"),
        (["check"], "required: log", "graphcal check"),
    ],
)
def test_a_usage_error_is_one_line_with_the_commands_help(args, expected, hint, capsys):
    err = _one_line_exit_2(args, capsys)
    assert expected in err, err
    assert f"{hint if hint.startswith('graphcal') else 'graphcal ' + hint} --help for the" in err


def test_an_unknown_command_points_at_the_commands(capsys):
    err = _one_line_exit_2(["calibrat", "x.csv"], capsys)
    assert "invalid choice: 'calibrat'" in err and "(graphcal --help for the commands)" in err


# --- options that do not apply -----------------------------------------------------------


@pytest.mark.parametrize("command", ["check", "calibrate"])
@pytest.mark.parametrize(
    ("option", "value"),
    [("--rate", "100"), ("--max-gap", "1"), ("--pose-topic", "/fix"), ("--speed-unit", "km/h")],
)
def test_recording_options_with_a_drive_log_csv_are_refused(
    drive_csv, tmp_path, capsys, command, option, value
):
    out = tmp_path / "result"
    args = [command, str(drive_csv), option, value]
    err = _one_line_exit_2([*args, "--out", str(out)] if command == "calibrate" else args, capsys)
    assert f"{option} " in err and str(drive_csv) in err and "drive-log CSV" in err, err
    assert "remove it" in err, err
    assert not out.exists()


@pytest.fixture(scope="module")
def streams_dir(tmp_path_factory):
    """A 1 km synthetic recording (seed 1) with its manifest."""
    from graphcal.simulate.streams import simulate_streams, write_streams

    directory = tmp_path_factory.mktemp("streams")
    write_streams(simulate_streams(1.0, 1), directory)
    return directory


@pytest.mark.parametrize("command", ["check", "import"])
def test_bag_options_with_a_manifest_are_refused(streams_dir, tmp_path, capsys, command):
    out = tmp_path / "drive.csv"
    manifest = str(streams_dir / "manifest.toml")
    args = [command, manifest, "--pose-topic", "/fix", "--rear-left", "rl_joint"]
    err = _one_line_exit_2([*args, "--out", str(out)] if command == "import" else args, capsys)
    assert "--pose-topic, --rear-left" in err and "ROS bag" in err and manifest in err, err
    assert not out.exists()


def test_simulate_bag_without_streams_is_refused(tmp_path, capsys):
    out = tmp_path / "q.csv"
    err = _one_line_exit_2(["simulate", "--bag", "ros2", "--out", str(out)], capsys)
    assert "--bag ros2 applies to --streams DIR" in err, err
    assert not out.exists()


def test_simulate_wheel_kind_without_streams_is_refused(tmp_path, capsys):
    out = tmp_path / "q.csv"
    err = _one_line_exit_2(["simulate", "--wheel-kind", "ticks", "--out", str(out)], capsys)
    assert "--wheel-kind ticks applies to --streams DIR" in err, err
    assert not out.exists()


def test_simulate_with_both_outputs_is_refused(tmp_path, capsys):
    out, streams = tmp_path / "x.csv", tmp_path / "d"
    err = _one_line_exit_2(["simulate", "--streams", str(streams), "--out", str(out)], capsys)
    assert "--out" in err and "--streams" in err and "not both" in err, err
    assert not out.exists() and not streams.exists()
