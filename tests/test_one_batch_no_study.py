"""A default run on a drive of no more selected segments than one batch ends clean (issue 44,
row 8): the README's robot example ended in "only 4 selected segments: 1 batch of 4 instead
of 9; one batch has no spread to report" and a batch table of IQR 0.000."""

from __future__ import annotations

from pathlib import Path

from graphcal.cli import main

ROOT = Path(__file__).resolve().parents[1]
ROBOT = ROOT / "data" / "vehicles" / "mocap_robot.toml"


def test_a_robot_of_four_segments_gets_no_batch_study(tmp_path, capsys):
    robot = tmp_path / "robot"
    assert main(["simulate", "--vehicle", str(ROBOT), "--streams", str(robot)]) == 0
    capsys.readouterr()
    out = tmp_path / "results"
    args = ["calibrate", str(robot / "manifest.toml"), "--vehicle", str(ROBOT), "--out", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr()
    assert "only 4 selected segments, no more than one batch of 9: no batch study" in printed.err
    assert "warning" not in printed.out + printed.err, printed.out
    assert "iqr" not in printed.out and "recommended θ" in printed.out, printed.out
    assert not (out / "batches.csv").exists() and not (out / "parameters.png").exists()
