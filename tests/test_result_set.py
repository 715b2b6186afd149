"""Results are a set: the output place is checked before the run and replaced whole at its end."""

from __future__ import annotations

import json

import pytest

import graphcal.pipeline.end_to_end.run
import graphcal.report.results
from graphcal.cli import main
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration


@pytest.fixture()
def no_calibration(monkeypatch):
    """Fail the test if a calibration starts: the error must come before it."""

    def refuse(*args, **kwargs):
        raise AssertionError("the calibration ran before the output place was checked")

    monkeypatch.setattr(graphcal.pipeline.end_to_end.run, "run_calibration", refuse)


def _bad_out(drive_csv, out, capsys) -> str:
    assert main(["calibrate", str(drive_csv), "--out", str(out), "--batches", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


def test_an_existing_file_as_out_is_refused_before_the_run(
    drive_csv, tmp_path, capsys, no_calibration
):
    out = tmp_path / "results"
    out.write_text("my notes\n")
    assert "exists and is not a directory" in _bad_out(drive_csv, out, capsys)
    assert out.read_text() == "my notes\n"


def test_an_unwritable_place_is_refused_before_the_run(drive_csv, tmp_path, capsys, no_calibration):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    assert "is not a directory" in _bad_out(drive_csv, blocker / "results", capsys)


def test_a_directory_with_other_files_is_refused_and_left_alone(
    drive_csv, tmp_path, capsys, no_calibration
):
    out = tmp_path / "home"
    out.mkdir()
    (out / "thesis.tex").write_text("precious")
    err = _bad_out(drive_csv, out, capsys)
    assert "thesis.tex" in err and "graphcal did not write" in err
    assert [p.name for p in out.iterdir()] == ["thesis.tex"]


@pytest.mark.slow
def test_an_earlier_result_set_is_replaced_whole(drive_csv, tmp_path, capsys):
    out = tmp_path / "results"
    out.mkdir()
    (out / "calibration.json").write_text('{"method": "staged", "versions": {"graphcal": "0.1.0"}}')
    (out / "wheel_rotations.png").write_bytes(b"staged figure")
    (out / "batches.csv").write_text("batch\n0\n")
    assert main(["calibrate", str(drive_csv), "--out", str(out), "--batches", "0"]) == 0
    names = {p.name for p in out.iterdir()}
    assert "wheel_rotations.png" not in names and "batches.csv" not in names  # not this run's
    assert json.loads((out / "calibration.json").read_text())["method"] == "whole"
    assert [p.name for p in tmp_path.iterdir()] == ["results"]  # no staging left behind


@pytest.mark.slow
def test_an_interrupted_write_leaves_the_earlier_set(drive, tmp_path, monkeypatch):
    out = tmp_path / "results"
    whole = run_calibration(drive.measured, method="whole")
    graphcal.report.results.write_results(whole, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    # A different run (with batches: more files) is interrupted while it writes its figures.
    joint = run_calibration(drive.measured, Settings(batches=BatchingSettings(count=2)))
    real = graphcal.report.results.atomic_write_chunks  # how each figure's PNG is written
    calls = {"n": 0}

    def interrupted(path, chunks):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real(path, chunks)

    monkeypatch.setattr(graphcal.report.results, "atomic_write_chunks", interrupted)
    with pytest.raises(KeyboardInterrupt):
        graphcal.report.results.write_results(joint, out)
    assert calls["n"] == 4  # it was interrupted mid-set, after some new files existed
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # no mix
    assert [p.name for p in tmp_path.iterdir()] == ["results"]


def test_a_foreign_calibration_json_is_not_taken_for_a_result_set(
    drive_csv, tmp_path, capsys, no_calibration
):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "calibration.json").write_text('{"my_vehicle": "van 7"}')
    (out / "validation.csv").write_text("my notes\n")
    assert "did not write" in _bad_out(drive_csv, out, capsys)
    assert (out / "calibration.json").read_text() == '{"my_vehicle": "van 7"}'


def test_the_working_directory_is_not_replaced(
    drive_csv, tmp_path, capsys, monkeypatch, no_calibration
):
    monkeypatch.chdir(tmp_path)
    assert "working directory" in _bad_out(drive_csv, ".", capsys)
