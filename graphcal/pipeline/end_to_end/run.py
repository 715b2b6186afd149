"""End-to-end calibration of one drive log: segments → selection → method → validation.

Methods:

* ``"staged"`` — the paper's five steps over batches (:mod:`graphcal.pipeline.methods.staged`); the
  recommended theta is the median of Step 5 over the batches. When the joint settings model
  the sensors (a time offset, a lever arm, outlying fixes: the defaults do), the joint
  whole-log solve runs first and the steps calibrate from the log it corrected.
* ``"joint"`` — one joint graph per batch (:mod:`graphcal.pipeline.solvers.joint`): start poses,
  wheel-rotation corrections and theta solved together, each with its marginal covariance and
  observability verdict; the recommended theta is the joint solve over *all* selected
  segments at once (the maximum-likelihood estimate from all the data, with its covariance).
  The batches show the spread and check the covariance; batches where a parameter is not
  observable are left out of the batch statistics, with the reason. By default the batches
  are solved from each segment's system at the whole-log solution
  (:mod:`graphcal.pipeline.methods.joint_batches`), at the cost of one whole-log iteration.
* ``"whole"`` — only the joint solve over all selected segments: quick, no batches.

With the joint and whole methods, every parameter is its posterior under the weak prior,
and those the data do not determine well (:mod:`graphcal.graph.solution.observability`) are reported
as not calibrated, with their estimate and σ. If fewer than
:data:`~graphcal.pipeline.methods.selection.MIN_SELECTED_SEGMENTS` segments pass the yaw-rate
selection they use every segment: the observability check, not the selection, then decides
what the drive determines.

Each method is one function (``_run_staged``, ``_run_joint``, ``_run_whole``):
:func:`~graphcal.pipeline.methods.prepare.prepare_log` (selection, the settings the log completes,
fix weights), the whole-log solve (:func:`~graphcal.pipeline.methods.whole_log.solve_whole_log`),
the method's batches, then validation and the trust checks
(:func:`~graphcal.pipeline.end_to_end.calibration_run.validated_run`).

Validation (§5.2): every theta is judged by its position error E_p (eq. 16 / K, averaged over
the 300 m validation segments), next to the nominal theta of ``settings.vehicle``, whose c_e
also turns wheel rotations into the distances segments are cut by. Comparison with a known truth
(synthetic drives) is :func:`graphcal.evaluation.evaluate`, apart from calibration.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import make_batches
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.calibration_run import (
    CalibrationRun,
    Method,
    MethodResult,
    validated_run,
)
from graphcal.pipeline.methods.batch_study import joint_batch_study
from graphcal.pipeline.methods.model_check import (
    ModelCheck,
    check_model,
    theta_alone,
    with_the_other_model,
)
from graphcal.pipeline.methods.prepare import PreparedLog, prepare_log
from graphcal.pipeline.methods.staged import run_staged
from graphcal.pipeline.methods.whole_log import WholeLog, models_sensors, solve_whole_log
from graphcal.progress import Progress, reports_progress, say

METHODS = ("staged", "joint", "whole")


@reports_progress
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
            (apply a vehicle with
            :func:`graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`).
        method: ``"staged"`` (the paper's five steps over batches), ``"joint"`` (one joint
            graph per batch, then one over all selected segments) or ``"whole"`` (only the
            joint solve over all selected segments; also what ``"joint"`` does with
            ``settings.batches.count`` 0).
        progress: called with one line per stage.
        workers: worker processes for batches and segments (results do not depend on it).

    Raises:
        NoUsableSegments: no segment passes the selection, or the log is too short.
        GraphcalError: the calibration failed.
    """
    settings = settings or Settings()
    if method not in METHODS:
        raise GraphcalError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    if settings.batches.count == 0:  # no batch study: the whole-log solve alone
        if method == "staged":
            raise GraphcalError(
                "[batches] count = 0 (one solve over the whole log) needs the joint or whole "
                "method; the staged method works on batches"
            )
        method = "whole"
    return _RUNS[method](log, settings, workers)


def _run_whole(log: DriveLog, settings: Settings, workers: int) -> CalibrationRun:
    """Only the joint solve over all selected segments: the recommended theta, checked by
    the segments' agreement, no batches."""
    prepared = prepare_log(log, settings, fall_back_to_all=True)
    solved, check = _solve_checked(prepared, workers)
    result = dataclasses.replace(_recommended(solved), model_check=check)
    return validated_run("whole", solved.corrected, solved, result, workers)


def _run_joint(log: DriveLog, settings: Settings, workers: int) -> CalibrationRun:
    """The joint solve over all selected segments (the recommended theta), checked by the
    segments' agreement, then the batch study from its solution
    (:mod:`graphcal.pipeline.methods.batch_study`)."""
    prepared = prepare_log(log, settings, fall_back_to_all=True)
    solved, check = _solve_checked(prepared, workers)
    recommended = dataclasses.replace(_recommended(solved), model_check=check)
    selected, size = len(solved.corrected.selected), settings.batches.size
    if selected <= size:  # one batch, all segments: the whole-log solve again, no spread
        say(
            f"only {selected} selected segments, no more than one batch of {size}: no batch "
            "study (the whole-log solve's σ and the segments' agreement stand)"
        )
        return validated_run("joint", solved.corrected, solved, recommended, workers)
    batches = _batches(solved.corrected, "joint", workers)
    study = joint_batch_study(solved, batches, workers)
    result = dataclasses.replace(
        recommended,
        warnings=[
            *recommended.warnings,
            *study.warnings,
            *_few_segments_warning(batches, solved.corrected),
        ],
        batches=batches,
        batch_theta=study.theta,
        batch_covariance=study.covariance,
        batch_excluded=study.excluded,
    )
    return validated_run("joint", solved.corrected, solved, result, workers)


def _run_staged(log: DriveLog, settings: Settings, workers: int) -> CalibrationRun:
    """The paper's five steps over batches (:mod:`graphcal.pipeline.methods.staged`) on the log the
    whole-log solve corrected, if the settings model the sensors; the recommended theta is
    the median of Step 5."""
    prepared = prepare_log(log, settings, fall_back_to_all=False)
    solved, check = _whole_log_corrections(prepared, workers)
    corrected = prepared if solved is None else solved.corrected
    batches = _batches(corrected, "staged", workers)
    staged = run_staged(corrected.data, batches, corrected.settings, workers)
    result = MethodResult(
        theta=staged.final_theta,
        warnings=[*staged.warnings, *_few_segments_warning(batches, corrected)],
        batches=batches,
        batch_theta=dict(staged.theta),
        staged=staged,
        model_check=check,
    )
    return validated_run("staged", corrected, solved, result, workers)


_RUNS: dict[str, Callable[[DriveLog, Settings, int], CalibrationRun]] = {
    "staged": _run_staged,
    "joint": _run_joint,
    "whole": _run_whole,
}


def _whole_log_corrections(
    prepared: PreparedLog, workers: int
) -> tuple[WholeLog | None, ModelCheck | None]:
    """The staged method's first step: when the joint settings model the sensors (a time
    offset, a lever arm, outlying fixes), the joint whole-log solve with its model check
    (:func:`_solve_checked`), whose estimates correct the log the five steps calibrate from;
    its theta is not the staged result, but the run reports the solve
    (``CalibrationRun.whole``) and the trust checks judge it. ``None`` otherwise."""
    if not models_sensors(prepared.settings.joint):
        return None, None
    solved, check = _solve_checked(prepared, workers)
    return solved, check


def _solve_checked(prepared: PreparedLog, workers: int) -> tuple[WholeLog, ModelCheck | None]:
    """The whole-log solve (:func:`~graphcal.pipeline.methods.whole_log.solve_whole_log`), then, if
    the settings ask for it and its defect model found something, the model check
    (:mod:`graphcal.pipeline.methods.model_check`): when theta alone predicts held-apart segments at
    least as well, the whole-log solve again without the defect model's sensor terms (or,
    where the defect model predicts best without slip, without slip)."""
    solved = solve_whole_log(prepared, workers)
    if not prepared.settings.joint.model_check:
        return solved, None
    check = check_model(prepared, solved, workers)
    if check is None:
        return solved, None
    say(check.line())
    if check.without_slip:
        joint = dataclasses.replace(prepared.settings.joint, slip="off")
        left_out = prepared.left_out
    elif check.theta_alone:
        joint, left_out = theta_alone(prepared.settings.joint), {}
    else:
        return solved, check
    simpler = dataclasses.replace(
        prepared, settings=dataclasses.replace(prepared.settings, joint=joint), left_out=left_out
    )
    chosen = solve_whole_log(simpler, workers)
    if check.theta_alone:
        chosen = with_the_other_model(chosen, solved)
    return chosen, check


def _recommended(solved: WholeLog) -> MethodResult:
    """The whole-log theta (every parameter its posterior under the weak prior), its
    marginal covariance and observability, with a warning naming what the data did not
    calibrate."""
    whole = solved.whole
    observability = whole.observability
    warnings = []
    if observability.degenerate:
        warnings.append(
            f"{', '.join(observability.not_calibrated)} not calibrated: "
            f"{observability.message()}; each reported at its estimate under the prior, "
            "with its σ"
        )
    return MethodResult(
        whole.theta, warnings, covariance=whole.covariance, observability=observability
    )


def _batches(prepared: PreparedLog, method: Method, workers: int) -> np.ndarray:
    """``(B, N)`` indices of the batches of the selected segments (fewer than N in a batch
    when fewer are selected)."""
    b, selected = prepared.settings.batches, prepared.selected
    size = min(b.size, len(selected))
    if size < b.size:
        say(f"only {len(selected)} segments: batches of {size} instead of {b.size}")
    batches = make_batches(len(selected), size, b.count, b.seed)
    if len(batches) < b.count and size == b.size:  # all distinct ones: a repeat adds nothing
        say(
            f"only {len(batches)} distinct batches of {size} of the {len(selected)} selected "
            f"segments: {len(batches)} instead of {b.count}"
        )
    say(
        f"{method}: {_plural(len(batches), 'batch', 'batches')} of {size} segments, "
        f"{_plural(workers, 'worker', 'workers')}"
    )
    return batches


def _few_segments_warning(batches: np.ndarray, prepared: PreparedLog) -> list[str]:
    """The warning that ``batches`` hold no more than the set number of segments (exactly
    that many: every batch is the same one, and its spread is 0)."""
    selected, wanted = len(prepared.selected), prepared.settings.batches.size
    if selected > wanted:
        return []
    count, size = batches.shape
    return [
        f"only {selected} selected segments: {_plural(count, 'batch', 'batches')} of "
        f"{size}"
        + (f" instead of {wanted}" if size < wanted else "")
        + (
            "; every batch shares most segments, so spreads understate the uncertainty"
            if count > 1
            else "; one batch has no spread to report"
        )
    ]


def _plural(count: int, one: str, many: str) -> str:
    """``"1 batch"``, ``"3 batches"``."""
    return f"{count} {one if count == 1 else many}"
