"""``graphcal check`` refuses a log calibrate would refuse (issue 44, row 7): a 50-row 4.8 m
log and a parked 0 m log were a "valid drive log" (the parked one then a traceback in
calibrate)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from graphcal.cli import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"


def _short(tmp_path: Path) -> Path:
    path = tmp_path / "short.csv"
    pd.read_csv(SAMPLE, nrows=50).to_csv(path, index=False)
    return path


def _parked(tmp_path: Path) -> Path:
    frame = pd.read_csv(SAMPLE, nrows=400)
    for column in ("n_rl", "n_rr", "beta", "ay"):
        frame[column] = 0.0
    for column in ("px", "py", "psi"):
        frame[column] = frame[column].iloc[0]
    path = tmp_path / "parked.csv"
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize(("make", "metres"), [(_short, "4.8"), (_parked, "0.0")])
def test_check_and_calibrate_refuse_a_log_shorter_than_a_segment(tmp_path, capsys, make, metres):
    log = make(tmp_path)
    said = []
    for command in (["check", str(log)], ["calibrate", str(log), "--out", str(tmp_path / "r")]):
        assert main(command) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        said.append(err)
    assert said[0] == said[1], said
    assert f"log covers only {metres} m, shorter than one 150 m segment" in said[0]
    assert not (tmp_path / "r").exists()
