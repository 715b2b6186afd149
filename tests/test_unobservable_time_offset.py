"""Issue 44, row 12 (fixed on main by d5161ff, issue 43): a time offset the drive does not
show reaches the joint batches' settings as a number, never NaN (a robot's one 350 m segment
ended in ``joint.time_offset_mean must be a number of seconds within ±1``)."""

from __future__ import annotations

import dataclasses

import numpy as np

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
