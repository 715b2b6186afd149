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

**Calibrated given X = prior.** The reported theta holds the unobservable parameters U at
their prior mean μ_U and moves the calibrated ones C by Gaussian conditioning
(:func:`condition_on_prior`): ``θ_C|U = θ̂_C + G (μ_U − θ̂_U)``, ``G = Σ_CU Σ_UU⁻¹``, with
the conditional covariance ``Σ_C|U = Σ_CC − G Σ_UC``. That value and σ are right only if
the true θ_U is μ_U. Were u_j's true value one prior σ (``σp_j``) away from μ_j, θ_i would
be off by ``|G_ij| σp_j`` (to first order), an error its σ_i|U does not contain. So

    q_ij = |G_ij| σp_j / σ_i|U

is the shift of i, in its own (conditional) σ, that a prior one σ off in j causes; for a
single unobservable j, ``G_ij = Σ_ij / Σ_jj`` and ``σ_i|j = σ_i √(1 − ρ_ij²)``, i.e.
``q_ij = |ρ_ij| / (r_j √(1 − ρ_ij²))`` with ``r_j = σ_j / σp_j``. A calibrated i with
``q_ij > HOLDS_GIVEN_SHIFT`` (1) for some unobservable j is **calibrated given j = prior**:
its value and σ are conditional on j's prior. Under an honest prior (the true u_j about
σp_j from μ_j) a parameter left "calibrated" errs by about ``√(1 + Σ_j q_ij²)`` of its σ
(at most √2 for one unobservable j).

The threshold 1 was chosen with a measurement (``docs/fleet.md``, "Values that hold only
given a prior"): on the 32 of 300 simulated 4 km city days (seeds 0–299) where t_r, or t_r
and d, were not observable, re-solving with j's prior mean moved by one σp_j moved each
conditioned θ_i by q_ij of its σ (measured / predicted 0.84–1.03, median 1.00, 99 pairs), so
q > 1 says what it means. With an unobservable prior so moved (either way), every parameter
a threshold of 1 leaves "calibrated" stayed within 3 of its σ of the truth (35 of them, rms
1.15 σ, largest 2.8 σ); a threshold of 1.5 left one beyond 3 σ, 3 left four (up to 5.3 σ).
The former rule (|correlation| > 0.9) marked only d (q 37–70) and called c_d "calibrated"
on days where it was 5.2–6.5 σ from its truth (q 8.7–26).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.model import PARAMETER_NAMES
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS

DEFAULT_MAX_SIGMA_RATIO = 0.1
#: A calibrated parameter holds only given an unobservable one's prior when a prior one σ
#: off would move it by more than this many of its (conditional) σ (module docstring).
HOLDS_GIVEN_SHIFT = 1.0
#: The note a verdict carries when its value and σ hold only given other parameters' prior.
CONDITIONAL_NOTE = "(σ conditional)"
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
        """These verdicts with ``name`` not calibrated, for ``reason``."""
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
        """Names of the parameters the data did not determine (held ones aside)."""
        return [
            n
            for n, ok, held in zip(PARAMETER_NAMES, self.calibrated, self.held, strict=True)
            if not (ok or held)
        ]

    def prior_shifts(self) -> np.ndarray:
        """``(4, 4)`` q_ij: how far the reported (conditioned) θ_i moves, in its conditional
        σ, were unobservable j's prior mean one prior σ off (module docstring); 0 where i is
        not calibrated or j is. Computed in prior-σ units from ``correlation`` and
        ``sigma_ratio`` (``Σ/σpσpᵀ = diag(r) ρ diag(r)``), so no units enter."""
        shifts = np.zeros((len(PARAMETER_NAMES), len(PARAMETER_NAMES)))
        c = np.flatnonzero(self.calibrated)
        u = np.flatnonzero(~np.asarray(self.calibrated, bool))
        if len(c) == 0 or len(u) == 0:
            return shifts
        ratio = np.asarray(self.sigma_ratio, float)
        scaled = np.asarray(self.correlation, float) * np.outer(ratio, ratio)
        gain = np.linalg.solve(scaled[np.ix_(u, u)], scaled[np.ix_(u, c)]).T  # G, prior-σ units
        conditional = scaled[np.ix_(c, c)] - gain @ scaled[np.ix_(u, c)]
        sigma = np.sqrt(np.maximum(np.diag(conditional), np.finfo(float).tiny))
        shifts[np.ix_(c, u)] = np.abs(gain) / sigma[:, None]
        return np.nan_to_num(shifts, nan=np.inf)

    def ties(self) -> list[tuple[str, str, float]]:
        """``(calibrated, unobservable, q)``: a calibrated parameter that holds only given
        the unobservable one's prior — a prior one σ off would move it by q > 1 of its
        conditional σ (:meth:`prior_shifts`) — e.g. d given t_r on a 4 km day."""
        shifts = self.prior_shifts()
        return [
            (PARAMETER_NAMES[i], PARAMETER_NAMES[j], float(shifts[i, j]))
            for i, j in zip(*np.nonzero(shifts > HOLDS_GIVEN_SHIFT), strict=True)
        ]

    def given(self) -> dict[str, list[str]]:
        """Per calibrated parameter that holds only given others' prior: those others."""
        out: dict[str, list[str]] = {}
        for name, other, _ in self.ties():
            out.setdefault(name, []).append(other)
        return out

    def verdicts(self) -> dict[str, str]:
        """Per parameter: ``"calibrated"``, ``"not observable"``, :data:`HELD_VERDICT` or, for
        one whose value and
        σ hold only given unobservable parameters at their prior,
        ``"calibrated given t_r = prior (σ conditional)"`` (``"given t_r, d = prior"`` for
        two)."""
        given = self.given()
        out = {}
        for name, ok, held in zip(PARAMETER_NAMES, self.calibrated, self.held, strict=True):
            if held:
                out[name] = HELD_VERDICT
            elif not ok:
                out[name] = "not observable"
            elif name in given:
                out[name] = f"calibrated given {', '.join(given[name])} = prior {CONDITIONAL_NOTE}"
            else:
                out[name] = "calibrated"
        return out

    def message(self) -> str:
        """One line naming what the data did not determine (empty if nothing)."""
        if not self.degenerate:
            return ""
        parts = [
            f"{name} not observable ({self.reasons.get(name) or self._sigma_text(name)})"
            for name in self.not_calibrated
        ]
        shifts: dict[str, list[str]] = {}
        for a, b, q in self.ties():
            shifts.setdefault(a, []).append(f"{b}'s by {q:.1f}")
        parts += [
            f"{a} holds only given {', '.join(self.given()[a])} = prior (a prior one σ off "
            f"would move {a}: {', '.join(moves)} of its σ)"
            for a, moves in shifts.items()
        ]
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
