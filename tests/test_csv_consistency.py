"""A drive-log CSV's columns checked against each other in its turns, as an import checks its
streams: swapped wheels, swapped positions, a heading of the other sign and a lateral
acceleration in g are one line naming the columns, exit 2, in ``check`` and ``calibrate``;
valid logs, also those that hardly turn, pass."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.log.validation import validate_frame
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


@pytest.mark.parametrize(("column", "scale"), [("n_rl", 1.5), ("n_rr", 0.9)])
def test_one_wheel_off_scale_is_named_not_called_swapped(city, tmp_path, capsys, column, scale):
    # A left wheel 1.5x turns the wheels right in most turns: it read as swapped wheels.
    frame = city.assign(**{column: city[column] * scale})
    error = check_error(frame, tmp_path, capsys, f"column '{column}'", f"{column}'s scale is off")
    travels = float(re.search(rf"{column} travels ([0-9.]+)x its distance", error).group(1))
    assert travels == pytest.approx(scale, rel=0.02)  # nominal c_e 2 m, the drive's 1.985 m
    assert "swapped" not in error


@pytest.mark.parametrize("degrees", [30.0, 180.0])
def test_a_heading_off_the_direction_of_travel_is_named(city, tmp_path, capsys, degrees):
    # 180° off: the differences split at ±π, whose plain median read +172°
    frame = city.assign(psi=city["psi"] + np.radians(degrees))
    error = check_error(frame, tmp_path, capsys, "column 'psi'", "on average", "zero")
    assert f"by {np.degrees(np.angle(np.exp(1j * np.radians(degrees)))):+.0f}°" in error


def test_a_heading_flipped_over_a_span_is_named_with_the_span(city, tmp_path, capsys):
    # A heading off by 180° for the middle third: masked at its two jumps, the span between
    # ran 22 s of solves on the sample drive and exited blaming the wheels' units.
    t = city["t"].to_numpy()
    a, b = t[-1] / 3, 2 * t[-1] / 3
    middle = (t >= a) & (t < b)
    frame = city.assign(psi=np.where(middle, city["psi"] + np.pi, city["psi"]))
    error = check_error(frame, tmp_path, capsys, "column 'psi'", "away from the direction")
    start, end = map(float, re.search(r"from t = ([0-9.]+) s to ([0-9.]+) s", error).groups())
    assert abs(start - a) < 5.0 and abs(end - b) < 5.0
    assert "180°" in error


def test_a_small_constant_heading_offset_passes(city, tmp_path, capsys):
    # a mounting offset of a few degrees is the model's to carry, not a data error
    path = tmp_path / "offset.csv"
    city.assign(psi=city["psi"] + np.radians(5.0)).to_csv(path, index=False)
    assert main(["check", str(path)]) == 0


def test_a_lateral_acceleration_of_the_other_sign_is_named(city, tmp_path, capsys):
    # the sample drive calibrated with exit 0 before, d -1.55 where its truth is +1.50
    check_error(
        city.assign(ay=-city["ay"]), tmp_path, capsys, "column 'ay'", "other sign", "negate"
    )


def test_axes_scaled_differently_are_named(city, tmp_path, capsys):
    # x 1.3x y (longitude without cos(latitude)): "calibrated" c_e 2.2885 m (truth 1.985)
    error = check_error(city.assign(px=city["px"] * 1.3), tmp_path, capsys, "scaled differently")
    stretch = float(re.search(r"is ([0-9.]+)x as long", error).group(1))
    assert stretch == pytest.approx(1.3, rel=0.03)
    assert "cos(latitude)" in error


def test_wheels_that_never_turn_the_vehicle_are_named(city, tmp_path, capsys):
    # n_rr a copy of n_rl: 32 s of solves, then exit 3 with nothing named
    error = check_error(city.assign(n_rr=city["n_rl"]), tmp_path, capsys, "barely turn")
    assert "equal in 100% of the rows" in error


def _cruise(speed: np.ndarray, rotation: float) -> pd.DataFrame:
    """A straight drive at ``speed`` [m/s] per 40 Hz row, fixes of 0.2 m, both wheels
    reporting ``rotation`` [rev] every row."""
    n, dt = len(speed), 0.025
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] * dt)])
    noise = np.random.default_rng(0).normal(0.0, 0.2, (2, n))
    rows = {"t": np.arange(n) * dt, "px": x + noise[0], "py": noise[1], "psi": np.zeros(n)}
    rows |= {"n_rl": np.full(n, rotation), "n_rr": np.full(n, rotation)}
    return pd.DataFrame(rows | {"beta": np.zeros(n), "ay": np.zeros(n)})


def test_frozen_wheels_are_masked_and_tick_counts_repeating_in_a_cruise_are_not():
    # Both wheels repeating one value while the vehicle speeds up from 12.5 to 20 m/s: a
    # stale message (the sample drive's middle third frozen ran 48 s of solves, exit 3).
    cruise, rotation = np.full(3600, 12.5), 12.5 * 0.025 / 2.0  # 90 s, tick counts alike
    log = validate_frame(_cruise(cruise, rotation), "cruise.csv")
    assert log.masked is None or not log.masked.any()
    speeding_up = np.concatenate([cruise, np.linspace(12.5, 20.0, 1200)])  # then 30 s
    stale = validate_frame(_cruise(speeding_up, rotation), "stale.csv")
    assert not stale.masked[:3900].any() and stale.masked[4100:4700].all()  # 15 m/s at 4000
    assert any("wheels frozen" in note for note in stale.mask_notes)


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
