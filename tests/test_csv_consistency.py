"""A drive-log CSV's columns checked against each other in its turns, as an import checks its
streams: swapped wheels, swapped positions, a heading of the other sign and a lateral
acceleration in g are one line naming the columns, exit 2, in ``check`` and ``calibrate``;
valid logs, also those that hardly turn, pass."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.simulate.drive import simulate_drive

ROOT = Path(__file__).resolve().parents[1]
#: g as the manipulated log divides by.
STANDARD_GRAVITY = 9.80665


@pytest.fixture(scope="module")
def city() -> pd.DataFrame:
    """A 1.5 km city drive (about 50 clear turns) as a drive-log table."""
    return simulate_drive(length_km=1.5, seed=1).measured.to_dataframe()


def exchanged(frame: pd.DataFrame, a: str, b: str) -> pd.DataFrame:
    """``frame`` with the columns ``a`` and ``b`` exchanged."""
    changed = frame.copy()
    changed[[a, b]] = frame[[b, a]].to_numpy()
    return changed


def check_error(frame: pd.DataFrame, tmp_path, capsys, *fragments: str) -> str:
    """``graphcal check`` of ``frame`` as a CSV exits 2 with one line holding ``fragments``."""
    path = tmp_path / "log.csv"
    frame.to_csv(path, index=False)
    assert main(["check", str(path)]) == 2
    captured = capsys.readouterr()
    assert "valid drive log" not in captured.out
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert captured.err.startswith(f"graphcal: error: {path}: ")
    for fragment in fragments:
        assert fragment in captured.err
    return captured.err


def test_swapped_wheels_are_named(city, tmp_path, capsys):
    check_error(
        exchanged(city, "n_rl", "n_rr"),
        tmp_path,
        capsys,
        "n_rl and n_rr look swapped",
        "opposite to the heading (psi) and the track (px, py)",
        "exchange the two columns",
    )


def test_swapped_positions_are_named(city, tmp_path, capsys):
    check_error(
        exchanged(city, "px", "py"),
        tmp_path,
        capsys,
        "px and py look swapped",
        "mirrored track",
        "exchange the two columns",
    )


def test_swapped_positions_without_a_heading_name_both_pairs(city, tmp_path, capsys):
    frame = exchanged(city, "px", "py").assign(psi=np.nan)
    check_error(frame, tmp_path, capsys, "px and py look swapped, or n_rl and n_rr")


def test_heading_of_the_other_sign_is_named(city, tmp_path, capsys):
    check_error(
        city.assign(psi=-city["psi"]),
        tmp_path,
        capsys,
        "column 'psi'",
        "the heading turns opposite to the wheels (n_rl, n_rr) and the track",
        "negate the column",
    )


def test_lateral_acceleration_in_g_is_named(city, tmp_path, capsys):
    check_error(
        city.assign(ay=city["ay"] / STANDARD_GRAVITY),
        tmp_path,
        capsys,
        "column 'ay'",
        "apparently in g",
        "multiply the column by 9.81",
    )


def test_calibrate_stops_at_the_same_line_and_writes_nothing(city, tmp_path, capsys):
    path = tmp_path / "log.csv"
    exchanged(city, "n_rl", "n_rr").to_csv(path, index=False)
    out = tmp_path / "results"
    assert main(["calibrate", str(path), "--out", str(out)]) == 2
    assert "n_rl and n_rr look swapped" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "log",
    [
        "data/sample_drive.csv",
        "data/real/comma2k19/drive.csv",  # a highway that barely turns: nothing to judge
    ],
)
def test_valid_logs_pass(log, capsys):
    assert main(["check", str(ROOT / log)]) == 0
    assert "valid drive log" in capsys.readouterr().out


def test_a_valid_simulated_drive_and_one_without_a_lateral_acceleration_pass(
    city, tmp_path, capsys
):
    for name, frame in (("city.csv", city), ("no_ay.csv", city.assign(ay=0.0))):
        frame.to_csv(tmp_path / name, index=False)
        assert main(["check", str(tmp_path / name)]) == 0
    assert capsys.readouterr().err == ""
