"""Issue 26: what an imported recording is refused for, said in the user's terms.

Every message names the stream's file and line (a bag's topic and message number), the
user's column with the manifest key that declared it, and the key to change; never a
drive-log column (``ay``, ``psi``, ``n_rl``) or row the user did not write. Each test runs
the command a user runs on a recording of ``graphcal simulate --streams`` edited the way a
real one goes wrong.
"""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.simulate.streams import simulate_streams, write_streams


@pytest.fixture(scope="module")
def streams_dir(tmp_path_factory):
    """A 4 km synthetic recording (seed 1): gnss.csv, wheels.csv, imu.csv, manifest.toml."""
    directory = tmp_path_factory.mktemp("streams")
    write_streams(simulate_streams(4.0, 1), directory)
    return directory


@pytest.fixture()
def recording(streams_dir, tmp_path):
    """A private copy of the recording, to edit."""
    shutil.copytree(streams_dir, tmp_path / "rec")
    return tmp_path / "rec"


def _edit(path, old: str, new: str, count: int = -1) -> None:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, count))


def _change(path, column: str, change) -> None:
    """Rewrite one column of a stream's CSV (times kept with every digit)."""
    frame = pd.read_csv(path)
    frame[column] = change(frame[column].to_numpy(dtype=float))
    frame.to_csv(path, index=False, float_format="%.17g")


def _refused(recording, tmp_path, capsys) -> str:
    """``graphcal calibrate rec/manifest.toml``: exit 2, one line, nothing written."""
    out = tmp_path / "result"
    assert main(["calibrate", str(recording / "manifest.toml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()
    assert "manifest.toml" not in err, err  # the stream's file, not the manifest's lines
    return err


def _no_drive_log_terms(err: str, *own: str) -> None:
    """No drive-log column (but the user's ``own`` columns of the same name) and no sample
    number in ``err``."""
    for column in ("ay", "psi", "n_rl", "n_rr", "beta"):
        assert column in own or f"'{column}'" not in err, (column, err)
    assert "sample " not in err, err


# --- row F: units, in the stream's own terms --------------------------------------------------


@pytest.mark.slow
def test_a_yaw_rate_in_deg_s_declared_rad_s_names_the_column_and_the_key(
    recording, tmp_path, capsys
):
    """The issue's case: no lateral acceleration logged, so the drive log's would be speed ×
    the yaw rate; the yaw rate logged in deg/s but declared rad/s."""
    _edit(recording / "manifest.toml", 'lateral_acceleration = "ay"\n', "")
    _edit(
        recording / "manifest.toml", 'yaw_rate = "wz"', 'yaw_rate = "wz"\nyaw_rate_unit = "rad/s"'
    )
    _change(recording / "imu.csv", "wz", np.degrees)
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'imu.csv'}: column 'wz' ([imu] yaw_rate" in err, err
    ratio = float(err.split("x as much as the GNSS track")[0].rsplit(" ", 1)[1])
    assert 54 < ratio < 60, err  # 180/π = 57.3, give or take the sideslip's change
    assert 'set [imu] yaw_rate_unit = "deg/s"' in err, err
    _no_drive_log_terms(err)


@pytest.mark.parametrize(
    ("declared", "convert", "key"),
    [
        ('heading_unit = "rad"', None, 'set [gnss] heading_unit = "deg"'),  # degrees as rad
        ('heading_unit = "deg"', np.radians, 'set [gnss] heading_unit = "rad"'),  # rad as deg
    ],
)
def test_a_heading_in_the_other_angle_unit_names_the_column_and_the_key(
    recording, tmp_path, capsys, declared, convert, key
):
    _edit(recording / "manifest.toml", 'heading_unit = "deg"', declared)
    if convert is not None:
        _change(recording / "gnss.csv", "heading", convert)
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'gnss.csv'}: column 'heading' ([gnss] heading, {declared}" in err, err
    assert "line " in err and key in err, err
    _no_drive_log_terms(err)


def test_wheel_speeds_in_km_h_declared_m_s_name_the_columns_and_the_unit_to_set(
    recording, tmp_path, capsys
):
    for column in ("rl", "rr"):
        _change(recording / "wheels.csv", column, lambda v: 3.6 * v)
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'wheels.csv'}: columns 'rl', 'rr' ([wheels] rear_left, rear_right" in err
    assert 'speed_unit = "m/s" by default' not in err and 'speed_unit = "m/s"' in err, err
    assert 'set [wheels] speed_unit = "km/h"' in err, err
    _no_drive_log_terms(err)


def test_a_wrong_ecu_circumference_names_the_value_as_declared(recording, tmp_path, capsys):
    _edit(recording / "manifest.toml", "circumference = 2.0", "circumference = 0.2")
    err = _refused(recording, tmp_path, capsys)
    assert "columns 'rl', 'rr'" in err and "circumference = 0.2 m" in err, err
    assert "travel 10.1x the distance of the GNSS track" in err, err
    assert "check [wheels] circumference (2.0" in err and "m would match the GNSS track" in err


def test_a_lateral_acceleration_in_g_is_refused_with_the_column(recording, tmp_path, capsys):
    _change(recording / "imu.csv", "ay", lambda v: v / 9.80665)
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'imu.csv'}: column 'ay' ([imu] lateral_acceleration" in err, err
    assert "apparently in g: multiply the column by 9.81" in err, err


# --- issue 35: times in another unit than declared, named before any other check -------


@pytest.mark.parametrize(
    ("declared", "read_as"),
    [('time_unit = "us"', "read as 100 us"), (None, "read as 100 s")],
)
@pytest.mark.slow
def test_times_in_ms_declared_otherwise_name_the_unit_to_set(
    recording, tmp_path, capsys, declared, read_as
):
    """Every stream's times in ms, declared us or left at the default s: the first stream read
    (the GNSS, at 10 Hz) names its file, the unit its interval fits and the key to set, not
    an implausible acceleration or a wheel circumference."""
    for name in ("gnss.csv", "wheels.csv", "imu.csv"):
        _change(recording / name, "t", lambda t: 1000.0 * t)
    if declared is not None:
        _edit(recording / "manifest.toml", 'time = "t"\n', f'time = "t"\n{declared}\n')
    err = _refused(recording, tmp_path, capsys)
    assert f"the times of {recording / 'gnss.csv'} look like ms (median interval 100 ms " in err
    assert read_as in err and 'set time_unit = "ms" in [gnss]' in err, err
    assert "lateral acceleration" not in err and "circumference" not in err, err


def test_times_in_ms_of_one_stream_name_that_stream(recording, tmp_path, capsys):
    """Only the wheels' times in ms (at 100 Hz: 10 ms read as 10 s): their file and section."""
    _change(recording / "wheels.csv", "t", lambda t: 1000.0 * t)
    err = _refused(recording, tmp_path, capsys)
    assert f"the times of {recording / 'wheels.csv'} look like ms" in err, err
    assert "(median interval 10 ms read as 10 s, " in err, err
    assert 'set time_unit = "ms" in [wheels]' in err, err


def _thinned_to_1_hz(recording, seed: int = 0) -> None:
    """Every 10th fix of gnss.csv, stamped with ±2 ms of jitter (a 1 Hz receiver, times in s)."""
    frame = pd.read_csv(recording / "gnss.csv").iloc[::10].reset_index(drop=True)
    frame["t"] += np.random.default_rng(seed).uniform(-0.002, 0.002, len(frame))
    frame.to_csv(recording / "gnss.csv", index=False, float_format="%.17g")


@pytest.mark.parametrize("seed", [1, 2])
def test_a_1_hz_receiver_stamped_in_seconds_imports(recording, tmp_path, capsys, seed):
    """The most common receiver: a median interval just over 1 s is no reason to read ms."""
    _thinned_to_1_hz(recording, seed)
    assert np.median(np.diff(pd.read_csv(recording / "gnss.csv")["t"])) > 1.0
    out = tmp_path / "drive.csv"
    assert main(["import", str(recording / "manifest.toml"), "--out", str(out)]) == 0, (
        capsys.readouterr().err
    )
    assert out.is_file()


def test_a_1_hz_receiver_declared_in_ms_is_told_to_say_s(recording, tmp_path, capsys):
    """1 s intervals declared ms read as a 1 kHz stream: only the spans tell, 1000x shorter
    than the wheels' and the IMU's."""
    _thinned_to_1_hz(recording)
    _edit(recording / "manifest.toml", 'time = "t"\n', 'time = "t"\ntime_unit = "ms"\n', 1)
    err = _refused(recording, tmp_path, capsys)
    assert f"the times of {recording / 'gnss.csv'} look like s (they span " in err, err
    assert 'set time_unit = "s" in [gnss]' in err, err


def test_a_500_hz_imu_in_ms_read_as_s_names_the_imu(recording, tmp_path, capsys):
    """2 ms intervals read as 2 s are a plausible 0.5 Hz rate; the IMU's span, 1000x the
    other streams', names the unit."""
    frame = pd.read_csv(recording / "imu.csv")
    t = np.arange(frame["t"].iloc[0], frame["t"].iloc[-1], 0.002)
    fine = pd.DataFrame({c: np.interp(t, frame["t"], frame[c]) for c in frame.columns})
    fine["t"] = 1000.0 * t
    fine.to_csv(recording / "imu.csv", index=False, float_format="%.17g")
    err = _refused(recording, tmp_path, capsys)
    assert f"the times of {recording / 'imu.csv'} look like ms (they span " in err, err
    assert 'set time_unit = "ms" in [imu]' in err, err


# --- row F: the drive log's own checks, traced back to the streams ------------------------


def test_a_lateral_acceleration_spike_names_the_imu_line(recording, tmp_path, capsys):
    _change(recording / "imu.csv", "ay", lambda v: np.where(np.arange(len(v)) == 5000, 80.0, v))
    err = _refused(recording, tmp_path, capsys)
    # data row 5000 is file line 5002 (the header is line 1)
    assert f"{recording / 'imu.csv'}: column 'ay' ([imu] lateral_acceleration" in err, err
    assert "line 5002: implausible lateral acceleration" in err, err
    _no_drive_log_terms(err, "ay")


def test_a_derived_lateral_acceleration_names_the_yaw_rate_and_the_wheels(
    recording, tmp_path, capsys
):
    """Without a lateral acceleration column the drive log's is speed × yaw rate: a spike in
    the yaw rate names the IMU's line, the key of its unit, and the wheel stream's line."""
    _edit(recording / "manifest.toml", 'lateral_acceleration = "ay"\n', "")
    _change(recording / "imu.csv", "wz", lambda v: np.where(np.arange(len(v)) == 5000, 30.0, v))
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'imu.csv'}: column 'wz' ([imu] yaw_rate, " in err, err
    assert "line 5002, times the speed of" in err, err
    assert f"{recording / 'wheels.csv'}: columns 'rl', 'rr'" in err, err
    assert "check [imu] yaw_rate_unit" in err, err
    _no_drive_log_terms(err)


def test_a_sideslip_in_degrees_declared_radians_names_the_column_and_the_key(
    recording, tmp_path, capsys
):
    _change(recording / "gnss.csv", "beta", np.degrees)
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'gnss.csv'}: column 'beta' ([gnss] sideslip, sideslip_unit" in err
    assert "implausible sideslip" in err and "check [gnss] sideslip_unit" in err, err
    _no_drive_log_terms(err, "beta")


def test_a_wheel_speed_spike_names_the_wheel_line(recording, tmp_path, capsys):
    _change(recording / "wheels.csv", "rl", lambda v: np.where(np.arange(len(v)) == 5000, 900, v))
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'wheels.csv'}: column 'rl' ([wheels] rear_left" in err, err
    assert "line 5002: implausible rear-left wheel speed" in err, err
    _no_drive_log_terms(err)


def test_one_wheel_line_at_999_km_h_names_the_line_in_the_streams_time(recording, tmp_path, capsys):
    """Issue 35: one line at 999 km/h (277.5 m/s) is diluted below 100 m/s on the drive log's
    grid; checked at the stream, it is named by its file line and the stream's time."""
    _change(recording / "wheels.csv", "rl", lambda v: np.where(np.arange(len(v)) == 3000, 277.5, v))
    t = pd.read_csv(recording / "wheels.csv")["t"].to_numpy()[3000]
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'wheels.csv'}: column 'rl' ([wheels] rear_left" in err, err
    assert f"line 3002: implausible rear-left wheel speed at t = {t:.3f} s: 277.5 m/s" in err
    assert "heading" not in err, err


# --- row G: a time written twice ----------------------------------------------------------


def _repeat_line(path, row: int, change: dict | None = None) -> None:
    """Write data row ``row`` of a CSV twice (the second copy changed by ``change``)."""
    frame = pd.read_csv(path, dtype=str)
    copy = frame.iloc[[row]].copy()
    for column, value in (change or {}).items():
        copy[column] = value
    frame = pd.concat([frame.iloc[: row + 1], copy, frame.iloc[row + 1 :]], ignore_index=True)
    frame.to_csv(path, index=False)


def test_a_gnss_line_written_twice_is_dropped_with_a_note(recording, tmp_path, capsys):
    _repeat_line(recording / "gnss.csv", 99)  # lines 101 and 102
    _repeat_line(recording / "gnss.csv", 199)  # lines 202 and 203 (after the first)
    out = tmp_path / "drive.csv"
    assert main(["import", str(recording / "manifest.toml"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    note = (
        f"note: {recording / 'gnss.csv'}: dropped 2 line(s) repeating the time and values of "
        "the one before (first: line 102)"
    )
    assert note in printed, printed


def test_a_gnss_time_written_twice_with_other_values_names_both_lines(recording, tmp_path, capsys):
    frame = pd.read_csv(recording / "gnss.csv", dtype=str)
    time, latitude = frame.loc[99, "t"], frame.loc[99, "lat"]
    _repeat_line(recording / "gnss.csv", 99, {"lat": "47.5"})
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'gnss.csv'}: line 101 and line 102 have the same time " in err, err
    assert f"{float(time)!r} s" in err and f"lat {float(latitude)!r} vs 47.5" in err, err
    assert "remove the wrong line" in err, err


def test_a_latitude_out_of_range_names_the_file_line(recording, tmp_path, capsys):
    """Row H's other numbers: a fix's file line (header = line 1), not its sample number."""
    _change(recording / "gnss.csv", "lat", lambda v: np.where(np.arange(len(v)) == 50, 147.0, v))
    err = _refused(recording, tmp_path, capsys)
    assert f"{recording / 'gnss.csv'}: column 'lat' ([gnss] latitude, degrees), line 52" in err
    assert "latitude is 147°, outside ±90°" in err, err
