"""The plausibility check of an estimated theta: wrong units show as an absurd vehicle."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed
from graphcal.graph.construction import keys
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


#: A theta within this many prior sigmas of its nominal is plausible, whatever the car's
#: ranges say: a skid-steer profile's effective track is twice its datasheet's by design
#: (nominal 0.55 m, prior σ 0.5 m, truth about 1.1 m; the car's range scaled to 0.55 m ends
#: at 1.065 m).
PRIOR_SPAN = 5.0


def plausible_ranges(
    reference: np.ndarray = THETA_NOMINAL, prior_sigmas: np.ndarray | None = None
) -> np.ndarray:
    """``(4, 2)`` plausible ranges of theta for a vehicle whose nominal theta is ``reference``.

    :data:`PLAUSIBLE_THETA` scaled by ``reference``'s c_e (for c_e, c_d and d, which are
    lengths or lengths per m/s²) and t_r (for t_r) relative to the paper's car; a reference
    without positive c_e and t_r keeps the car's ranges. Each range is widened to cover
    ``reference`` ± :data:`PRIOR_SPAN` of the theta prior's ``prior_sigmas`` (SI), if given:
    what a profile's own prior allows is plausible.
    """
    reference = np.asarray(reference, float)
    if not (reference[C_E] > 0 and reference[T_R] > 0):
        ranges = PLAUSIBLE_THETA.copy()
    else:
        scale = np.full(4, reference[C_E] / THETA_NOMINAL[C_E])
        scale[T_R] = reference[T_R] / THETA_NOMINAL[T_R]
        ranges = PLAUSIBLE_THETA * scale[:, None]
    if prior_sigmas is not None:
        span = PRIOR_SPAN * np.abs(np.asarray(prior_sigmas, float))
        ranges[:, 0] = np.minimum(ranges[:, 0], reference - span)
        ranges[:, 1] = np.maximum(ranges[:, 1], reference + span)
    return ranges


@dataclass(frozen=True)
class BeyondPlausible:
    """How far a solve's theta lies beyond ``ranges`` (``(4, 2)``, :func:`plausible_ranges`),
    in widths of its range: the largest over the parameters, 0 inside (a solve's
    ``SolveOptions.runaway``)."""

    ranges: np.ndarray

    def __call__(self, values: gtsam.Values) -> float:
        theta = np.asarray(values.atVector(keys.THETA), float)
        low, high = self.ranges[:, 0], self.ranges[:, 1]
        beyond = np.maximum(low - theta, theta - high) / (high - low)
        return float(max(beyond.max(), 0.0))


def check_plausible(
    theta: np.ndarray,
    label: str = "the solve",
    reference: np.ndarray = THETA_NOMINAL,
    causes: Callable[[], tuple[str, ...]] | None = None,
    prior_sigmas: np.ndarray | None = None,
) -> None:
    """Raise :class:`~graphcal.errors.CalibrationFailed` unless theta is finite, and
    :class:`ImplausibleTheta` unless it is inside
    the plausible ranges of a vehicle with nominal theta ``reference`` (:func:`plausible_ranges`;
    by default the paper's car, :data:`PLAUSIBLE_THETA`; widened by the theta prior's
    ``prior_sigmas``). ``causes()``, called only for an
    implausible theta, names what in the data or the weights likely drove the solve there
    (the heading's weight, the fix rate, a time offset beyond its prior); units are named
    only when it names nothing."""
    theta = np.asarray(theta, float)
    if not np.all(np.isfinite(theta)):
        raise CalibrationFailed(f"{label} produced a non-finite theta")
    ranges = plausible_ranges(reference, prior_sigmas)
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
