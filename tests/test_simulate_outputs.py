"""``graphcal simulate`` never overwrites a file graphcal did not write (issue 44, row 5):
``--out mine.csv`` and ``--streams DIR`` onto a user's own ``gnss.csv`` were overwritten."""

from __future__ import annotations

import pytest

from graphcal.cli import main


def _one_line(err: str, expected: str) -> None:
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err, err


def test_out_onto_a_users_csv_is_refused(tmp_path, capsys):
    mine = tmp_path / "mine.csv"
    mine.write_text("my,data\n")
    assert main(["simulate", "--length-km", "0.3", "--out", str(mine)]) == 2
    _one_line(capsys.readouterr().err, "would overwrite a file graphcal did not write")
    assert mine.read_text() == "my,data\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.csv"]


def test_out_replaces_its_own_drive(tmp_path):
    out = tmp_path / "drive.csv"
    assert main(["simulate", "--length-km", "0.3", "--out", str(out)]) == 0
    assert main(["simulate", "--length-km", "0.3", "--seed", "1", "--out", str(out)]) == 0


def test_streams_onto_a_users_files_are_refused(tmp_path, capsys):
    streams = tmp_path / "rec"
    streams.mkdir()
    (streams / "gnss.csv").write_text("mine\n")
    assert main(["simulate", "--length-km", "0.3", "--streams", str(streams)]) == 2
    _one_line(capsys.readouterr().err, "holds files graphcal did not write")
    assert [p.name for p in streams.iterdir()] == ["gnss.csv"]
    assert (streams / "gnss.csv").read_text() == "mine\n"


def test_streams_replace_their_own_recording(tmp_path):
    streams = tmp_path / "rec"
    assert main(["simulate", "--length-km", "0.3", "--streams", str(streams)]) == 0
    assert main(["simulate", "--length-km", "0.3", "--streams", str(streams)]) == 0


def test_a_fleet_onto_a_users_directory_is_refused(tmp_path, capsys):
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    (fleet / "notes.txt").write_text("mine\n")
    args = ["simulate", "--fleet", str(fleet), "--vehicles", "1", "--days", "1"]
    assert main([*args, "--change", "none", "--length-km", "0.3"]) == 2
    _one_line(capsys.readouterr().err, "holds files graphcal did not write")


def test_an_interrupted_synthetic_drive_leaves_no_file(tmp_path, monkeypatch):
    # Ctrl-C after the drive's CSV but before its truth (the interrupt stress script hit it
    # at 3 s into `simulate --length-km 30`): the CSV written alone is removed.
    from graphcal.simulate import drive as drive_module

    drive = drive_module.simulate_drive(0.3, seed=1)
    calls = []

    def write(log, path):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        original(log, path)

    original = drive_module.write_drive_log
    monkeypatch.setattr(drive_module, "write_drive_log", write)
    with pytest.raises(KeyboardInterrupt):
        drive_module.write_synthetic_drive(drive, tmp_path / "drive.csv")
    assert list(tmp_path.iterdir()) == []
