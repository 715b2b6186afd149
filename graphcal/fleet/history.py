"""A vehicle's calibration over days: when theta changed, and theta since the last change.

Each day's log gives the whole-log posterior of theta (under the solve's weak prior) with its
covariance; a day whose calibration is not trusted has no honest covariance and is left out
(and flagged). Going through the days in order, the days since the last change are combined,
information-weighted with the prior counted once (``Σ = (Σ Σᵢ⁻¹ − (n−1) P)⁻¹``,
``θ = Σ (Σ Σᵢ⁻¹ θᵢ − (n−1) P μ)`` for the prior ``N(μ, P⁻¹)``), and each new day is tested
against that combination:

    χ² = (θ_day − θ_comb)ᵀ (Σ_day + Σ_comb)⁻¹ (θ_day − θ_comb)

over all four parameters (a parameter a log did not determine has its prior's σ there and
weighs nothing). Above the χ² quantile of ``1 − α`` (default
``α = 10⁻³``), theta changed on that day — a tyre replaced, a pressure drop, a re-mounted
wheel — and the parameter with the largest difference in its σ is named; the combination
restarts from that day. The vehicle's current theta is the combination of the days since
its last change.

Across the fleet, a vehicle whose current theta lies far from the others' (more than
:data:`FLEET_OUTLIER_Z` robust standard deviations of the fleet's spread, and more than that
many of its own σ) is flagged, as is any day whose calibration failed or was not trusted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graphcal.model import PARAMETER_NAMES
from graphcal.statistics import chi2_survival

#: Default false-alarm probability of one day's change test.
CHANGE_ALPHA = 1e-3
#: A vehicle is a fleet outlier beyond this many robust σ of the fleet's spread.
FLEET_OUTLIER_Z = 5.0


@dataclass(frozen=True)
class DayEstimate:
    """One day's whole-log posterior of theta (SI): its mean and covariance under the weak
    prior ``N(prior_mean, diag(prior_sigmas²))`` the solve had, unobservable parameters left
    at their posterior (not held at the prior), so that their correlations stay visible."""

    day: str
    theta: np.ndarray
    covariance: np.ndarray
    prior_mean: np.ndarray
    prior_sigmas: np.ndarray


@dataclass(frozen=True)
class DetectedChange:
    """A change of a vehicle's theta that the day-to-day test detected.

    Attributes:
        day: the first day with the new theta.
        parameter: the parameter that moved most, in its σ.
        difference: ``θ_day − θ_before`` (SI, all four parameters).
        sigma: the σ of that difference (SI).
        chi2, dof, p_value: the test.
    """

    day: str
    parameter: str
    difference: np.ndarray
    sigma: np.ndarray
    chi2: float
    dof: int
    p_value: float

    def describe(self) -> str:
        """``"day3: c_e -3.02 mm (11.8σ)"`` (display units)."""
        from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS

        i = PARAMETER_NAMES.index(self.parameter)
        z = self.difference[i] / self.sigma[i]
        return (
            f"{self.day}: {self.parameter} {self.difference[i] * DEVIATION_SCALE[i]:+.2f} "
            f"{DEVIATION_UNITS[i]} ({z:+.1f}σ)"
        )


@dataclass(frozen=True)
class VehicleHistory:
    """A vehicle's days, changes and current theta.

    Attributes:
        vehicle: its name.
        days: the days with a calibration, in order.
        changes: the changes found, in order.
        theta, covariance: the combination of the days since the last change (SI);
            ``None`` if no day was calibrated.
        current_days: those days.
        flags: reasons to look at this vehicle (failed or untrusted days, a fleet outlier).
    """

    vehicle: str
    days: list[DayEstimate]
    changes: list[DetectedChange]
    theta: np.ndarray | None
    covariance: np.ndarray | None
    current_days: list[str]
    flags: list[str] = field(default_factory=list)


def combine(estimates: list[DayEstimate]) -> tuple[np.ndarray, np.ndarray]:
    """The posterior of theta from all ``estimates`` together: their information summed with
    the weak prior counted once (each day's posterior holds it), ``theta, covariance``."""
    prior_information = np.diag(1.0 / np.asarray(estimates[0].prior_sigmas, float) ** 2)
    extra = len(estimates) - 1
    information = -extra * prior_information
    vector = -extra * prior_information @ np.asarray(estimates[0].prior_mean, float)
    for e in estimates:
        day_information = np.linalg.inv(e.covariance)
        information = information + day_information
        vector = vector + day_information @ e.theta
    covariance = np.linalg.inv(information)
    covariance = 0.5 * (covariance + covariance.T)
    return covariance @ vector, covariance


def vehicle_history(
    vehicle: str, days: list[DayEstimate], alpha: float = CHANGE_ALPHA
) -> VehicleHistory:
    """Changes and the current theta of one vehicle from its days' estimates (in order)."""
    changes: list[DetectedChange] = []
    regime: list[DayEstimate] = []
    for day in days:
        if regime:
            change = _test(regime, day, alpha)
            if change is not None:
                changes.append(change)
                regime = []
        regime.append(day)
    if not regime:
        return VehicleHistory(vehicle, days, changes, None, None, [])
    theta, covariance = combine(regime)
    return VehicleHistory(vehicle, days, changes, theta, covariance, [d.day for d in regime])


def _test(regime: list[DayEstimate], day: DayEstimate, alpha: float) -> DetectedChange | None:
    theta, covariance = combine(regime)
    difference = day.theta - theta
    total = day.covariance + covariance
    dof = len(difference)
    chi2 = float(difference @ np.linalg.solve(total, difference))
    p_value = chi2_survival(chi2, dof)
    if p_value >= alpha:
        return None
    sigma = np.sqrt(np.diag(total))
    parameter = PARAMETER_NAMES[int(np.argmax(np.abs(difference) / sigma))]
    return DetectedChange(day.day, parameter, difference, sigma, chi2, dof, p_value)


def flag_fleet_outliers(histories: list[VehicleHistory], z: float = FLEET_OUTLIER_Z) -> None:
    """Add a flag to each vehicle whose current theta is far from the fleet's (robust spread:
    1.4826 × the median absolute deviation across vehicles), and from it by more than ``z``
    of its own σ too. Needs at least 4 vehicles with a theta."""
    current = [h for h in histories if h.theta is not None]
    if len(current) < 4:
        return
    thetas = np.array([h.theta for h in current])
    median = np.median(thetas, axis=0)
    spread = 1.4826 * np.median(np.abs(thetas - median), axis=0)
    for h in current:
        sigma = np.sqrt(np.diag(h.covariance))
        distance = np.abs(h.theta - median)
        far = (distance > z * spread) & (distance > z * sigma)
        for i in np.flatnonzero(far):
            scale = max(spread[i], sigma[i])
            h.flags.append(
                f"{PARAMETER_NAMES[i]} {distance[i] / scale:.1f} robust σ from the fleet's median"
            )
