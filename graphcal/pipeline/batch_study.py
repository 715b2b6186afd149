"""The joint method's batch study: each batch's Step 1 baseline and joint estimate (with its
covariance and verdict), and which batches the statistics leave out and why.

The batches solve the log the whole-log solve corrected (:mod:`graphcal.pipeline.whole_log`),
with its fix weights and slip verdict, from its solution: Step 1 (no time-offset or lever-arm
variable) the exactly corrected segments, the joint batches the wheels shifted by whole
samples with the rest of the offset as their prior, the lever arm a variable.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.log.timing import whole_samples
from graphcal.pipeline.joint_batches import BatchEstimate, solve_joint_batches
from graphcal.pipeline.sensor_estimates import SensorEstimate, run_of
from graphcal.pipeline.staged import step1_thetas
from graphcal.pipeline.whole_log import WholeLog


@dataclass(frozen=True)
class BatchStudy:
    """The joint method's batches (SI).

    Attributes:
        theta: per method (``"step1"``, ``"joint"``), theta of each batch ``(B, 4)``; NaN
            rows for failed solves.
        covariance: ``"joint"``: the marginal covariance of each batch's theta ``(B, 4, 4)``;
            NaN for failed solves.
        excluded: per method, why each batch is left out of the statistics (``""`` if it is
            not); Step 1 leaves out the joint method's, to compare both on the same batches.
        warnings: the failed Step 1 solves and the reasons for leaving batches out.
    """

    theta: dict[str, np.ndarray]
    covariance: dict[str, np.ndarray]
    excluded: dict[str, np.ndarray]
    warnings: list[str]


def joint_batch_study(
    solved: WholeLog,
    batches: np.ndarray,
    values: gtsam.Values | None,
    workers: int,
) -> BatchStudy:
    """Step 1 and the joint solve of each of the ``batches`` ``(B, N)`` of the selected
    segments of ``solved``; ``values``: the whole-log solution the linearized joint batches
    start from (:func:`~graphcal.pipeline.joint_batches.solve_joint_batches`)."""
    corrected = solved.corrected
    settings = corrected.settings
    # The fixes weighted as the whole-log solve found: batches solve without robust rounds.
    batch_settings = dataclasses.replace(
        settings.joint,
        **_batch_time_offset(solved.estimated, corrected.log.dt),
        robust_threshold=0.0,
        slip="on" if solved.whole.slip_modelled else "off",
    )
    step1 = step1_thetas(corrected.data, batches, settings, workers)
    warnings = []
    step1_failed = int((~np.all(np.isfinite(step1), axis=1)).sum())
    if step1_failed:
        warnings.append(
            f"step1: {step1_failed} of {len(batches)} batch solves of the Step 1 "
            "baseline failed and are left out of its statistics"
        )
    estimates = solve_joint_batches(
        solved.batch_data(),
        batches,
        batch_settings,
        settings.batches.joint_solve,
        values,
        workers,
    )
    nan_theta, nan_matrix = np.full(4, np.nan), np.full((4, 4), np.nan)
    theta = np.array([nan_theta if r is None else r.theta for r in estimates])
    covariance = np.array([nan_matrix if r is None else r.covariance for r in estimates])
    reasons = np.array([exclusion_reason(r) for r in estimates], dtype=object)
    return BatchStudy(
        theta={"step1": step1, "joint": theta},
        covariance={"joint": covariance},
        # Step 1 is the baseline of the same batches: compare both on the batches kept.
        excluded={"joint": reasons, "step1": reasons},
        warnings=warnings + _exclusion_warnings(reasons),
    )


def exclusion_reason(result: BatchEstimate | None) -> str:
    """Why a batch's joint solve is left out of the batch statistics (``""``: it is not)."""
    if result is None:
        return "solve failed"
    if result.observability.degenerate:
        return "not observable: " + ", ".join(result.observability.not_calibrated)
    return ""


def _exclusion_warnings(reasons: np.ndarray) -> list[str]:
    """One warning per distinct reason for leaving batches out of the statistics."""
    out = []
    for reason in sorted(set(reasons) - {""}):
        count = int((reasons == reason).sum())
        out.append(
            f"{count} of {len(reasons)} joint batches left out of the batch statistics: {reason}"
        )
    if len(reasons) and all(reasons != ""):
        out.append("no joint batch determines every parameter; see the recommended theta's verdict")
    return out


def _batch_time_offset(estimated: dict[str, SensorEstimate], dt: float) -> dict:
    """The joint batches' time-offset prior: what the whole-log estimate of each run leaves
    beyond the whole-sample shift of its log, with their largest σ (no variable if the
    whole-log solve had none)."""
    found = [e for e in estimated.values() if run_of(e.name)[0] == "time_offset"]
    if not found:
        return {"time_offset_sigma": 0.0}
    rest = [e.value - (whole_samples(e.value, dt) if e.detected else 0.0) for e in found]
    return {"time_offset_sigma": max(e.sigma for e in found), "time_offset_means": tuple(rest)}
