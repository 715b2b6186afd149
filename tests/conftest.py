"""Shared fixtures: short synthetic drives made once per test session."""

from __future__ import annotations

import numpy as np
import pytest

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


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
