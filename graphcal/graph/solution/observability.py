"""Which parameters a drive determines: degeneracy detection from theta's information.

The joint graph carries a weak prior on theta (``JointSettings.theta_prior_sigmas``), so every
solve returns a number for every parameter. Whether the *data* determined it shows in the
information the solve gathered about theta: its posterior information less the prior's.
graphcal judges that information against a fixed yardstick, the **reference sigmas**
(:func:`graphcal.model.reference_sigmas`: the paper's car's prior sigmas — c_e ±10 cm, c_d
±1 cm, t_r ±20 cm, d ±0.01 s² — scaled to the vehicle's size), not against the prior a
profile or settings file set: the data's information plus a prior of the reference widths
gives each parameter a σ, and it is **calibrated** when that σ is at most
``max_sigma_ratio`` (default 0.1) of its reference sigma, i.e. the data carry at least 99
times a reference prior's information about it. Doubling or halving
``theta_prior_sigmas`` then changes no verdict (it did, with the prior as the yardstick: on
the real highway minute, twice the prior turned d "calibrated" on a drive without bends).
For the paper's car the reference sigmas are the default prior sigmas, so with the default
prior the two yardsticks are the same.

Typical degeneracies (``docs/method.md``):

* straight-only driving: t_r and d are not observable, c_d is known only relative to t_r
  (the yaw drift shows c_d / t_r) — c_d is then calibrated *given t_r = prior*;
* too little lateral acceleration: d is not observable;
* a short city day (4 km) where t_r is not observable: d is known only together with t_r.

**What is reported.** Every parameter's value is its posterior under the weak prior and its
σ the marginal one: the uncertainty of every parameter the data leave open (a straight
road's t_r, on which c_d then depends) is in it, so no value holds "only given" another's
prior. A parameter that is not calibrated but whose σ from the data and the reference prior
is at most :data:`WEAK_SIGMA_RATIO` of the reference sigma — the data carry at least as much
information about it as the reference prior does, so its estimate is mostly theirs — is
**weakly determined**: its estimate with that σ is what is written, never the nominal (a
skid-steer robot's c_e 3σ below its datasheet value, σ 17 % of its reference: keeping the
datasheet's is the worse answer). Otherwise it is **not observable**: the estimate is mostly
the prior's. Like "calibrated", both are read on the reference prior, so the prior's width
changes none (an estimate's distance from the nominal would not do: a direction the data
barely see moves in proportion to the prior's variance, the real highway minute's t_r 1.5σ
from its nominal at the documented prior and 2.2σ at twice its width).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.model import PARAMETER_NAMES
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS

DEFAULT_MAX_SIGMA_RATIO = 0.1
#: A parameter that is not calibrated is weakly determined when its σ from the data and the
#: reference prior is at most this share of the reference sigma: the data's information about
#: it is at least the reference prior's (module docstring).
WEAK_SIGMA_RATIO = 1.0 / np.sqrt(2.0)
#: The verdict of a parameter the data inform without calibrating it.
WEAK_VERDICT = "weakly determined"
#: The verdict of a parameter the vehicle profile holds at its nominal value.
HELD_VERDICT = "fixed at nominal (vehicle profile)"


@dataclass(frozen=True)
class Observability:
    """What the data determined about theta.

    Attributes:
        calibrated: ``(4,)`` True where the data determined the parameter.
        sigma_ratio: ``(4,)`` σ / reference sigma, the σ from the data's information and a
            prior of the reference widths (1 = the data added nothing; module docstring).
        correlation: ``(4, 4)`` correlation of theta under that information.
        weak_directions: ``(M, 4)`` unit directions (in reference-sigma units) whose σ
            exceeds ``max_sigma_ratio`` times the reference's: the unobservable combinations.
        max_sigma_ratio: the threshold used.
        reasons: why a parameter is not calibrated where the σ alone does not say (a
            parameter whose apparent information the drive cannot give), by name.
        held: ``(4,)`` True where the vehicle profile holds the parameter at its nominal
            (``fix_d``): neither calibrated nor a degeneracy of the drive.
        reference: ``(4,)`` the reference sigmas [SI] (``None``: the prior sigmas were the
            yardstick).
    """

    calibrated: np.ndarray
    sigma_ratio: np.ndarray
    correlation: np.ndarray
    weak_directions: np.ndarray
    max_sigma_ratio: float
    reasons: dict[str, str] = field(default_factory=dict)
    held: np.ndarray = field(default_factory=lambda: np.zeros(len(PARAMETER_NAMES), bool))
    reference: np.ndarray | None = None

    def without(self, name: str, reason: str) -> Observability:
        """These verdicts with ``name`` not calibrated (nor weakly determined), for
        ``reason``."""
        calibrated = self.calibrated.copy()
        calibrated[PARAMETER_NAMES.index(name)] = False
        reasons = {**self.reasons, name: reason}
        return dataclasses.replace(self, calibrated=calibrated, reasons=reasons)

    @property
    def degenerate(self) -> bool:
        """True if some parameter that is not held is not determined by the data."""
        return not bool((self.calibrated | self.held).all())

    @property
    def not_calibrated(self) -> list[str]:
        """Names of the parameters the data did not determine (held ones aside; the weakly
        determined ones among them)."""
        return [
            n
            for n, ok, held in zip(PARAMETER_NAMES, self.calibrated, self.held, strict=True)
            if not (ok or held)
        ]

    @property
    def weakly_determined(self) -> np.ndarray:
        """``(4,)`` True where a parameter is not calibrated (nor held, nor left out for a
        reason) but the data's information about it is at least the reference prior's
        (σ ratio at most :data:`WEAK_SIGMA_RATIO`)."""
        informed = np.asarray(self.sigma_ratio, float) <= WEAK_SIGMA_RATIO
        reasoned = np.isin(PARAMETER_NAMES, list(self.reasons))
        return (
            informed & ~np.asarray(self.calibrated, bool) & ~np.asarray(self.held, bool) & ~reasoned
        )

    def verdicts(self) -> dict[str, str]:
        """Per parameter: ``"calibrated"``, :data:`WEAK_VERDICT`, ``"not observable"`` or
        :data:`HELD_VERDICT`."""
        weak = self.weakly_determined
        out = {}
        for i, name in enumerate(PARAMETER_NAMES):
            if self.held[i]:
                out[name] = HELD_VERDICT
            elif self.calibrated[i]:
                out[name] = "calibrated"
            else:
                out[name] = WEAK_VERDICT if weak[i] else "not observable"
        return out

    def message(self) -> str:
        """One line naming what the data did not determine (empty if nothing)."""
        if not self.degenerate:
            return ""
        weak = self.weakly_determined
        parts = []
        for name in self.not_calibrated:
            i = PARAMETER_NAMES.index(name)
            why = self.reasons.get(name) or self._sigma_text(name)
            if weak[i]:
                parts.append(f"{name} weakly determined ({why})")
            else:
                parts.append(f"{name} not observable ({why})")
        return "; ".join(parts)

    def _sigma_text(self, name: str) -> str:
        """Why ``name`` is not calibrated, in its σ: against the reference sigma it needs
        (``σ 2.6 mm from the data; calibrated needs ≤ 1 mm``), or the prior's share."""
        i = PARAMETER_NAMES.index(name)
        if self.reference is None:
            return f"data shrank its prior sigma only to {self.sigma_ratio[i]:.0%}"
        scale, unit = DEVIATION_SCALE[i], DEVIATION_UNITS[i]
        sigma = self.sigma_ratio[i] * self.reference[i] * scale
        needed = self.max_sigma_ratio * self.reference[i] * scale
        return f"σ {sigma:.3g} {unit} from the data; calibrated needs ≤ {needed:.3g} {unit}"


def assess_observability(
    covariance: np.ndarray,
    prior_sigmas: np.ndarray,
    max_sigma_ratio: float = DEFAULT_MAX_SIGMA_RATIO,
    held: np.ndarray | None = None,
    reference_sigmas: np.ndarray | None = None,
) -> Observability:
    """Judge which parameters the data determined from theta's posterior ``covariance``.

    Args:
        covariance: 4×4 marginal covariance of theta from a solve whose only prior on theta
            has standard deviations ``prior_sigmas`` (SI).
        prior_sigmas: ``(4,)`` prior standard deviations (SI).
        max_sigma_ratio: a parameter counts as calibrated when its σ is at most this share of
            its reference sigma.
        held: ``(4,)`` True where a tight prior holds the parameter at its nominal (the
            vehicle's ``fix_d``); such a parameter is never judged calibrated, and the others
            are judged with it held.
        reference_sigmas: ``(4,)`` the yardstick (SI; :func:`graphcal.model.reference_sigmas`);
            the prior's information is taken out of ``covariance`` and a prior of these
            widths put in (module docstring). ``None``: the prior sigmas are the yardstick.
    """
    covariance = np.asarray(covariance, float)
    prior_sigmas = np.asarray(prior_sigmas, float)
    held = np.zeros(len(prior_sigmas), bool) if held is None else np.asarray(held, bool)
    reference = prior_sigmas if reference_sigmas is None else np.asarray(reference_sigmas, float)
    reference = np.where(held, prior_sigmas, reference)  # a held one stays held
    if not np.array_equal(reference, prior_sigmas):
        covariance = with_prior_sigmas(covariance, prior_sigmas, reference)
    sigma = np.sqrt(np.diag(covariance))
    ratio = sigma / reference
    correlation = covariance / np.outer(sigma, sigma)
    # In reference-sigma units the reference prior alone has identity covariance; directions
    # that keep a large share of it are the unobservable combinations.
    scaled = covariance / np.outer(reference, reference)
    eigenvalues, eigenvectors = np.linalg.eigh(scaled)
    weak = eigenvectors[:, np.sqrt(np.maximum(eigenvalues, 0.0)) > max_sigma_ratio].T
    calibrated = (ratio <= max_sigma_ratio) & ~held
    return Observability(
        calibrated,
        ratio,
        correlation,
        weak,
        max_sigma_ratio,
        held=held,
        reference=None if reference_sigmas is None else reference,
    )


def with_prior_sigmas(covariance: np.ndarray, prior: np.ndarray, other: np.ndarray) -> np.ndarray:
    """``covariance`` of a solve under a zero-correlation prior of sigmas ``prior`` turned
    into the one under a prior of sigmas ``other``: the prior's information taken out, the
    other's put in (in prior-sigma units, where the prior's information is the identity;
    the data's information is kept positive semi-definite)."""
    scaled = covariance / np.outer(prior, prior)
    information = np.linalg.inv(0.5 * (scaled + scaled.T)) - np.eye(len(prior))
    values, vectors = np.linalg.eigh(0.5 * (information + information.T))
    data = (vectors * np.maximum(values, 0.0)) @ vectors.T
    ratio = other / prior
    out = np.linalg.inv(data + np.diag(1.0 / ratio**2))
    return 0.5 * (out + out.T) * np.outer(prior, prior)
