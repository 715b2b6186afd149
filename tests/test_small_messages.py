"""Issue 44, row 13: the small things a new user hit, each said plainly and before work."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.cli import main
from graphcal.pipeline.methods.prepare import _with_heading_noise
from graphcal.progress import reporting_to

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"
CAN_MANIFEST = ROOT / "data" / "real" / "comma2k19" / "can.toml"


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_import_out_named_as_a_directory_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["import", str(CAN_MANIFEST), "--out", "newdir/"]) == 2
    assert "--out newdir/: names a directory" in _error(capsys)
    assert list(tmp_path.iterdir()) == []  # wrote 'newdir' and 'newdir.json' before


def test_import_out_where_nothing_can_be_written_is_refused_before_the_import(capsys):
    assert main(["import", str(CAN_MANIFEST), "--out", "/proc/x.csv"]) == 2
    err = _error(capsys)
    assert err.startswith("graphcal: error: --out /proc/x.csv: cannot write in /proc"), err
    assert ".tmp" not in err


def test_wheel_rotations_in_radians_are_named(tmp_path, capsys):
    frame = pd.read_csv(SAMPLE)
    frame[["n_rl", "n_rr"]] *= 2 * np.pi
    frame.to_csv(tmp_path / "rad.csv", index=False)
    assert main(["check", str(tmp_path / "rad.csv")]) == 2
    assert "not in radians or degrees" in _error(capsys)


def test_a_time_gap_names_the_masked_column(tmp_path, capsys):
    pd.read_csv(SAMPLE).drop(index=range(1000, 1100)).to_csv(tmp_path / "gap.csv", index=False)
    assert main(["check", str(tmp_path / "gap.csv")]) == 2
    err = _error(capsys)
    assert "masked = 1" in err and "separate logs" not in err, err


def test_simulate_help_says_when_out_is_required(capsys):
    try:
        main(["simulate", "--help"])
    except SystemExit:
        pass
    out = " ".join(capsys.readouterr().out.split())
    assert "required unless --streams DIR or --fleet DIR" in out


def test_help_manifest_is_plain_text(capsys):
    try:
        main(["import", "--help-manifest"])
    except SystemExit:
        pass
    out = capsys.readouterr().out
    assert "``" not in out and ":mod:" not in out and "::\n" not in out
    assert "time_unit and time_offset exist in every section" in out


def test_the_heading_weight_has_three_figures():
    import graphcal

    log = graphcal.load_drive_log(SAMPLE)
    lines: list[str] = []
    with reporting_to(lines.append):
        _with_heading_noise(log, graphcal.Settings())
    assert lines and lines[0].endswith("heading weight 57.6"), lines
