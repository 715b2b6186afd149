"""The plausibility check of an estimated theta: wrong units show as an absurd vehicle."""

from __future__ import annotations

import numpy as np

from graphcal.errors import CalibrationFailed
from graphcal.model import PARAMETER_NAMES

#: Plausible ranges of theta (SI) for a road vehicle; outside them the data is almost surely in
#: wrong units (e.g. sideslip in degrees) rather than the vehicle unusual.
PLAUSIBLE_THETA = np.array([[0.5, 5.0], [-0.1, 0.1], [0.5, 3.0], [-0.05, 0.05]])


def check_plausible(theta: np.ndarray, label: str = "the solve") -> None:
    """Raise :class:`~graphcal.errors.CalibrationFailed` unless theta is finite and inside
    :data:`PLAUSIBLE_THETA`."""
    theta = np.asarray(theta, float)
    if not np.all(np.isfinite(theta)):
        raise CalibrationFailed(f"{label} produced a non-finite theta")
    outside = (theta < PLAUSIBLE_THETA[:, 0]) | (theta > PLAUSIBLE_THETA[:, 1])
    if outside.any():
        bad = ", ".join(f"{PARAMETER_NAMES[i]} = {theta[i]:.4g}" for i in np.flatnonzero(outside))
        raise CalibrationFailed(
            f"{label} gave an implausible theta ({bad}, SI units); check the units of the "
            "wheel rotations (rev per sample), sideslip (rad) and lateral acceleration (m/s²)"
        )
