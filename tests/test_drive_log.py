"""The drive-log format: loading, unwrapping, and one clear line per kind of bad input."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.log.drive_log import COLUMNS, DriveLogError, write_drive_log
from graphcal.log.load import load_drive_log


@pytest.fixture()
def frame(drive) -> pd.DataFrame:
    """The first 60 s of the test drive as a table (fresh copy per test)."""
    return drive.measured.to_dataframe().iloc[:2400].reset_index(drop=True)


def write(frame: pd.DataFrame, tmp_path, name: str = "log.csv"):
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def test_round_trip_preserves_values(drive, tmp_path):
    path = tmp_path / "log.csv"
    write_drive_log(drive.measured, path)
    log = load_drive_log(path)
    for column in COLUMNS:
        np.testing.assert_array_equal(getattr(log, column), getattr(drive.measured, column))
    assert log.to_dataframe().shape == (len(drive.measured), 8)


def test_extra_columns_are_ignored(frame, tmp_path):
    frame.insert(0, "gps_quality", 4)
    frame["comment"] = "ok"
    log = load_drive_log(write(frame, tmp_path))
    assert len(log) == len(frame)


def test_heading_is_unwrapped_on_load(frame, tmp_path):
    truth = np.linspace(0, 20, len(frame))  # several turns
    frame["psi"] = (truth + np.pi) % (2 * np.pi) - np.pi
    frame["n_rr"] = frame["n_rl"] + (truth[1] - truth[0]) * 1.55 / 2.0
    # the track turns with the heading (the checks compare them), on circles of the wheels'
    step = 0.5 * (frame["n_rl"] + frame["n_rr"]).to_numpy() * 2.0
    frame["px"] = np.concatenate([[0.0], np.cumsum(step * np.cos(truth))[:-1]])
    frame["py"] = np.concatenate([[0.0], np.cumsum(step * np.sin(truth))[:-1]])
    log = load_drive_log(write(frame, tmp_path))
    np.testing.assert_allclose(log.psi, truth, atol=1e-9)


def expect_error(frame, tmp_path, capsys, *fragments):
    """Library raises DriveLogError; CLI prints one line with the same text and exits 2."""
    path = write(frame, tmp_path)
    with pytest.raises(DriveLogError) as info:
        load_drive_log(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("graphcal: error: ") and message in err
    return message


def test_missing_column(frame, tmp_path, capsys):
    expect_error(frame.drop(columns=["n_rr"]), tmp_path, capsys, "missing column(s) 'n_rr'")


def test_non_numeric_value(frame, tmp_path, capsys):
    frame["ay"] = frame["ay"].astype(object)
    frame.loc[100, "ay"] = "0.3g"
    expect_error(frame, tmp_path, capsys, "column 'ay'", "line 102", "non-numeric value '0.3g'")


def test_nan_value(frame, tmp_path, capsys):
    frame.loc[50, "px"] = np.nan
    expect_error(frame, tmp_path, capsys, "column 'px'", "line 52", "nan")


def test_infinite_value(frame, tmp_path, capsys):
    frame.loc[70, "beta"] = np.inf
    expect_error(frame, tmp_path, capsys, "column 'beta'", "line 72", "inf")


def test_time_not_increasing(frame, tmp_path, capsys):
    frame.loc[300, "t"] = frame.loc[299, "t"]
    expect_error(frame, tmp_path, capsys, "column 't'", "line 302", "time does not increase")


def test_time_stepping_back_by_a_microsecond_prints_two_different_times(frame, tmp_path, capsys):
    """Issue 26 row H: Unix times (1.76e9 s) written with every digit, so a step back of a
    microsecond does not read "1.76385611e+09 then 1.76385611e+09"; both lines named."""
    frame["t"] += 1763856110.0
    frame.loc[300, "t"] = frame.loc[299, "t"] - 1e-6
    frame["t"] = frame["t"].map(repr)  # every digit in the file
    before, after = frame.loc[299, "t"], frame.loc[300, "t"]
    message = expect_error(frame, tmp_path, capsys, "column 't'", "line 302", "on line 301")
    assert f"time does not increase ({after} s after {before} s on line 301)" in message
    assert before != after


def test_time_not_uniform(frame, tmp_path, capsys):
    frame.loc[500:, "t"] += 0.1  # a 100 ms gap
    expect_error(frame, tmp_path, capsys, "column 't'", "line 502", "non-uniform sampling")


def test_heading_in_degrees_with_wraps(frame, tmp_path, capsys):
    degrees = np.rad2deg(np.linspace(0, 12, len(frame)))
    frame["psi"] = (degrees + 180) % 360 - 180
    expect_error(frame, tmp_path, capsys, "column 'psi'", "degrees", "radians")


def test_heading_in_degrees_without_wraps(drive, tmp_path, capsys):
    frame = drive.measured.to_dataframe().iloc[:8000].reset_index(drop=True)
    frame["psi"] = np.rad2deg(frame["psi"] - frame["psi"].iloc[0])
    assert frame["psi"].diff().abs().max() < 180  # no wrap-around jump for the first check
    expect_error(frame, tmp_path, capsys, "column 'psi'", "apparently degrees")


def test_negative_wheel_rotation(frame, tmp_path, capsys):
    frame.loc[900, "n_rl"] = -0.05
    expect_error(frame, tmp_path, capsys, "column 'n_rl'", "line 902", "negative wheel rotation")


@pytest.mark.slow
def test_cumulative_wheel_rotation_is_implausible(frame, tmp_path, capsys):
    frame["n_rr"] = frame["n_rr"].cumsum()
    message = expect_error(frame, tmp_path, capsys, "column 'n_rr'", "implausible wheel rotation")
    assert "cumulative" in message


def test_log_too_short_for_one_segment(frame, tmp_path, capsys):
    path = write(frame.iloc[:200], tmp_path)  # ~50 m
    with pytest.raises(DriveLogError, match=r"shorter than one 150 m segment"):
        load_drive_log(path, min_distance=150.0)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "shorter than one 150 m segment" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_missing_file(tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.csv")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_not_a_csv(tmp_path, capsys):
    path = tmp_path / "log.csv"
    path.write_bytes(b"\x00\x01\x02binary\xff\xfe")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("graphcal: error: ") and "Traceback" not in err


def test_repeated_column_after_stripping_spaces(frame, tmp_path, capsys):
    frame["t "] = frame["t"]
    expect_error(frame, tmp_path, capsys, "column 't'", "more than once")


def test_trailing_comma_on_data_rows_keeps_the_columns(frame, tmp_path):
    path = tmp_path / "log.csv"
    body = frame.to_csv(index=False, float_format="%.17g").splitlines()
    path.write_text("\n".join([body[0]] + [row + "," for row in body[1:]]) + "\n")
    log = load_drive_log(path)
    np.testing.assert_array_equal(log.t, frame["t"].to_numpy())


def test_time_in_nanoseconds(frame, tmp_path, capsys):
    frame["t"] = (frame["t"] * 1e9).round()
    expect_error(frame, tmp_path, capsys, "column 't'", "not plausible in seconds")


def test_sampling_jitter_is_accepted(frame, tmp_path):
    jitter = np.random.default_rng(0).uniform(-0.002, 0.002, len(frame))
    frame["t"] = frame["t"] + jitter
    assert len(load_drive_log(write(frame, tmp_path))) == len(frame)


def test_sideslip_in_degrees(frame, tmp_path, capsys):
    frame["beta"] = np.rad2deg(frame["beta"]) + 5.0
    expect_error(frame, tmp_path, capsys, "column 'beta'", "implausible value", "radians")


def test_lateral_acceleration_in_g_times_100(frame, tmp_path, capsys):
    frame.loc[40, "ay"] = 250.0
    expect_error(frame, tmp_path, capsys, "column 'ay'", "line 42", "m/s²")


def test_unrelated_json_next_to_the_log_is_not_a_sidecar(drive, tmp_path, capsys):
    from graphcal.simulate.drive import read_sidecar

    path = tmp_path / "log.csv"
    write_drive_log(drive.measured, path)
    for text in ("{not json", '{"seed": 1}', '{"generator": "other", "theta_true": {}}'):
        (tmp_path / "log.json").write_text(text)
        assert read_sidecar(path) is None
    assert main(["check", str(path)]) == 0


def test_sparse_fixes_round_trip_through_the_csv(tmp_path):
    """Rows without a fix leave px, py empty, rows without a heading psi; a fix between rows
    keeps its time in t_fix: written and read back, the same measurements at the same times."""
    from graphcal.simulate.defects import degrade, parse_defects
    from graphcal.simulate.drive import simulate_drive

    sparse = degrade(simulate_drive(1.0, seed=2), parse_defects("gnss10hz"), seed=3).measured
    path = tmp_path / "sparse.csv"
    write_drive_log(sparse, path)
    frame = pd.read_csv(path)
    assert frame["px"].isna().mean() == pytest.approx(0.75, abs=0.01)
    assert "t_fix" in frame.columns
    back = load_drive_log(path)
    np.testing.assert_array_equal(back.measured, sparse.measured)
    np.testing.assert_allclose(back.fix_lag, sparse.fix_lag, atol=1e-9)
    fixes = back.position_measured
    np.testing.assert_array_equal(back.px[fixes], sparse.px[fixes])


@pytest.mark.parametrize(
    "change, column, what",
    [
        ({"py": ""}, "py", "empty where the other coordinate is given"),
        ({"t_fix": "0.2"}, "t_fix", "not after the previous row's t"),
    ],
)
def test_sparse_fix_mistakes_are_one_line(tmp_path, change, column, what):
    rows = ["t,px,py,psi,n_rl,n_rr,beta,ay,t_fix"]
    for k in range(300):
        t = 0.025 * k
        fix = k % 4 == 0
        cells = [f"{t:.3f}", f"{0.5 * k:.3f}" if fix else "", "0" if fix else "", ""]
        cells += ["0.1", "0.1", "0", "0", f"{t - 0.01:.3f}" if fix and k else ""]
        rows.append(",".join(cells))
    line = 4 * 10 + 1  # row k = 40, a fix row
    cells = rows[line].split(",")
    names = rows[0].split(",")
    for name, value in change.items():
        cells[names.index(name)] = value
    rows[line] = ",".join(cells)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(DriveLogError, match=what) as raised:
        load_drive_log(path)
    message = str(raised.value)
    assert f"column '{column}', line {line + 1}" in message and "\n" not in message


def test_check_says_what_a_sparse_log_measures(tmp_path, capsys):
    from graphcal.simulate.defects import degrade, parse_defects
    from graphcal.simulate.drive import simulate_drive

    sparse = degrade(simulate_drive(1.0, seed=2), parse_defects("gnss10hz=1"), seed=3).measured
    path = tmp_path / "sparse.csv"
    write_drive_log(sparse, path)
    assert main(["check", str(path)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "measurements" in x)
    assert "position fixes (1.0 Hz)" in line and "taken between rows" in line
