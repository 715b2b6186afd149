"""Bad or unusual input a user brings: each is found, located and either refused with one line
(exit 2, nothing written) or masked and reported — never a confident wrong answer."""

from __future__ import annotations

import gzip
import json
from importlib.metadata import version

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.evaluation import Truth, evaluate
from graphcal.log.drive_log import DriveLog
from graphcal.log.load import load_drive_log
from graphcal.log.validation import validate_frame
from graphcal.pipeline.configuration.settings import BatchingSettings, SegmentSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.simulate.drive import simulate_drive


def _one_line_exit_2(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _write(frame: pd.DataFrame, path, **kwargs):
    frame.to_csv(path, index=False, float_format="%.17g", **kwargs)
    return path


@pytest.fixture()
def table(drive) -> pd.DataFrame:
    return drive.measured.to_dataframe()


def test_an_absurd_position_is_refused_by_check_and_calibrate(table, tmp_path, capsys):
    table.loc[5000, "px"] = 1e30
    path = _write(table, tmp_path / "log.csv")
    err = _one_line_exit_2(["check", str(path)], capsys)
    assert "line 5002" in err and "metres of a local frame" in err
    out = tmp_path / "out"
    _one_line_exit_2(["calibrate", str(path), "--out", str(out)], capsys)
    assert not out.exists()


@pytest.mark.slow
def test_positions_in_kilometres_are_a_unit_mistake(table, tmp_path, capsys):
    table[["px", "py"]] /= 1000.0
    err = _one_line_exit_2(["check", str(_write(table, tmp_path / "log.csv"))], capsys)
    assert "the distance the wheel rotations imply" in err and "metres" in err


def test_a_repeated_column_is_named_before_pandas_renames_it(table, tmp_path, capsys):
    path = tmp_path / "log.csv"
    text = table.assign(psi_deg=np.degrees(table["psi"])).to_csv(index=False)
    path.write_text(text.replace("psi_deg", "psi", 1))  # the header names psi twice
    err = _one_line_exit_2(["check", str(path)], capsys)
    assert "column 'psi'" in err and "more than once" in err


def test_a_directory_given_as_the_log_gets_a_hint(table, tmp_path, capsys):
    _write(table, tmp_path / "drive.csv")
    err = _one_line_exit_2(["check", str(tmp_path)], capsys)
    assert "is a directory" in err and "drive.csv" in err


def test_a_semicolon_separated_file_gets_a_hint(table, tmp_path, capsys):
    path = _write(table, tmp_path / "log.csv", sep=";")
    err = _one_line_exit_2(["check", str(path)], capsys)
    assert "separated by semicolons" in err


@pytest.mark.slow
def test_gzip_data_under_a_csv_name_is_read(table, tmp_path, drive):
    path = tmp_path / "log.csv"
    path.write_bytes(gzip.compress(table.to_csv(index=False, float_format="%.17g").encode()))
    log = load_drive_log(path)
    np.testing.assert_array_equal(log.px, drive.measured.px)


def test_an_absurd_yaw_rate_threshold_is_refused_at_once(drive_csv, tmp_path, capsys):
    out = tmp_path / "out"
    err = _one_line_exit_2(
        ["calibrate", str(drive_csv), "--min-yaw-rate", "10", "--out", str(out)], capsys
    )
    assert "--min-yaw-rate 10" in err and not out.exists()  # what the user typed


def _hold_fixes(log: DriveLog, starts_s: list[float], seconds: float) -> DriveLog:
    """The receiver repeats its last fix (position and heading) during outages."""
    columns = {name: getattr(log, name).copy() for name in ("px", "py", "psi")}
    for start in starts_s:
        a = int(start / log.dt)
        b = a + int(seconds / log.dt)
        for values in columns.values():
            values[a:b] = values[a - 1]
    frame = log.to_dataframe().assign(**columns)
    return DriveLog.from_arrays(**{c: frame[c].to_numpy() for c in frame.columns})


@pytest.mark.slow
def test_frozen_fixes_are_masked_reported_and_do_not_bias_theta(drive, tmp_path):
    held = _hold_fixes(drive.measured, [60.0, 160.0, 260.0], 20.0)
    path = _write(held.to_dataframe(), tmp_path / "held.csv")
    log = load_drive_log(path)
    assert log.masked is not None and len(log.mask_notes) == 3
    assert all("frozen" in note for note in log.mask_notes)
    assert 60.0 <= log.masked.sum() * log.dt <= 62.0  # the holds and where each fix resumes
    run = run_calibration(log, method="whole")
    assert any("masked" in w and "frozen" in w for w in run.warnings)
    # What the remaining segments determine is within 3σ of the truth; the rest says so.
    error = np.abs(evaluate(run, Truth(drive.theta_true)).theta_error)
    sigma = np.sqrt(np.diag(run.covariance))
    verdicts = list(run.observability.verdicts().values())
    plainly = np.array([v == "calibrated" for v in verdicts])
    assert plainly[0] and np.all(error[plainly] < 3 * sigma[plainly]), (error, sigma, verdicts)


def test_isolated_position_spikes_are_flagged_and_jumps_masked(table, tmp_path, capsys):
    table.loc[3000:3004, "px"] += 30.0  # a multipath fix for 0.125 s, then back on track
    table.loc[6000:, "py"] += 20.0  # a jump that stays
    path = _write(table, tmp_path / "log.csv")
    log = load_drive_log(path)
    assert np.flatnonzero(log.outlying).tolist() == list(range(3000, 3005))
    assert not log.masked[2990:3010].any()  # segments keep the spike's neighbourhood
    assert log.masked[5999:6001].all() and len(log.mask_notes) == 1
    assert "spike" in log.mask_notes[0]
    assert main(["check", str(path)]) == 0
    printed = capsys.readouterr().out
    assert "1 isolated position spike(s), 5 sample(s)" in printed and "masked" in printed


def test_heading_spikes_are_masked(table, tmp_path):
    table.loc[4000:4003, "psi"] += 0.6  # the fused heading jumps by 34° for 0.1 s
    log = load_drive_log(_write(table, tmp_path / "log.csv"))
    assert log.masked[4000:4004].all() and len(log.mask_notes) == 1
    assert "heading jumps" in log.mask_notes[0]


def test_clean_drives_are_not_masked():
    for length, seed in ((4.0, 7), (2.0, 3), (6.0, 11)):
        log = simulate_drive(length_km=length, seed=seed).measured
        assert validate_frame(log.to_dataframe(), "clean").masked is None


@pytest.mark.slow
def test_a_short_drive_says_why_it_has_no_batch_study(tmp_path):
    """Too few segments for batches of 9: the one batch would be the whole-log solve again,
    so there is no batch study, said as progress, not a warning (issue 44, row 8)."""
    log = simulate_drive(length_km=1.0, seed=3).measured
    lines: list[str] = []
    run = run_calibration(log, progress=lines.append)
    assert run.batches is None and len(run.selected) < 9
    assert any("no more than one batch of 9: no batch study" in line for line in lines), lines
    assert not [w for w in run.warnings if "batch" in w], run.warnings


@pytest.mark.slow
def test_failed_step1_baseline_solves_of_the_joint_method_are_reported(drive, monkeypatch):
    import graphcal.pipeline.methods.staged as staged_module
    from graphcal.errors import CalibrationFailed

    def fail(*args, **kwargs):
        raise CalibrationFailed("batch solve failed: test")

    # The solve over all segments fails, then each batch's own (what it falls back to).
    monkeypatch.setattr(staged_module, "held_start_batches", fail)
    monkeypatch.setattr(staged_module, "calibrate_batch", fail)
    settings = Settings(segments=SegmentSettings(stride=25.0), batches=BatchingSettings(count=3))
    run = run_calibration(drive.measured, settings)
    assert any("step1: 3 of 3 batch solves" in w for w in run.warnings), run.warnings


@pytest.mark.slow
def test_calibration_json_names_the_gtsam_version(drive_csv, tmp_path):
    out = tmp_path / "out"
    assert main(["calibrate", str(drive_csv), "--out", str(out), "--batches", "0"]) == 0
    doc = json.loads((out / "calibration.json").read_text())
    assert doc["versions"]["gtsam"] == version("gtsam")
