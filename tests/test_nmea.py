"""GNSS from a receiver's NMEA log (``[gnss] nmea = ...``): the same fixes as a CSV give the
same import and calibration; dates, midnight, bad sentences and bad manifests."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from graphcal.cli import main
from graphcal.evaluation import Truth, evaluate
from graphcal.files import atomic_write_csv
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.recording.importer import import_recording
from graphcal.recording.manifest_recording import read_manifest
from graphcal.recording.nmea.fixes import read_nmea
from graphcal.simulate.nmea import (
    nmea_lines,
    nmea_manifest,
    receiver_fixes,
    sentence,
    write_nmea,
)
from graphcal.simulate.streams import EPOCH, simulate_streams, write_streams

pytest.importorskip("pynmea2")

#: Midnight UTC between 2025-11-22 and 2025-11-23 (the synthetic recordings' start).
MIDNIGHT = EPOCH


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A 3 km recording (seed 2) as streams whose GNSS is a receiver's NMEA log (GGA + RMC
    at 10 Hz, ``nmea.toml``) and the same fixes as a CSV (``csv.toml``)."""
    directory = tmp_path_factory.mktemp("nmea")
    sim = simulate_streams(3.0, 2)
    write_streams(sim, directory)
    fixes = receiver_fixes(sim)
    write_nmea(fixes, directory / "receiver.nmea")
    atomic_write_csv(fixes[["t", "lat", "lon"]], directory / "fixes.csv")
    (directory / "nmea.toml").write_text(nmea_manifest(sim))
    columns = 'file = "fixes.csv"\ntime = "t"\nlatitude = "lat"\nlongitude = "lon"\n'
    (directory / "csv.toml").write_text(
        nmea_manifest(sim).replace('nmea = "receiver.nmea"\n', columns)
    )
    return directory, sim, fixes


@pytest.fixture()
def recording(drive, tmp_path):
    """A private copy of the recording, to edit."""
    shutil.copytree(drive[0], tmp_path / "rec")
    return tmp_path / "rec"


def _one_line_exit_2(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _lines(path) -> list[str]:
    return path.read_text().splitlines()


def _write(path, lines: list[str]) -> None:
    path.write_text("\r\n".join(lines) + "\r\n")


@pytest.mark.slow
def test_every_fix_is_the_csvs_within_a_millimetre_at_its_centisecond(drive):
    directory, _, fixes = drive
    text = _lines(directory / "receiver.nmea")
    assert text[0].startswith("$GNGGA,000000.") and text[1].startswith("$GNRMC,000000.")
    latitude = text[0].split(",")[2]
    assert len(latitude.split(".")[1]) == 7  # ddmm.mmmmmmm: 0.19 mm
    nmea = read_manifest(directory / "nmea.toml")
    csv = read_manifest(directory / "csv.toml")
    assert len(nmea.pose.t) == len(csv.pose.t) == len(fixes)
    assert np.all(nmea.pose.t == csv.pose.t)  # the same Unix times, to the centisecond
    centiseconds = nmea.pose.t * 100
    assert np.abs(centiseconds - np.round(centiseconds)).max() < 1e-3
    assert np.hypot(nmea.pose.x - csv.pose.x, nmea.pose.y - csv.pose.y).max() < 1e-3
    assert nmea.pose.heading is None and nmea.pose.sideslip is None
    summary = " | ".join(nmea.notes)
    assert f"{len(fixes)} fixes from {len(fixes)} GGA, {len(fixes)} RMC" in summary
    assert "RTK float (5) 100%" in summary and "HDOP median" in summary


@pytest.mark.slow
def test_an_nmea_log_calibrates_as_the_csv_of_its_fixes_within_3_sigma(drive):
    directory, sim, _ = drive
    runs = {}
    for name in ("nmea", "csv"):
        imported = import_recording(directory / f"{name}.toml")
        runs[name] = run_calibration(imported.log, method="whole", workers=1)
    sigma = np.sqrt(np.diag(runs["nmea"].covariance))
    error = evaluate(runs["nmea"], Truth(sim.drive.theta_true)).theta_error
    assert np.all(np.abs(error) < 3 * sigma), error / sigma
    difference = runs["nmea"].theta - runs["csv"].theta
    assert np.all(np.abs(difference) < 0.01 * sigma), difference / sigma


@pytest.mark.slow
def test_hdt_gives_the_true_heading_and_time_offset_shifts_the_fixes(recording, drive):
    fixes = drive[2]
    write_nmea(fixes, recording / "receiver.nmea", hdt=True)
    manifest = recording / "nmea.toml"
    manifest.write_text(manifest.read_text().replace("[gnss]\n", "[gnss]\ntime_offset = 0.25\n"))
    pose = read_manifest(manifest).pose
    expected = np.radians(90.0 - fixes["heading"].to_numpy())
    assert np.abs(np.angle(np.exp(1j * (pose.heading - expected)))).max() < np.radians(0.006)
    np.testing.assert_allclose(pose.t, fixes["t"].to_numpy() + 0.25, rtol=0, atol=1e-6)
    # heading = false: positions only
    manifest.write_text(manifest.read_text().replace("[gnss]\n", "[gnss]\nheading = false\n"))
    ignored = read_manifest(manifest)
    assert ignored.pose.heading is None
    assert any("heading ignored" in note for note in ignored.notes)


def test_a_dual_antenna_baseline_across_the_car_is_named_in_nmea_terms(recording, drive, capsys):
    _, _, fixes = drive
    across = fixes.assign(heading=np.mod(fixes["heading"] + 90.0, 360.0))
    write_nmea(across, recording / "receiver.nmea", hdt=True)
    err = _one_line_exit_2(["check", str(recording / "nmea.toml")], capsys)
    assert "receiver.nmea: HDT/THS heading ([gnss] nmea)" in err, err
    assert "differs from the direction of travel by -90°" in err, err
    assert "heading = false" in err and "heading_convention" not in err, err


def _midnight_fixes(drive) -> pd.DataFrame:
    """The drive's fixes a minute earlier: the log crosses midnight 2025-11-22/23."""
    return drive[2].assign(t=np.round((drive[2]["t"] - 60.0) * 100) / 100)[:1200]


def test_midnight_rolls_over_with_rmc_dates_or_the_date_key(drive, tmp_path):
    fixes = _midnight_fixes(drive)
    expected = fixes["t"].to_numpy()
    assert expected[0] < MIDNIGHT < expected[-1]
    lines = nmea_lines(fixes)
    path = tmp_path / "log.nmea"
    # GGA and RMC at every epoch, a logger's time stamp before each sentence
    _write(path, [f"2025-11-23T00:00:00.000 {line}" for line in lines])
    np.testing.assert_allclose(read_nmea(path).t, expected, rtol=0, atol=1e-6)
    # RMC (with its date) only once a second and only after midnight
    after = expected >= MIDNIGHT
    sparse = [
        line
        for k, line in enumerate(lines)
        if "GGA" in line or (after[k // 2] and (k // 2) % 10 == 0)
    ]
    _write(path, sparse)
    np.testing.assert_allclose(read_nmea(path).t, expected, rtol=0, atol=1e-6)
    # GGA only: the date key names the first fix's date
    _write(path, [line for line in lines if "GGA" in line])
    np.testing.assert_allclose(read_nmea(path, "2025-11-22").t, expected, rtol=0, atol=1e-6)


def test_corrupt_checksums_and_invalid_fixes_are_skipped_and_noted(recording, drive):
    _, _, fixes = drive
    fixes = fixes.copy()
    fixes.loc[300:309, "quality"] = 0  # the receiver lost its fix for a second
    write_nmea(fixes, recording / "receiver.nmea")
    lines = _lines(recording / "receiver.nmea")
    corrupt = [100, 102, 104, 500, 501]  # 3 GGA alone, then GGA and RMC of fix 250
    for k in corrupt:
        lines[k] = lines[k].replace(",N,", ",S,")  # a flipped bit the checksum catches
    lines.insert(7, "$GNGGA,000001.00,4729.87")  # a sentence cut off: no checksum
    lines.insert(8, "$GPGSV,3,1,11,01,45,123,40*7A")  # another type: counted, skipped
    _write(recording / "receiver.nmea", lines)
    imported = read_manifest(recording / "nmea.toml")
    clean = read_manifest(drive[0] / "nmea.toml").pose
    notes = " | ".join(imported.notes)
    assert "skipped 6 sentence(s) with a wrong or missing checksum (first: line 8)" in notes
    assert "dropped 10 fix(es) with fix quality 0 (invalid) (first: line 603)" in notes, notes
    assert len(imported.pose.t) == len(fixes) - 10 - 1  # fix 250 has no sentence left
    # the epochs whose GGA failed keep their RMC's position; quality 0 is gone
    pose = imported.pose
    np.testing.assert_array_equal(pose.t[49:53], clean.t[49:53])
    assert np.hypot(pose.x[49:53] - clean.x[49:53], pose.y[49:53] - clean.y[49:53]).max() < 1e-3
    assert not np.isin(clean.t[300:310], pose.t).any()
    assert list(pose.provenance.quality[49:53]) == [5, -1, -1, -1]


def test_ths_is_a_heading_and_vtg_is_not(drive, tmp_path):
    fixes = drive[2][:50]
    lines = nmea_lines(fixes)
    extra = []
    for k, line in enumerate(lines):
        extra.append(line)
        if "RMC" in line:
            heading = fixes["heading"].iloc[k // 2]
            extra.append(sentence(f"GNVTG,{(heading + 5) % 360:.2f},T,,M,20.0,N,37.0,K,A"))
            extra.append(sentence(f"GNTHS,{heading:.2f},A"))
    path = tmp_path / "ths.nmea"
    _write(path, extra)
    log = read_nmea(path)
    np.testing.assert_allclose(log.heading, fixes["heading"].to_numpy(), atol=0.006)
    assert log.counts["VTG"] == 50 and log.counts["THS"] == 50


NMEA_ERRORS = [
    (
        ["$GPGSV,3,1,11,01,45,123,40*7A", sentence("GPGSA,A,3,01,02,,,,,,,,,,,1.2,0.8,0.9")],
        None,
        ["receiver.nmea: no GGA or RMC sentence (found 1 GSV, 1 GSA)", "enable them"],
    ),
    (
        "gga only",
        None,
        ["100 GGA sentences and no RMC: their UTC times", 'add [gnss] date = "YYYY-MM-DD"'],
    ),
    ("gga only", 'latitude = "lat"\n', ["[gnss] latitude: not used with nmea = ..."]),
    ("gga only", 'date = "23.11.2025"\n', ["date = '23.11.2025': give the UTC date as \"YYYY-"]),
]


@pytest.mark.parametrize(("log", "keys", "expected"), NMEA_ERRORS)
def test_bad_nmea_input_gets_one_line(recording, drive, capsys, tmp_path, log, keys, expected):
    if log == "gga only":
        log = [line for line in nmea_lines(drive[2][:100]) if "GGA" in line]
    _write(recording / "receiver.nmea", log)
    if keys:
        manifest = recording / "nmea.toml"
        manifest.write_text(manifest.read_text().replace("[gnss]\n", f"[gnss]\n{keys}"))
    out = tmp_path / "drive.csv"
    err = _one_line_exit_2(["import", str(recording / "nmea.toml"), "--out", str(out)], capsys)
    for text in expected:
        assert text in err, err
    assert not out.exists()


def test_the_keys_are_printed_by_help_manifest_and_the_log_is_never_overwritten(recording, capsys):
    with pytest.raises(SystemExit):
        main(["import", "--help-manifest"])
    printed = capsys.readouterr().out
    assert 'nmea = "receiver.nmea"' in printed and 'date = "2025-11-23"' in printed
    out = recording / "receiver.nmea"
    err = _one_line_exit_2(["import", str(recording / "nmea.toml"), "--out", str(out)], capsys)
    assert "a file of the recording" in err
