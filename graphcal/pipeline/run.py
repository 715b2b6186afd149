"""End-to-end calibration of one drive log: segments → selection → method → validation.

Methods:

* ``"staged"`` — the paper's five steps over batches (:mod:`graphcal.pipeline.staged`); the
  recommended theta is the median of Step 5 over the batches. When the joint settings model
  the sensors (a time offset, a lever arm, outlying fixes: the defaults do), the joint
  whole-log solve runs first and the steps calibrate from the log it corrected.
* ``"joint"`` — one joint graph per batch (:mod:`graphcal.pipeline.joint`): start poses,
  wheel-rotation corrections and theta solved together, each with its marginal covariance and
  observability verdict; the recommended theta is the joint solve over *all* selected
  segments at once (the maximum-likelihood estimate from all the data, with its covariance).
  The batches show the spread and check the covariance; batches where a parameter is not
  observable are left out of the batch statistics, with the reason. By default the batches
  are solved from each segment's system at the whole-log solution
  (:mod:`graphcal.pipeline.joint_batches`), at the cost of one whole-log iteration.
* ``"whole"`` — only the joint solve over all selected segments: quick, no batches.

With the joint and whole methods, parameters the data do not determine
(:mod:`graphcal.graph.observability`) stay at their prior (the nominal value) and are
reported as not calibrated. If no segment passes the yaw-rate selection they use all
segments: the observability check, not the selection, then decides what the drive determines.

Each method is one function (``_run_staged``, ``_run_joint``, ``_run_whole``):
:func:`~graphcal.pipeline.prepare.prepare_log` (selection, the settings the log completes,
fix weights), the whole-log solve (:func:`~graphcal.pipeline.whole_log.solve_whole_log`), the
method's batches, then validation and the trust checks (``_validated``).

Validation (§5.2): every theta is judged by its position error E_p (eq. 16 / K, averaged over
the 300 m validation segments), next to the nominal theta of ``settings.vehicle``, whose c_e
also turns wheel rotations into the distances segments are cut by. Comparison with a known truth
(synthetic drives) is :func:`graphcal.evaluation.evaluate`, apart from calibration.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from graphcal.data.drive_log import DriveLog
from graphcal.data.segments import SegmentData, Segments, make_batches
from graphcal.errors import GraphcalError
from graphcal.graph.observability import Observability, condition_on_prior
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.batch_study import joint_batch_study
from graphcal.pipeline.joint import JointCalibration
from graphcal.pipeline.prepare import PreparedLog, prepare_log
from graphcal.pipeline.sensor_estimates import DownWeightedFixes, SensorEstimate
from graphcal.pipeline.settings import Settings
from graphcal.pipeline.staged import StagedResult, run_staged
from graphcal.pipeline.trust import TrustAssessment, assess_trust, circumference_warning
from graphcal.pipeline.validation import position_errors
from graphcal.pipeline.whole_log import WholeLog, models_sensors, solve_whole_log

Progress = Callable[[str], None]
Method = Literal["staged", "joint", "whole"]
METHODS = ("staged", "joint", "whole")


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
        trust: the checks that need no truth (:mod:`graphcal.pipeline.trust`).
        estimated: sensor quantities the whole-log solve estimated with theta
            (``"time_offset"`` [s], ``"lever_arm_longitudinal"``, ``"lever_arm_lateral"``
            [m]; :mod:`graphcal.pipeline.sensor_estimates`); observable ones are corrected
            in ``log`` for the batches and the validation.
        down_weighted: the fixes the robust whole-log solve down-weighted as outliers.
        whole: the whole-log joint solve (joint and whole methods, and staged when it
            estimates sensor quantities or outliers), ``None`` otherwise.
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

    def verdicts(self) -> dict[str, str]:
        """Per parameter: the observability verdict, or why it is not to be trusted
        (:mod:`graphcal.pipeline.trust`)."""
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


def mean_validation_error(validation: SegmentData, theta: np.ndarray) -> float:
    """E_p [m]: the position error of eq. (16) / K averaged over the validation segments."""
    if not np.all(np.isfinite(theta)):
        return float("nan")
    return float(np.mean(position_errors(validation, theta)))


def run_calibration(
    log: DriveLog,
    settings: Settings | None = None,
    method: Method = "joint",
    *,
    progress: Progress | None = None,
    workers: int = 1,
) -> CalibrationRun:
    """Calibrate theta from ``log``.

    Args:
        log: a validated drive log.
        settings: run settings (the paper's by default); ``settings.vehicle`` gives the
            nominal theta for cutting segments and for the "nominal" validation errors
            (apply a vehicle with :func:`graphcal.pipeline.vehicle_settings.apply_vehicle`).
        method: ``"staged"`` (the paper's five steps over batches), ``"joint"`` (one joint
            graph per batch, then one over all selected segments) or ``"whole"`` (only the
            joint solve over all selected segments).
        progress: called with one line per stage.
        workers: worker processes for batches and segments (results do not depend on it).

    Raises:
        NoUsableSegments: no segment passes the selection, or the log is too short.
        GraphcalError: the calibration failed.
    """
    settings = settings or Settings()
    say = progress or (lambda _line: None)
    if method not in METHODS:
        raise GraphcalError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    return _RUNS[method](log, settings, workers, say)


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


def _run_whole(log: DriveLog, settings: Settings, workers: int, say: Progress) -> CalibrationRun:
    """Only the joint solve over all selected segments: the recommended theta, no batches."""
    prepared = prepare_log(log, settings, say, fall_back_to_all=True)
    solved, _ = solve_whole_log(prepared, workers, say)
    return _validated("whole", solved.corrected, solved, _recommended(solved), say)


def _run_joint(log: DriveLog, settings: Settings, workers: int, say: Progress) -> CalibrationRun:
    """The joint solve over all selected segments (the recommended theta), then the batch
    study from its solution (:mod:`graphcal.pipeline.batch_study`)."""
    prepared = prepare_log(log, settings, say, fall_back_to_all=True)
    solved, values = solve_whole_log(prepared, workers, say, keep_values=True)
    recommended = _recommended(solved)
    batches = _batches(solved.corrected, "joint", workers, say)
    study = joint_batch_study(solved, batches, values, workers, say)
    del values  # the whole log's solution, most of the memory of a long log
    result = dataclasses.replace(
        recommended,
        warnings=recommended.warnings + study.warnings,
        batches=batches,
        batch_theta=study.theta,
        batch_covariance=study.covariance,
        batch_excluded=study.excluded,
    )
    return _validated("joint", solved.corrected, solved, result, say)


def _run_staged(log: DriveLog, settings: Settings, workers: int, say: Progress) -> CalibrationRun:
    """The paper's five steps over batches (:mod:`graphcal.pipeline.staged`) on the log the
    whole-log solve corrected, if the settings model the sensors; the recommended theta is
    the median of Step 5."""
    prepared = prepare_log(log, settings, say, fall_back_to_all=False)
    solved = _whole_log_corrections(prepared, workers, say)
    corrected = prepared if solved is None else solved.corrected
    batches = _batches(corrected, "staged", workers, say)
    staged = run_staged(corrected.data, batches, corrected.settings, workers, say)
    result = MethodResult(
        theta=staged.final_theta,
        warnings=list(staged.warnings),
        batches=batches,
        batch_theta=dict(staged.theta),
        staged=staged,
    )
    return _validated("staged", corrected, solved, result, say)


_RUNS: dict[str, Callable[[DriveLog, Settings, int, Progress], CalibrationRun]] = {
    "staged": _run_staged,
    "joint": _run_joint,
    "whole": _run_whole,
}


def _whole_log_corrections(prepared: PreparedLog, workers: int, say: Progress) -> WholeLog | None:
    """The staged method's first step: when the joint settings model the sensors (a time
    offset, a lever arm, outlying fixes), the joint whole-log solve
    (:func:`~graphcal.pipeline.whole_log.solve_whole_log`), whose estimates correct the log
    the five steps calibrate from; its theta is not the staged result, but the run reports
    the solve (``CalibrationRun.whole``) and the trust checks judge it. ``None`` otherwise."""
    if not models_sensors(prepared.settings.joint):
        return None
    solved, _ = solve_whole_log(prepared, workers, say)
    return solved


def _recommended(solved: WholeLog) -> MethodResult:
    """The whole-log theta with unobservable parameters at their prior, its covariance and
    observability, with a warning naming the parameters kept at the prior."""
    whole, settings = solved.whole, solved.corrected.settings.joint
    theta, covariance = condition_on_prior(
        whole.theta,
        whole.covariance,
        whole.observability.calibrated,
        settings.theta_initial,
        settings.theta_prior_sigmas,
    )
    observability = whole.observability
    warnings = []
    if observability.degenerate:
        warnings.append(
            f"{', '.join(observability.not_calibrated)} not calibrated: "
            f"{observability.message()}; kept at the prior (nominal) value"
        )
    return MethodResult(theta, warnings, covariance=covariance, observability=observability)


def _batches(prepared: PreparedLog, method: Method, workers: int, say: Progress) -> np.ndarray:
    """``(B, N)`` indices of the batches of the selected segments (fewer than N in a batch
    when fewer are selected)."""
    b, selected = prepared.settings.batches, prepared.selected
    size = min(b.size, len(selected))
    if size < b.size:
        say(f"only {len(selected)} segments: batches of {size} instead of {b.size}")
    batches = make_batches(len(selected), size, b.count, b.seed)
    say(
        f"{method}: {_plural(len(batches), 'batch', 'batches')} of {size} segments, "
        f"{_plural(workers, 'worker', 'workers')}"
    )
    return batches


def _validated(
    method: Method,
    corrected: PreparedLog,
    solved: WholeLog | None,
    result: MethodResult,
    say: Progress,
) -> CalibrationRun:
    """The run: ``result`` validated on the validation segments of ``corrected`` (the log
    the method calibrated from), judged (:mod:`graphcal.pipeline.trust`), with every warning
    said."""
    validation, settings = corrected.validation, corrected.settings
    segment_errors = {
        "nominal": position_errors(validation, settings.vehicle.theta_nominal),
        "calibrated": position_errors(validation, result.theta),
    }
    batch_errors = _batch_errors(validation, result)
    whole = None if solved is None else solved.whole
    trust = _trust(whole, settings, result, segment_errors)
    warnings = [
        *corrected.warnings,
        *result.warnings,
        *_few_segments_warning(result.batches, len(corrected.selected), settings),
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
    )


def _batch_errors(validation: SegmentData, result: MethodResult) -> dict[str, np.ndarray]:
    """Per step or method, E_p [m] of each batch's theta; NaN for failed or excluded ones."""
    return {
        name: np.array(
            [
                mean_validation_error(validation, t)
                for t in without_excluded(thetas, result.batch_excluded.get(name))
            ]
        )
        for name, thetas in result.batch_theta.items()
    }


def _trust(
    whole: JointCalibration | None,
    settings: Settings,
    result: MethodResult,
    segment_errors: dict[str, np.ndarray],
) -> TrustAssessment:
    """The trust checks (:func:`~graphcal.pipeline.trust.assess_trust`) of the whole-log
    solve (if any), the joint batches (if any) and the validation."""
    calibrated, nominal = np.mean(segment_errors["calibrated"]), np.mean(segment_errors["nominal"])
    joint_batches = "joint" in result.batch_covariance
    return assess_trust(
        iterations=whole.iterations if whole is not None else 0,
        max_iterations=settings.joint.max_iterations if whole is not None else 1,
        chi2_per_dof=whole.chi2_per_dof if whole is not None else None,
        batch_theta=without_excluded(
            result.batch_theta["joint"], result.batch_excluded.get("joint")
        )
        if joint_batches
        else None,
        batch_covariance=result.batch_covariance.get("joint"),
        calibrated=result.observability.calibrated
        if result.observability is not None
        else np.ones(4, bool),
        validation_calibrated=float(calibrated),
        validation_nominal=float(nominal),
    )


def _few_segments_warning(
    batches: np.ndarray | None, selected: int, settings: Settings
) -> list[str]:
    """The warning that batches hold fewer than the set number of segments."""
    if batches is None or selected >= settings.batches.size:
        return []
    count, size = batches.shape
    return [
        f"only {selected} selected segments: {_plural(count, 'batch', 'batches')} of "
        f"{size} instead of {settings.batches.size}"
        + (
            "; every batch shares most segments, so spreads understate the uncertainty"
            if count > 1
            else "; one batch has no spread to report"
        )
    ]


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


def _plural(count: int, one: str, many: str) -> str:
    """``"1 batch"``, ``"3 batches"``."""
    return f"{count} {one if count == 1 else many}"
