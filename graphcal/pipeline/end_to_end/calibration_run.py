"""The result of a calibration run: what a method found (:class:`MethodResult`), validated on
the validation segments and judged by the trust checks into a :class:`CalibrationRun`."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from graphcal.graph.solution.observability import Observability
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, Segments
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.trust import (
    TrustAssessment,
    ValidationErrors,
    assess_trust,
    circumference_warning,
)
from graphcal.pipeline.methods.model_check import ModelCheck
from graphcal.pipeline.methods.prepare import PreparedLog
from graphcal.pipeline.methods.sensor_estimates import DownWeightedFixes, SensorEstimate
from graphcal.pipeline.methods.staged import StagedResult
from graphcal.pipeline.methods.validation import position_error_spread, position_errors
from graphcal.pipeline.methods.whole_log import WholeLog
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.progress import say

Method = Literal["staged", "joint", "whole"]


@dataclass(frozen=True)
class CalibrationRun:
    """Everything a calibration run produced (SI).

    Attributes:
        log, settings, method: what was run.
        segments: all calibration segments; ``selected`` those passing the selection.
        yaw_rate: the selection statistic of every calibration segment [rad/s].
        data: the selected segments' signals.
        theta: the recommended theta.
        batches: ``(B, N)`` segment indices of the batches (``None`` for ``"whole"``).
        batch_theta: per step or method (``"step1"``, ``"step3"``, ``"step5"``; ``"joint"``;
            ``"whole"``), theta of each batch ``(B, 4)``; NaN rows for failed solves.
        batch_covariance: per method that reports one (``"joint"``), the marginal covariance
            of each batch's theta ``(B, 4, 4)``; NaN for failed solves.
        batch_excluded: per method, why each batch is left out of the statistics (``""``
            if it is not): a failed solve or parameters the batch does not determine.
        covariance: covariance of the recommended theta (joint and whole methods), ``(4, 4)``.
        observability: what the data determined about the recommended theta (joint, whole).
        staged: the five steps' results (``method == "staged"``).
        validation_segments, validation: the validation segments and their signals.
        segment_errors: per validation segment, mean position error [m] of odometry with
            ``"nominal"`` and ``"calibrated"`` theta.
        batch_errors: per step, E_p [m] of each batch's theta, ``(B,)``; NaN where the batch
            failed (never written to a file).
        warnings: what a user must know before trusting the result.
        trust: the checks that need no truth (:mod:`graphcal.pipeline.end_to_end.trust`).
        estimated: sensor quantities the whole-log solve estimated with theta
            (``"time_offset"`` [s], ``"lever_arm_longitudinal"``, ``"lever_arm_lateral"``
            [m]; :mod:`graphcal.pipeline.methods.sensor_estimates`); observable ones are corrected
            in ``log`` for the batches and the validation.
        down_weighted: the fixes the robust whole-log solve down-weighted as outliers.
        whole: the whole-log joint solve (joint and whole methods, and staged when it
            estimates sensor quantities or outliers), ``None`` otherwise.
        model_check: the defect model against theta alone on held-apart segments
            (:mod:`graphcal.pipeline.methods.model_check`), ``None`` when not run.
    """

    log: DriveLog
    settings: Settings
    method: Method
    segments: Segments
    selected: Segments
    yaw_rate: np.ndarray
    data: SegmentData
    theta: np.ndarray
    batches: np.ndarray | None
    batch_theta: dict[str, np.ndarray]
    batch_covariance: dict[str, np.ndarray]
    staged: StagedResult | None
    validation_segments: Segments
    validation: SegmentData
    segment_errors: dict[str, np.ndarray]
    batch_errors: dict[str, np.ndarray]
    batch_excluded: dict[str, np.ndarray]
    warnings: tuple[str, ...] = ()
    covariance: np.ndarray | None = None
    observability: Observability | None = None
    trust: TrustAssessment | None = None
    estimated: dict[str, SensorEstimate] = field(default_factory=dict)
    down_weighted: DownWeightedFixes | None = None
    whole: JointCalibration | None = None
    model_check: ModelCheck | None = None

    def verdicts(self) -> dict[str, str]:
        """Per parameter: the observability verdict, or why it is not to be trusted
        (:mod:`graphcal.pipeline.end_to_end.trust`)."""
        out = self.observability.verdicts() if self.observability is not None else {}
        doubts = self.trust.parameter_doubts if self.trust is not None else {}
        for name in PARAMETER_NAMES:
            if name in doubts and out.get(name, "calibrated").startswith("calibrated"):
                out[name] = f"not trusted: {doubts[name]}"
            out.setdefault(name, "calibrated")
        return out

    def batch_estimates(self, name: str) -> np.ndarray:
        """Per-batch thetas ``(B, 4)`` of step or method ``name`` with failed and excluded
        batches as NaN rows: what statistics and figures summarize."""
        return without_excluded(self.batch_theta[name], self.batch_excluded.get(name))

    def validation_error(self, name: str) -> float:
        """E_p [m] of ``"nominal"`` or ``"calibrated"`` theta."""
        return float(np.mean(self.segment_errors[name]))


def without_excluded(thetas: np.ndarray, reasons: np.ndarray | None) -> np.ndarray:
    """``thetas`` ``(B, 4)`` with the rows of excluded batches (a non-empty reason) as NaN."""
    out = np.array(thetas, dtype=float)
    if reasons is not None:
        out[np.asarray(reasons) != ""] = np.nan
    return out


@dataclass(frozen=True)
class MethodResult:
    """What a method found, before validation; the fields are :class:`CalibrationRun`'s."""

    theta: np.ndarray
    warnings: list[str]
    batches: np.ndarray | None = None
    batch_theta: dict[str, np.ndarray] = field(default_factory=dict)
    batch_covariance: dict[str, np.ndarray] = field(default_factory=dict)
    batch_excluded: dict[str, np.ndarray] = field(default_factory=dict)
    staged: StagedResult | None = None
    covariance: np.ndarray | None = None
    observability: Observability | None = None
    model_check: ModelCheck | None = None


def validated_run(
    method: Method,
    corrected: PreparedLog,
    solved: WholeLog | None,
    result: MethodResult,
    workers: int = 1,
) -> CalibrationRun:
    """The run: ``result`` validated on the validation segments of ``corrected`` (the log
    the method calibrated from; the batches' thetas in ``workers`` threads), judged
    (:mod:`graphcal.pipeline.end_to_end.trust`), with every warning said."""
    validation, settings = corrected.validation, corrected.settings
    segment_errors = {
        "nominal": position_errors(validation, settings.vehicle.theta_nominal),
        "calibrated": position_errors(validation, result.theta),
    }
    batch_errors = _batch_errors(validation, result, workers)
    whole = None if solved is None else solved.whole
    trust = _trust(solved, result, segment_errors, validation, settings.vehicle.theta_nominal)
    warnings = [
        *corrected.warnings,
        *result.warnings,
        *(f"not to be trusted: {doubt}" for doubt in trust.doubts),
        *_closing_warnings(result, batch_errors, settings),
    ]
    for line in warnings:
        say(f"warning: {line}")
    say(f"validated on {len(validation)} {settings.segments.validation_length:g} m segments")
    return CalibrationRun(
        log=corrected.log,
        settings=settings,
        method=method,
        segments=corrected.segments,
        selected=corrected.selected,
        yaw_rate=corrected.yaw_rate,
        data=corrected.data,
        theta=result.theta,
        batches=result.batches,
        batch_theta=result.batch_theta,
        batch_covariance=result.batch_covariance,
        staged=result.staged,
        validation_segments=corrected.validation_segments,
        validation=validation,
        segment_errors=segment_errors,
        batch_errors=batch_errors,
        batch_excluded=result.batch_excluded,
        warnings=tuple(warnings),
        trust=trust,
        estimated={} if solved is None else solved.estimated,
        down_weighted=None if solved is None else solved.down_weighted,
        whole=whole,
        covariance=result.covariance,
        observability=result.observability,
        model_check=result.model_check,
    )


def _batch_errors(
    validation: SegmentData, result: MethodResult, workers: int = 1
) -> dict[str, np.ndarray]:
    """Per step or method, E_p [m] of each batch's theta (the position error of eq. 16 / K
    averaged over the validation segments); NaN for failed or excluded ones. The thetas in
    ``workers`` threads, a share each: numpy's integration releases the GIL, and each theta
    is independent of the others (the same errors whatever the count)."""
    names = list(result.batch_theta)
    thetas = [
        without_excluded(result.batch_theta[name], result.batch_excluded.get(name))
        for name in names
    ]
    every = np.concatenate(thetas) if thetas else np.empty((0, 4))
    errors = np.full(len(every), np.nan)
    finite = np.flatnonzero(np.all(np.isfinite(every), axis=1))
    shares = [s for s in np.array_split(finite, max(1, min(workers, len(finite)))) if len(s)]

    def mean_errors(share: np.ndarray) -> np.ndarray:
        return position_errors(validation, every[share]).mean(axis=1)

    if len(shares) > 1:
        with ThreadPoolExecutor(len(shares)) as pool:
            means = list(pool.map(mean_errors, shares))
    else:
        means = [mean_errors(share) for share in shares]
    for share, mean in zip(shares, means, strict=True):
        errors[share] = mean
    bounds = np.cumsum([0, *(len(block) for block in thetas)])
    return {name: errors[a:b] for name, a, b in zip(names, bounds[:-1], bounds[1:], strict=True)}


def _trust(
    solved: WholeLog | None,
    result: MethodResult,
    segment_errors: dict[str, np.ndarray],
    validation: SegmentData,
    theta_nominal: np.ndarray,
) -> TrustAssessment:
    """The trust checks (:func:`~graphcal.pipeline.end_to_end.trust.assess_trust`) of the whole-log
    solve (if any), the joint batches (if any) and the validation. The validation check
    judges what is called calibrated and what the data moved: a parameter not calibrated
    keeps its nominal in it (a weakly determined c_d of a 100 m log, −4.3 ± 5.6 mm, moves the
    prediction by noise, and that is what its verdict and σ already say) unless its
    estimate lies more than :data:`MOVED_SIGMAS` σ from the nominal (a skid-steer robot's
    weakly determined t_r of 1.11 ± 0.035 m against a geometric 0.55 m: with the nominal
    t_r, its calibrated c_d validated 2 m worse than the nominal theta, with the estimate
    2.6 m against 16.7 m)."""
    whole = None if solved is None else solved.whole
    calibrated, nominal = segment_errors["calibrated"], segment_errors["nominal"]
    claimed = result.theta
    if result.observability is not None and not result.observability.calibrated.all():
        kept = result.observability.calibrated | _moved_from_nominal(
            result.theta, result.covariance, theta_nominal
        )
        claimed = np.where(kept, result.theta, theta_nominal)
        calibrated = position_errors(validation, claimed)
    batch_theta = None
    if "joint" in result.batch_covariance:
        batch_theta = without_excluded(
            result.batch_theta["joint"], result.batch_excluded.get("joint")
        )
    observability = result.observability
    return assess_trust(
        solve=whole.outcome if whole is not None else None,
        chi2_per_dof=whole.chi2_per_dof if whole is not None else None,
        batch_theta=batch_theta,
        batch_covariance=result.batch_covariance.get("joint"),
        calibrated=observability.calibrated if observability is not None else np.ones(4, bool),
        agreement=None if solved is None else solved.agreement,
        validation=ValidationErrors(
            calibrated, nominal, position_error_spread(validation, claimed, result.covariance)
        ),
    )


#: A parameter whose estimate lies more than this many of its σ from the nominal was moved
#: by the data (issue 43: the nominal is then not what graphcal stands for).
MOVED_SIGMAS = 2.0


def _moved_from_nominal(
    theta: np.ndarray, covariance: np.ndarray | None, theta_nominal: np.ndarray
) -> np.ndarray:
    """``(4,)`` True where ``theta`` lies more than :data:`MOVED_SIGMAS` of its marginal σ
    (``covariance`` ``(4, 4)`` [SI]; none: nowhere) from ``theta_nominal``."""
    if covariance is None:
        return np.zeros(len(theta), bool)
    sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        moved = np.abs(np.asarray(theta) - theta_nominal) > MOVED_SIGMAS * sigma
    return moved & (sigma > 0.0) & np.isfinite(sigma)


def _closing_warnings(
    result: MethodResult, batch_errors: dict[str, np.ndarray], settings: Settings
) -> list[str]:
    """A calibrated circumference far from the vehicle's, and a Step 5 that validates worse
    than Step 1."""
    warnings = []
    scale = circumference_warning(float(result.theta[0]), float(settings.vehicle.theta_nominal[0]))
    if scale is not None:
        warnings.append(scale)
    solved_errors = {k: e[np.isfinite(e)] for k, e in batch_errors.items()}
    if result.staged is not None and len(solved_errors["step1"]) and len(solved_errors["step5"]):
        first, last = np.median(solved_errors["step1"]), np.median(solved_errors["step5"])
        if last > first:
            warnings.append(
                f"Step 5 validates worse than Step 1 (median {last:.2f} m vs {first:.2f} m): "
                "too little data for the compensation; try --method joint or a longer drive"
            )
    return warnings
