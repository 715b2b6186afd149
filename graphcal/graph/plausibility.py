"""The plausibility check of an estimated theta: wrong units show as an absurd vehicle."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from graphcal.errors import CalibrationFailed
from graphcal.model import C_E, PARAMETER_NAMES, T_R, THETA_NOMINAL

#: Plausible ranges of theta (SI) for a road vehicle like the paper's car; outside them the data
#: is almost surely in wrong units (e.g. sideslip in degrees) rather than the vehicle unusual.
#: Another vehicle's ranges scale with its nominal theta (:func:`plausible_ranges`).
PLAUSIBLE_THETA = np.array([[0.5, 5.0], [-0.1, 0.1], [0.5, 3.0], [-0.05, 0.05]])


class ImplausibleTheta(CalibrationFailed):
    """A solve whose theta left the plausible ranges (:func:`plausible_ranges`).

    Attributes:
        names: the parameters outside their range, in :data:`~graphcal.model.PARAMETER_NAMES`
            order.
    """

    def __init__(self, message: str, names: tuple[str, ...]) -> None:
        super().__init__(message)
        self.names = names


def plausible_ranges(reference: np.ndarray = THETA_NOMINAL) -> np.ndarray:
    """``(4, 2)`` plausible ranges of theta for a vehicle whose nominal theta is ``reference``.

    :data:`PLAUSIBLE_THETA` scaled by ``reference``'s c_e (for c_e, c_d and d, which are
    lengths or lengths per m/s²) and t_r (for t_r) relative to the paper's car; a reference
    without positive c_e and t_r keeps the car's ranges.
    """
    reference = np.asarray(reference, float)
    if not (reference[C_E] > 0 and reference[T_R] > 0):
        return PLAUSIBLE_THETA.copy()
    scale = np.full(4, reference[C_E] / THETA_NOMINAL[C_E])
    scale[T_R] = reference[T_R] / THETA_NOMINAL[T_R]
    return PLAUSIBLE_THETA * scale[:, None]


def check_plausible(
    theta: np.ndarray,
    label: str = "the solve",
    reference: np.ndarray = THETA_NOMINAL,
    causes: Callable[[], tuple[str, ...]] | None = None,
) -> None:
    """Raise :class:`~graphcal.errors.CalibrationFailed` unless theta is finite, and
    :class:`ImplausibleTheta` unless it is inside
    the plausible ranges of a vehicle with nominal theta ``reference`` (:func:`plausible_ranges`;
    by default the paper's car, :data:`PLAUSIBLE_THETA`). ``causes()``, called only for an
    implausible theta, names what in the data or the weights likely drove the solve there
    (the heading's weight, the fix rate, a time offset beyond its prior); units are named
    only when it names nothing."""
    theta = np.asarray(theta, float)
    if not np.all(np.isfinite(theta)):
        raise CalibrationFailed(f"{label} produced a non-finite theta")
    ranges = plausible_ranges(reference)
    outside = (theta < ranges[:, 0]) | (theta > ranges[:, 1])
    if outside.any():
        names = tuple(PARAMETER_NAMES[i] for i in np.flatnonzero(outside))
        bad = ", ".join(f"{PARAMETER_NAMES[i]} = {theta[i]:.4g}" for i in np.flatnonzero(outside))
        found = causes() if causes is not None else ()
        if found:
            raise ImplausibleTheta(
                f"{label} gave an implausible theta ({bad}, SI units); likely cause: "
                + "; ".join(found),
                names,
            )
        raise ImplausibleTheta(
            f"{label} gave an implausible theta ({bad}, SI units); check the units of the "
            "wheel rotations (rev per sample), sideslip (rad) and lateral acceleration (m/s²)",
            names,
        )
