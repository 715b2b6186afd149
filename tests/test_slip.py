"""Slow per-wheel slip: modelled as Gauss–Markov scale states, it no longer biases theta."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from graphcal.data.drive_log import validate_frame
from graphcal.evaluation import Truth, evaluate
from graphcal.pipeline.run import run_calibration
from graphcal.pipeline.settings import Settings
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


@pytest.mark.slow
def test_modelled_slip_keeps_theta_within_3_sigma():
    drive = degrade(simulate_drive(8.0, 3), parse_defects("slip=0.003"), 3)
    log = validate_frame(drive.measured.to_dataframe(), "slip", 150.0)

    def z(slip_sigma: float) -> np.ndarray:
        settings = Settings()
        joint = dataclasses.replace(settings.joint, slip_sigma=slip_sigma)
        run = run_calibration(log, dataclasses.replace(settings, joint=joint), "whole")
        error = evaluate(run, Truth(drive.theta_true)).theta_error
        return np.abs(error) / np.sqrt(np.diag(run.covariance))

    assert z(0.0).max() > 10  # white wheel noise only: confidently wrong
    assert z(0.003).max() < 3
