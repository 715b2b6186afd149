"""Whether a calibration can be trusted, judged without a truth (issue 13: never confidently
wrong).

A solve reports a σ for each parameter. That σ is honest only if the data fit the model and
its noise levels. Four checks need nothing but the run itself:

* **convergence**: the whole-log solve stopped before its iteration limit;
* **fit** (χ² test): the whole-log solve's normalized residuals, ``2 · error / dof``, are
  about 1 when the noise model fits (0.97 on the sample drive); above
  :data:`MAX_CHI2_PER_DOF` the residuals are larger than the model allows (a lever arm, a
  heading noisier than assumed, outliers);
* **agreement** (joint and whole methods): groups of consecutive segments each give theta,
  and a χ² test tells whether they differ from the whole log's by more than their σ allow
  (:mod:`graphcal.pipeline.methods.agreement`); where they do, the σ was already scaled by their
  scatter before the verdicts, so it is reported, not judged here. (The joint method's
  batch spread, the interquartile range of the batch estimates over the median per-batch
  σ, about 1.35 for honest σ and independent batches, is reported as ``spread_ratio``);
* **spread** (joint method): that ratio above :data:`MAX_SPREAD_RATIO` — one-sided, since
  batches that share segments make it smaller — the batches disagree beyond their σ;
* **validation**: the calibrated parameters (the others at their nominal) predict the
  validation segments worse than the nominal theta: each segment's error with one theta
  less the other's, larger on average by more than :data:`VALIDATION_WORSE_Z` standard
  errors of that mean. A segment's error holds its fixes' own error, the same for both
  thetas and not cancelled when the fixes err alike for tens of seconds: a delivery robot's
  200 m with fixes sharing 1.1 m of error over 44 s validated 0.11 m worse calibrated on 5
  segments whose differences scatter by 0.37 m, and was called untrusted for it. The
  standard error also holds what the calibration's own σ moves its validation error by
  (the only part there is with fewer than three segments): graphcal's skid-steer robot on
  one 106 m segment validated 2.55 m with c_e and t_r calibrated beside c_d at its nominal
  (0.31 ± 0.49 mm estimated, 0.30 true), 2.45 m with the nominal theta.

A parameter that fails a check is not reported as calibrated: its verdict says why, the run
is marked untrusted in ``calibration.json`` and ``graphcal calibrate`` exits with status
:data:`EXIT_UNTRUSTED`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from graphcal.graph.optimization.solve_options import SolveOutcome
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.methods.agreement import Agreement
from graphcal.statistics import student_t_quantile

#: χ² per degree of freedom above which the residuals do not fit the noise model: the σ
#: would be understated by more than sqrt(1.5) = 1.22 (statistical noise on the whole-log
#: solve's tens of thousands of degrees of freedom is about 0.01).
MAX_CHI2_PER_DOF = 1.5
#: Exit status of ``graphcal calibrate`` when the result is written but not to be trusted.
EXIT_UNTRUSTED = 3
#: Normal distribution's interquartile range in units of its σ.
NORMAL_IQR = 1.349
#: Relative difference between the calibrated c_e and the vehicle's nominal above which
#: graphcal names the likely causes. Tyre wear, pressure and load move the effective
#: circumference by 1–2 %; a wheel speed converted with another circumference than the
#: ECU's, a speed unit or a tick count that is off move it by far more.
MAX_C_E_DEVIATION = 0.03


@dataclass(frozen=True)
class TrustAssessment:
    """The checks of the module docstring and what they found.

    Attributes:
        converged: the whole-log solve stopped before its iteration limit.
        iterations, max_iterations: of the whole-log solve.
        chi2_per_dof: its χ² per degree of freedom (``None`` if unknown).
        spread_ratio: ``(4,)`` batch IQR / median batch σ per parameter, or ``None``
            without batches with σ (reported, not judged).
        agreement: the segments' agreement test, or ``None`` where it was not run.
        validates_worse: the calibrated theta validates worse than the nominal one.
        parameter_doubts: per parameter, why it is not to be trusted (absent if it is).
        doubts: the run-level reasons, one line each.
    """

    converged: bool
    iterations: int
    max_iterations: int
    chi2_per_dof: float | None
    spread_ratio: np.ndarray | None
    agreement: Agreement | None
    validates_worse: bool
    parameter_doubts: dict[str, str]
    doubts: tuple[str, ...]

    @property
    def trusted(self) -> bool:
        """True if no check failed."""
        return not self.doubts

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json``."""
        return {
            "trusted": self.trusted,
            "converged": self.converged,
            "iterations": self.iterations,
            "max_iterations": self.max_iterations,
            "chi2_per_dof": self.chi2_per_dof,
            "max_chi2_per_dof": MAX_CHI2_PER_DOF,
            "spread_ratio": None
            if self.spread_ratio is None
            else {
                n: (float(r) if np.isfinite(r) else None)
                for n, r in zip(PARAMETER_NAMES, self.spread_ratio, strict=True)
            },
            "max_spread_ratio": MAX_SPREAD_RATIO,
            "agreement": None if self.agreement is None else self.agreement.to_dict(),
            "validates_worse_than_nominal": self.validates_worse,
            "doubts": list(self.doubts),
        }


def spread_ratio(batch_theta: np.ndarray, batch_covariance: np.ndarray) -> np.ndarray | None:
    """IQR of the batch estimates over their median σ, per parameter ``(4,)``; ``None`` with
    fewer than 8 usable batches (rows with NaN are left out)."""
    theta = np.asarray(batch_theta, float)
    sigma = np.sqrt(np.abs(np.diagonal(np.asarray(batch_covariance, float), axis1=1, axis2=2)))
    usable = np.all(np.isfinite(theta), axis=1) & np.all(np.isfinite(sigma), axis=1)
    if usable.sum() < 8:
        return None
    q75, q25 = np.percentile(theta[usable], [75, 25], axis=0)
    return (q75 - q25) / np.median(sigma[usable], axis=0)


#: Standard errors of the mean paired difference by which the calibrated theta's validation
#: errors must exceed the nominal's to count as worse.
VALIDATION_WORSE_Z = 2.0


def validates_worse(
    calibrated: np.ndarray | float, nominal: np.ndarray | float, theta_spread: float = 0.0
) -> bool:
    """Whether the validation errors [m] per segment of the calibrated theta exceed the
    nominal theta's by more than :data:`VALIDATION_WORSE_Z` standard errors of their mean
    paired difference: the segments' scatter (two or more segments) and ``theta_spread``
    [m], the σ of the mean error that the calibration's own σ makes
    (:func:`~graphcal.pipeline.methods.validation.position_error_spread`). A scatter read
    from few segments is itself uncertain: the limit is Student's t at the same false-alarm
    rate (t₂ 4.5 from three segments, t₁ 14 from two: a robot's two validation segments
    under fixes of 1.7 m, 3.39 m against 3.22 m, were "not to be trusted" on any amount
    worse; campaign seed 42's shape 14)."""
    difference = np.atleast_1d(np.asarray(calibrated, float) - np.asarray(nominal, float))
    difference = difference[np.isfinite(difference)]
    if len(difference) == 0:
        return False
    mean = float(np.mean(difference))
    variance = theta_spread**2 if np.isfinite(theta_spread) else 0.0
    limit = VALIDATION_WORSE_Z
    if len(difference) >= 2:
        n = len(difference)
        scatter = float(np.var(difference, ddof=1)) / n
        variance += scatter
        # the scatter read from n segments: Student's t of its (Welch–Satterthwaite) degrees
        # of freedom at the normal quantile's false-alarm rate (3 segments: 4.5, not 2)
        dof = variance**2 / (scatter**2 / (n - 1)) if scatter > 0 else math.inf
        limit = student_t_quantile(NormalDist().cdf(VALIDATION_WORSE_Z), dof)
    return bool(mean > limit * np.sqrt(variance))


@dataclass(frozen=True)
class ValidationErrors:
    """The validation's position errors E_p [m] of the calibrated and the nominal theta,
    per validation segment (or their means), and ``theta_spread`` [m], the σ of the
    calibrated theta's mean error that its own σ makes (:func:`validates_worse`)."""

    calibrated: np.ndarray | float
    nominal: np.ndarray | float
    theta_spread: float = 0.0

    @property
    def worse(self) -> bool:
        """The calibrated theta validates worse than the nominal (:func:`validates_worse`)."""
        return validates_worse(self.calibrated, self.nominal, self.theta_spread)


def assess_trust(
    *,
    solve: SolveOutcome | None,
    chi2_per_dof: float | None,
    batch_theta: np.ndarray | None,
    batch_covariance: np.ndarray | None,
    calibrated: np.ndarray,
    validation: ValidationErrors,
    agreement: Agreement | None = None,
) -> TrustAssessment:
    """Run the checks of the module docstring.

    Args:
        solve: how the whole-log solve ended (its status and iterations; ``None``: there
            was none).
        chi2_per_dof: its χ² per degree of freedom.
        batch_theta, batch_covariance: per-batch estimates ``(B, 4)`` and covariances
            ``(B, 4, 4)`` of the joint method (``None`` without batches).
        calibrated: ``(4,)`` the parameters the data determined (observability); the
            agreement of the others is not judged.
        validation: the validation errors of both thetas.
        agreement: the segments' agreement test (``None``: not run).
    """
    ratio = None
    if batch_theta is not None and batch_covariance is not None:
        ratio = spread_ratio(batch_theta, batch_covariance)
    worse = validation.worse
    findings = [
        _convergence(solve),
        _fit(chi2_per_dof),
        _spread(ratio, calibrated),
        _validation(
            worse, float(np.mean(validation.calibrated)), float(np.mean(validation.nominal))
        ),
    ]
    parameter_doubts: dict[str, str] = {}
    for _, reasons in findings:
        for name, reason in reasons.items():
            parameter_doubts.setdefault(name, reason)  # the first check's reason
    return TrustAssessment(
        converged=solve is None or solve.converged,
        iterations=0 if solve is None else solve.iterations,
        max_iterations=1 if solve is None else solve.max_iterations,
        chi2_per_dof=chi2_per_dof,
        spread_ratio=ratio,
        agreement=agreement,
        validates_worse=worse,
        parameter_doubts=parameter_doubts,
        doubts=tuple(doubt for doubt, _ in findings if doubt is not None),
    )


#: A check's finding: the run-level doubt (``None``: passed) and why each parameter it
#: concerns is not to be trusted.
_Finding = tuple[str | None, dict[str, str]]

#: Batch IQR over median batch σ above which the batches disagree beyond their σ (about 1.35
#: when σ is honest and the batches independent; batches sharing segments make it smaller,
#: so a ratio above this is disagreement, one below it proves nothing).
MAX_SPREAD_RATIO = 2.5


def _spread(ratio: np.ndarray | None, calibrated: np.ndarray) -> _Finding:
    """The joint method's batches of the calibrated parameters disagree no more than their σ
    allows. One-sided: the segments' agreement test is the test of the σ; this catches what
    a bias common to every group of segments hides from it (slow wheel slip without the
    defect model: c_d −5.4σ off with the groups agreeing, batches spread 5× their σ)."""
    if ratio is None:
        return None, {}
    spread = [
        (name, float(r))
        for name, r, ok in zip(PARAMETER_NAMES, ratio, calibrated, strict=True)
        if ok and np.isfinite(r) and r > MAX_SPREAD_RATIO
    ]
    if not spread:
        return None, {}
    listed = ", ".join(f"{name} {r:.1f}×" for name, r in spread)
    return (
        f"the batches disagree far more than their σ allows (IQR over median σ: "
        f"{listed}; about {NORMAL_IQR:.2f} when σ is honest, limit {MAX_SPREAD_RATIO:g})",
        {name: f"batches spread {r:.1f}× their σ" for name, r in spread},
    )


def _convergence(solve: SolveOutcome | None) -> _Finding:
    """The whole-log solve converged (its status, not its iteration count)."""
    if solve is None or solve.converged:
        return None, {}
    return (
        f"the whole-log solve {solve.message}",
        dict.fromkeys(PARAMETER_NAMES, "the solve did not converge"),
    )


def _fit(chi2_per_dof: float | None) -> _Finding:
    """The residuals fit the noise model (χ² test)."""
    if chi2_per_dof is None or not chi2_per_dof > MAX_CHI2_PER_DOF:  # NaN passes
        return None, {}
    return (
        f"the residuals do not fit the noise model: χ²/dof = {chi2_per_dof:.2f} (about 1 "
        f"when they do; limit {MAX_CHI2_PER_DOF:g}): a defect the model does not cover "
        "(lever arm, latency, outliers, a noisier heading) or noise levels set too low",
        dict.fromkeys(PARAMETER_NAMES, f"residuals {chi2_per_dof:.1f}× the noise model"),
    )


def _validation(validates_worse: bool, calibrated: float, nominal: float) -> _Finding:
    """The calibrated theta validates no worse than the nominal one."""
    if not validates_worse:
        return None, {}
    return (
        f"the calibrated theta validates worse than the nominal one "
        f"({calibrated:.2f} m vs {nominal:.2f} m)",
        dict.fromkeys(PARAMETER_NAMES, "validates worse than nominal"),
    )


def circumference_warning(c_e: float, nominal_c_e: float) -> str | None:
    """One line when the calibrated ``c_e`` [m] lies more than :data:`MAX_C_E_DEVIATION`
    from the vehicle's ``nominal_c_e`` [m], naming what usually puts it there; else None.

    The value may be right (a profile for another vehicle), so this is a warning, not a
    doubt: the wheel rotations are scaled by what the recording declared, and c_e absorbs
    any error in that scale one to one.
    """
    deviation = c_e / nominal_c_e - 1.0
    if not np.isfinite(deviation) or abs(deviation) <= MAX_C_E_DEVIATION:
        return None
    return (
        f"c_e = {c_e:.4f} m is {deviation:+.1%} from the vehicle's nominal {nominal_c_e:g} m, "
        "more than tyres explain: check the scale of the wheel rotations — for wheel speeds "
        "the manifest's `circumference` (the one the ECU used) and `speed_unit`, for tick "
        "counters `ticks_per_revolution` — or the vehicle profile (`theta_nominal`)"
    )
