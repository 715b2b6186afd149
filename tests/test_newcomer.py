"""What a new user hits first (issue 26): a recording's directory, the manifest's keys, a
wrong ECU circumference, an imported synthetic log, one install hint."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from graphcal.cli import main
from graphcal.simulate.streams import simulate_streams, write_streams

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def streams_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 km recording as `graphcal simulate --streams DIR` writes it (speeds from an ECU
    that used a 2.0 m circumference)."""
    directory = tmp_path_factory.mktemp("recording")
    write_streams(simulate_streams(3.0, 2), directory)
    return directory


def test_a_directory_holding_a_manifest_is_that_recording(streams_dir, capsys):
    assert main(["check", str(streams_dir)]) == 0
    assert "valid recording" in capsys.readouterr().out


def test_import_help_manifest_prints_every_key(capsys):
    with pytest.raises(SystemExit) as exited:
        main(["import", "--help-manifest"])
    assert exited.value.code == 0
    printed = capsys.readouterr().out
    for key in ("time_offset", "heading_unit", "circumference", "yaw_rate_unit", "ticks_wrap"):
        assert key in printed


@pytest.mark.slow
def test_a_wrong_ecu_circumference_is_named(streams_dir, tmp_path, capsys):
    """Speeds the ECU computed with 2.0 m, declared as 2.2 m: c_e comes out 10 % high, and the
    result says so and names the key."""
    recording = tmp_path / "rec"
    shutil.copytree(streams_dir, recording)
    manifest = recording / "manifest.toml"
    text = manifest.read_text()
    assert "circumference = 2.0" in text
    manifest.write_text(text.replace("circumference = 2.0", "circumference = 2.2"))
    out = tmp_path / "out"
    assert main(["calibrate", str(manifest), "--method", "whole", "--out", str(out)]) == 0
    result = json.loads((out / "calibration.json").read_text())
    assert result["parameters"]["c_e"]["value"] == pytest.approx(1.985 * 1.1, rel=0.005)
    named = [w for w in result["warnings"] if "circumference" in w and "c_e" in w]
    assert named and "+9." in named[0], result["warnings"]
    assert "circumference" in capsys.readouterr().out


@pytest.mark.slow
def test_an_imported_synthetic_log_names_no_file_the_user_never_gave(streams_dir, tmp_path, capsys):
    csv = tmp_path / "drive.csv"
    assert main(["import", str(streams_dir), "--out", str(csv)]) == 0
    out = tmp_path / "out"
    assert main(["calibrate", str(csv), "--method", "whole", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "_truth.csv" not in captured.err + captured.out
    assert "theta_true" in captured.err  # the comparison with the truth still happens
    assert "true" in captured.out


def _install_hints() -> list[tuple[str, str]]:
    """Every `pip install ...` naming an extra, in the code, the README and docs."""
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    files += sorted((ROOT / "graphcal").rglob("*.py"))
    found = []
    for path in files:
        for match in re.finditer(r"pip install[^`\n]*\[\w+\][^`\n]*", path.read_text()):
            found.append((path.name, match.group(0)))
    return found


def test_every_install_hint_has_one_form():
    hints = _install_hints()
    assert len(hints) >= 5
    form = re.compile(r'pip install -e "\.\[\w+\]"')
    odd = [(name, hint) for name, hint in hints if not form.search(hint)]
    assert not odd, odd


def _one_hertz_with_late_wheels(streams_dir: Path, directory: Path, heading_in_rad: bool) -> Path:
    """The recording at 1 Hz GNSS, its wheels 1 s late; the heading column converted to rad
    (the manifest still declaring deg) when ``heading_in_rad``."""
    import numpy as np
    import pandas as pd

    shutil.copytree(streams_dir, directory)
    gnss = pd.read_csv(directory / "gnss.csv").iloc[::10].copy()
    if heading_in_rad:
        gnss["heading"] = np.deg2rad(gnss["heading"])
    gnss.to_csv(directory / "gnss.csv", index=False, float_format="%.17g")
    wheels = pd.read_csv(directory / "wheels.csv")
    wheels["t"] += 1.0
    wheels.to_csv(directory / "wheels.csv", index=False, float_format="%.17g")
    return directory


def test_a_heading_in_rad_declared_deg_is_named_not_the_wheels_units(streams_dir, tmp_path, capsys):
    """Issue 26: heading in rad declared deg, wheels 1 s late, 1 Hz GNSS gave 'implausible
    theta ... check the units of the wheel rotations, sideslip and lateral acceleration'."""
    recording = _one_hertz_with_late_wheels(streams_dir, tmp_path / "rec", heading_in_rad=True)
    assert main(["calibrate", str(recording), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert 'heading_unit = "rad"' in err and "gnss.csv" in err
    assert "wheel rotations" not in err and not (tmp_path / "out").exists()


@pytest.mark.slow
def test_late_wheels_at_one_hertz_are_found_not_blamed_on_units(streams_dir, tmp_path, capsys):
    recording = _one_hertz_with_late_wheels(streams_dir, tmp_path / "rec", heading_in_rad=False)
    out = tmp_path / "out"
    assert main(["calibrate", str(recording), "--method", "whole", "--out", str(out)]) == 0
    result = json.loads((out / "calibration.json").read_text())
    offset = result["estimated"]["time_offset"]
    assert offset["value"] == pytest.approx(1.0, abs=3 * offset["sigma"] + 0.025)
