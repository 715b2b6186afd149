"""The library's side of the CLI's decisions: opening a log by path, choosing settings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import graphcal

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "data" / "sample_drive.csv"


def test_open_log_reads_a_csv_as_load_drive_log_does():
    vehicle = graphcal.Settings().vehicle
    log, imported = graphcal.open_log(SAMPLE, vehicle, min_distance=150.0)
    assert imported is None
    np.testing.assert_array_equal(log.t, graphcal.load_drive_log(SAMPLE).t)


def test_a_recording_directory_is_its_manifest(tmp_path):
    assert graphcal.recording_path(tmp_path) == tmp_path
    (tmp_path / "manifest.toml").write_text("")
    assert graphcal.recording_path(tmp_path) == tmp_path / "manifest.toml"
    (tmp_path / "metadata.yaml").write_text("")  # a ROS 2 bag
    assert graphcal.recording_path(tmp_path) == tmp_path


def test_configure_settings_layers_the_file_the_vehicle_and_the_options(tmp_path):
    config = tmp_path / "cfg.toml"
    config.write_text("[segments]\nlength = 200.0\n")
    settings = graphcal.configure_settings(
        config, segments={"length": None, "stride": 50.0}, batches={"count": 7}
    )
    assert (settings.segments.length, settings.segments.stride) == (200.0, 50.0)
    assert settings.batches.count == 7
    assert graphcal.configure_settings(paper_exact=True).staged.heading_correction == "paper"
    with pytest.raises(graphcal.GraphcalError):
        graphcal.configure_settings(segments={"length": -1.0})
