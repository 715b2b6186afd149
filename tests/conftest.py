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

#: The longest tests (about 40 s or more each on the 2-core CI machine), longest first. They
#: run before everything else so that ``-n auto`` never ends on one of them with the other
#: core idle: the short tests that follow fill in around them.
LONGEST_FIRST = (
    "tests/test_docs.py::test_block_runs_as_written[docs/fleet.md:14]",
    "tests/test_real_recordings.py::test_the_real_robot_calibrates_from_its_free_runs",
    "tests/test_fleet.py::test_fleet_interrupted_and_resumed_finds_the_change",
    "tests/test_campaign.py::test_calibrations_keep_the_invariants[car-noisy-fixes]",
    "tests/test_campaign.py::test_calibrations_keep_the_invariants[skid-steer-correlated",
    "tests/test_can.py::test_a_can_log_calibrates_as_its_decoded_csv",
    "tests/test_newcomer.py::test_late_wheels_at_one_hertz_are_found_not_blamed_on_units",
    "tests/test_slip.py::test_slip_screened_on_a_spread_sample_decides_as_the_whole_log",
    "tests/test_observability.py::test_cli_straight_drive_names_what_it_cannot_calibrate",
    "tests/test_staged.py::test_staged_cli_end_to_end_is_deterministic_across_workers",
)


def _rank(item: pytest.Item) -> int:
    """0, 1, ...: the longest tests in their order; then the slow tier; then the rest."""
    for rank, prefix in enumerate(LONGEST_FIRST):
        if item.nodeid.startswith(prefix):
            return rank
    return len(LONGEST_FIRST) + (item.get_closest_marker("slow") is None)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=_rank)  # stable: the order within each rank is the collection's


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
