"""A synthetic fleet: several vehicles, one drive per day each, with known truths and changes.

Each vehicle has its own true theta (the default truth plus a vehicle-to-vehicle spread of
:data:`VEHICLE_SPREAD`); a :class:`FleetChange` changes one vehicle's theta from a day on (a
tyre replaced: c_e drops). Every day is a drive of its own route and noise. Written as the
tree ``graphcal fleet`` reads (``OUT/VEHICLE/DAY.csv`` with each drive's truth and sidecar)
and ``OUT/fleet_truth.csv`` (vehicle, day and the true theta in SI).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.files import atomic_write_csv
from graphcal.model import PARAMETER_NAMES
from graphcal.simulate.drive import THETA_TRUE_DEFAULT, simulate_drive, write_synthetic_drive

#: Standard deviation of the vehicles' true theta around the default truth (SI: c_e 1.5 mm,
#: c_d 0.3 mm, t_r 10 mm, d 0.2 mm·s²/m).
VEHICLE_SPREAD = np.array([1.5e-3, 0.3e-3, 10e-3, 0.2e-3])


@dataclass(frozen=True)
class FleetChange:
    """Vehicle ``vehicle``'s theta changes by ``delta`` (SI) from day ``day`` on (1-based)."""

    vehicle: int
    day: int
    delta: np.ndarray = field(default_factory=lambda: np.array([-3e-3, 0.0, 0.0, 0.0]))


def vehicle_name(index: int) -> str:
    """``"v1"``, ``"v2"``, ... (1-based)."""
    return f"v{index}"


def day_name(index: int, days: int = 9) -> str:
    """``"day1"``, ``"day2"``, ... (1-based), zero-padded to the width of ``days`` so that
    the names sort as the days do (``"day01"`` ... ``"day12"``)."""
    return f"day{index:0{len(str(days))}d}"


def fleet_truth(
    vehicles: int, days: int, seed: int = 0, change: FleetChange | None = None
) -> pd.DataFrame:
    """The true theta (SI) of every vehicle and day: columns ``vehicle, day`` and the
    parameters."""
    rng = np.random.default_rng(seed)
    base = THETA_TRUE_DEFAULT + VEHICLE_SPREAD * rng.standard_normal((vehicles, 4))
    rows = []
    for v in range(1, vehicles + 1):
        for d in range(1, days + 1):
            theta = base[v - 1].copy()
            if change is not None and v == change.vehicle and d >= change.day:
                theta = theta + np.asarray(change.delta, float)
            rows.append(
                {
                    "vehicle": vehicle_name(v),
                    "day": day_name(d, days),
                    **dict(zip(PARAMETER_NAMES, theta, strict=True)),
                }
            )
    return pd.DataFrame(rows)


def simulate_fleet(
    out: str | os.PathLike[str],
    vehicles: int = 6,
    days: int = 3,
    length_km: float = 4.0,
    seed: int = 0,
    change: FleetChange | None = None,
) -> Path:
    """Write a synthetic fleet into ``out`` (see the module docstring); returns the path of
    ``fleet_truth.csv``. Every drive's seed follows from ``seed``, the vehicle and the day.

    Raises:
        ValueError: for fewer than one vehicle or day, or a change outside the fleet.
    """
    if vehicles < 1 or days < 1:
        raise ValueError("a fleet needs at least one vehicle and one day")
    if change is not None and not (1 <= change.vehicle <= vehicles and 1 <= change.day <= days):
        raise ValueError(
            f"the change (vehicle {change.vehicle}, day {change.day}) is outside the fleet of "
            f"{vehicles} vehicles and {days} days"
        )
    out = Path(out)
    truth = fleet_truth(vehicles, days, seed, change)
    for row in truth.itertuples(index=False):
        v, d = int(row.vehicle[1:]), int(row.day[3:])  # v1, day01
        theta = np.array([getattr(row, name) for name in PARAMETER_NAMES])
        drive = simulate_drive(length_km, seed=seed * 10_000 + v * 100 + d, theta_true=theta)
        write_synthetic_drive(drive, out / row.vehicle / f"{row.day}.csv")
    return atomic_write_csv(truth, out / "fleet_truth.csv")
