"""Shared fixtures: short synthetic drives made once per test session."""

from __future__ import annotations

import numpy as np
import pytest

from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL, integrate
from graphcal.simulate.drive import (
    NoiseLevels,
    SyntheticDrive,
    simulate_drive,
    write_synthetic_drive,
)


@pytest.fixture(scope="session")
def drive() -> SyntheticDrive:
    """A 4 km city drive at the paper's noise levels."""
    return simulate_drive(length_km=4.0, seed=7)


@pytest.fixture(scope="session")
def clean_drive() -> SyntheticDrive:
    """The same kind of drive without any measurement noise."""
    zero = NoiseLevels(position=0.0, heading=0.0, wheel_rotation=0.0)
    return simulate_drive(length_km=3.0, seed=3, noise=zero)


@pytest.fixture(scope="session")
def drive_csv(tmp_path_factory: pytest.TempPathFactory, drive: SyntheticDrive):
    """``drive`` written to disk with its truth file and sidecar."""
    path = tmp_path_factory.mktemp("drive") / "drive.csv"
    write_synthetic_drive(drive, path)
    return path


@pytest.fixture(scope="session")
def straight_log() -> DriveLog:
    """A noise-free 1.2 km drive on a straight line at 12 m/s (nothing turns)."""
    k = 4000
    inputs = np.tile([0.15, 0.15, 0.0, 0.0], (k, 1))
    poses = integrate(np.zeros(3), inputs[:-1], THETA_NOMINAL)
    return DriveLog.from_arrays(
        t=np.arange(k) * 0.025,
        px=poses[:, 0],
        py=poses[:, 1],
        psi=poses[:, 2],
        n_rl=inputs[:, 0],
        n_rr=inputs[:, 1],
        beta=inputs[:, 2],
        ay=inputs[:, 3],
    )


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
