"""Which parameters a drive determines: degeneracy detection from theta's information.

The joint graph carries a weak prior on theta (``JointSettings.theta_prior_sigmas``), so every
solve returns a number for every parameter. Whether the *data* determined it shows in the
marginal covariance: the prior alone gives sigma = prior sigma; data that determine a
parameter shrink its sigma far below that. graphcal calls a parameter **calibrated** when its
posterior sigma is at most ``max_sigma_ratio`` (default 0.1) times its prior sigma, i.e. the
data carry at least 99 times the prior's information about it.

Typical degeneracies (``docs/method.md``):

* straight-only driving: t_r and d are not observable, c_d is known only relative to t_r
  (the yaw drift shows c_d / t_r) — c_d is then calibrated *given t_r's prior*;
* too little lateral acceleration: d is not observable.

Pure numpy; the covariance comes from a solve such as
:func:`graphcal.pipeline.joint.calibrate_joint` or :func:`graphcal.localization.smooth_drive`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.model import PARAMETER_NAMES

DEFAULT_MAX_SIGMA_RATIO = 0.1
TIE_CORRELATION = 0.9


@dataclass(frozen=True)
class Observability:
    """What the data determined about theta.

    Attributes:
        calibrated: ``(4,)`` True where the data determined the parameter.
        sigma_ratio: ``(4,)`` posterior sigma / prior sigma (1 = the data added nothing).
        correlation: ``(4, 4)`` posterior correlation of theta.
        weak_directions: ``(M, 4)`` unit directions (in prior-sigma units) whose posterior
            sigma exceeds ``max_sigma_ratio`` times the prior's: the unobservable combinations.
        max_sigma_ratio: the threshold used.
        reasons: why a parameter is not calibrated where the σ alone does not say (a
            parameter whose apparent information the drive cannot give), by name.
    """

    calibrated: np.ndarray
    sigma_ratio: np.ndarray
    correlation: np.ndarray
    weak_directions: np.ndarray
    max_sigma_ratio: float
    reasons: dict[str, str] = field(default_factory=dict)

    def without(self, name: str, reason: str) -> Observability:
        """These verdicts with ``name`` not calibrated, for ``reason``."""
        calibrated = self.calibrated.copy()
        calibrated[PARAMETER_NAMES.index(name)] = False
        reasons = {**self.reasons, name: reason}
        return dataclasses.replace(self, calibrated=calibrated, reasons=reasons)

    @property
    def degenerate(self) -> bool:
        """True if some parameter is not determined by the data."""
        return not bool(self.calibrated.all())

    @property
    def not_calibrated(self) -> list[str]:
        """Names of the parameters the data did not determine."""
        return [n for n, ok in zip(PARAMETER_NAMES, self.calibrated, strict=True) if not ok]

    def ties(self) -> list[tuple[str, str, float]]:
        """``(calibrated, unobservable, correlation)`` pairs: a calibrated parameter whose
        value is fixed only relative to one the data did not determine (|correlation| above
        0.9), e.g. c_d given t_r's prior on a straight drive."""
        out = []
        for i, ok in enumerate(self.calibrated):
            for j, other_ok in enumerate(self.calibrated):
                if ok and not other_ok and abs(self.correlation[i, j]) > TIE_CORRELATION:
                    out.append(
                        (PARAMETER_NAMES[i], PARAMETER_NAMES[j], float(self.correlation[i, j]))
                    )
        return out

    def verdicts(self) -> dict[str, str]:
        """Per parameter: ``"calibrated"``, ``"calibrated given the prior of X"`` or
        ``"not observable"``."""
        given: dict[str, list[str]] = {}
        for name, other, _ in self.ties():
            given.setdefault(name, []).append(other)
        out = {}
        for name, ok in zip(PARAMETER_NAMES, self.calibrated, strict=True):
            if not ok:
                out[name] = "not observable"
            elif name in given:
                out[name] = f"calibrated given the prior of {' and '.join(given[name])}"
            else:
                out[name] = "calibrated"
        return out

    def message(self) -> str:
        """One line naming what the data did not determine (empty if nothing)."""
        if not self.degenerate:
            return ""
        parts = [
            f"{name} not observable ({self.reasons[name]})"
            if name in self.reasons
            else f"{name} not observable (data shrank its prior sigma only to "
            f"{self.sigma_ratio[PARAMETER_NAMES.index(name)]:.0%})"
            for name in self.not_calibrated
        ]
        parts += [
            f"{a} is determined only relative to {b} (correlation {r:+.2f}), so it holds for "
            f"{b}'s prior value"
            for a, b, r in self.ties()
        ]
        return "; ".join(parts)


def assess_observability(
    covariance: np.ndarray,
    prior_sigmas: np.ndarray,
    max_sigma_ratio: float = DEFAULT_MAX_SIGMA_RATIO,
) -> Observability:
    """Judge which parameters the data determined from theta's posterior ``covariance``.

    Args:
        covariance: 4×4 marginal covariance of theta from a solve whose only prior on theta
            has standard deviations ``prior_sigmas`` (SI).
        prior_sigmas: ``(4,)`` prior standard deviations (SI).
        max_sigma_ratio: a parameter counts as calibrated when posterior sigma / prior sigma
            is at most this.
    """
    covariance = np.asarray(covariance, float)
    prior_sigmas = np.asarray(prior_sigmas, float)
    sigma = np.sqrt(np.diag(covariance))
    ratio = sigma / prior_sigmas
    correlation = covariance / np.outer(sigma, sigma)
    # In prior-sigma units the prior alone has identity covariance; directions that keep a
    # large share of it are the unobservable combinations.
    scaled = covariance / np.outer(prior_sigmas, prior_sigmas)
    eigenvalues, eigenvectors = np.linalg.eigh(scaled)
    weak = eigenvectors[:, np.sqrt(np.maximum(eigenvalues, 0.0)) > max_sigma_ratio].T
    return Observability(ratio <= max_sigma_ratio, ratio, correlation, weak, max_sigma_ratio)


def condition_on_prior(
    theta: np.ndarray,
    covariance: np.ndarray,
    calibrated: np.ndarray,
    prior_mean: np.ndarray,
    prior_sigmas: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Theta and covariance with the unobservable parameters held at their prior.

    The calibrated parameters were estimated jointly with the unobservable ones; holding
    those at the prior mean moves the calibrated ones along their correlation (Gaussian
    conditioning): ``θ_c + Σ_cu Σ_uu⁻¹ (μ_u − θ_u)`` with covariance
    ``Σ_cc − Σ_cu Σ_uu⁻¹ Σ_uc``. The unobservable entries become the prior mean with the
    prior's variance and no correlation.
    """
    theta = np.asarray(theta, float).copy()
    covariance = np.asarray(covariance, float).copy()
    c = np.flatnonzero(calibrated)
    u = np.flatnonzero(~np.asarray(calibrated, bool))
    if len(u) == 0:
        return theta, covariance
    gain = covariance[np.ix_(c, u)] @ np.linalg.inv(covariance[np.ix_(u, u)])
    theta[c] += gain @ (np.asarray(prior_mean, float)[u] - theta[u])
    conditioned = covariance[np.ix_(c, c)] - gain @ covariance[np.ix_(u, c)]
    theta[u] = np.asarray(prior_mean, float)[u]
    out = np.zeros_like(covariance)
    out[np.ix_(c, c)] = 0.5 * (conditioned + conditioned.T)
    out[u, u] = np.asarray(prior_sigmas, float)[u] ** 2
    return theta, out
