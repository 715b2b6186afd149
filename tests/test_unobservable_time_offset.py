"""Issue 44, row 12 (fixed on main by d5161ff, issue 43): a time offset the drive does not
show reaches the joint batches' settings as a number, never NaN (a robot's one 350 m segment
ended in ``joint.time_offset_mean must be a number of seconds within ±1``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.graph.solution.estimates import NuisanceEstimate
from graphcal.pipeline.methods.sensor_estimates import sensor_estimates
from graphcal.pipeline.methods.whole_log import _batch_time_offset
from graphcal.pipeline.solvers.joint_settings import JointSettings


def test_a_time_offset_without_information_gives_the_batches_a_valid_prior():
    singular = NuisanceEstimate(np.array([np.nan]), np.array([[np.nan]]), 0.5)
    estimated = sensor_estimates({"time_offset": singular}, 0.1)
    prior = _batch_time_offset(estimated, 0.025)
    assert np.all(np.isfinite(prior["time_offset_means"])), prior
    settings = dataclasses.replace(JointSettings(), **prior)  # raised ValueError before
    assert settings.time_offset_sigma == 0.5


def test_an_offset_run_away_without_being_detected_gives_the_batches_a_valid_prior():
    """Campaign seed 35's shape 56 (a differential robot, three drives, 5 Hz fixes sharing
    1.5 m over 50 s): the time-offset rounds shifted a run's wheels by −1.4 s, the last solve
    found that offset not observable, and its total reached the batches' settings: a
    traceback. Not detected, it is not corrected, and the batches' prior is 0."""
    from graphcal.pipeline.methods.sensor_estimates import SensorEstimate

    ran_away = SensorEstimate("time_offset", -1.41, 0.45, 0.5, False)
    prior = _batch_time_offset({"time_offset": ran_away}, 0.05)
    assert prior["time_offset_means"] == (0.0,)
    dataclasses.replace(JointSettings(), **prior)  # raised ValueError before
    found = SensorEstimate("time_offset", 0.1234, 0.002, 0.5, True)  # detected: the rest
    rest = _batch_time_offset({"time_offset": found}, 0.05)["time_offset_means"][0]
    assert rest == pytest.approx(0.1234 - 0.1, abs=1e-9)
