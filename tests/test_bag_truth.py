"""Issue 35, reports: a simulated bag is compared with its truth, like its manifest is.

``graphcal simulate --streams DIR --bag ros2`` writes DIR/truth.json beside the bag; the
manifest names it (``truth = "truth.json"``), the bag cannot, so calibrating the bag looked
like a real recording's calibration: no true theta, no errors."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from graphcal.cli.simulate_streams import BAG_NAMES, write_streams_and_bag
from graphcal.evaluation import synthetic_truth
from graphcal.model import PARAMETER_NAMES
from graphcal.recording.importer import import_recording
from graphcal.simulate.streams import simulate_streams

pytest.importorskip("rosbags")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory):
    directory = tmp_path_factory.mktemp("bag_truth")
    sim = simulate_streams(length_km=0.6, seed=2)
    write_streams_and_bag(sim, directory, "ros2")
    return sim, directory


def test_a_simulated_bag_brings_the_truth_json_beside_it(simulated):
    sim, directory = simulated
    imported = import_recording(directory / BAG_NAMES["ros2"])
    np.testing.assert_array_equal(imported.truth, sim.drive.theta_true)
    assert imported.truth_file == str((directory / "truth.json").resolve())
    heard: list[str] = []
    truth = synthetic_truth(None, directory / BAG_NAMES["ros2"], imported, heard.append)
    np.testing.assert_array_equal(truth.theta, sim.drive.theta_true)
    assert "truth.json" in heard[0], heard
    assert "theta_true" in imported.sidecar()  # `graphcal import` keeps it for the CSV


def test_a_truth_json_graphcal_did_not_write_is_not_taken_for_the_truth(simulated, tmp_path):
    sim, directory = simulated
    bag = tmp_path / "drive_ros2"
    shutil.copytree(directory / BAG_NAMES["ros2"], bag)
    theta = dict(zip(PARAMETER_NAMES, map(float, sim.drive.theta_true), strict=True))
    (tmp_path / "truth.json").write_text(json.dumps({"theta_true": theta}))  # no generator
    assert import_recording(bag).truth is None
