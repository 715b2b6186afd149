"""The joint method's batch study: each batch's Step 1 baseline and joint estimate (with its
covariance and verdict), and which batches the statistics leave out and why.

The batches solve the log the whole-log solve corrected
(:mod:`graphcal.pipeline.methods.whole_log`), with its fix weights and slip verdict, from its
solution: Step 1 (no time-offset or lever-arm variable) the exactly corrected segments, the joint
batches the wheels shifted by whole samples with the rest of the offset as their prior, the lever
arm a variable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.pipeline.methods.joint_batches import (
    BatchEstimate,
    linearized_batches,
    solve_joint_batches,
)
from graphcal.pipeline.methods.staged import step1_thetas
from graphcal.pipeline.methods.whole_log import WholeLog


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


def joint_batch_study(solved: WholeLog, batches: np.ndarray, workers: int) -> BatchStudy:
    """Step 1 and the joint solve of each of the ``batches`` ``(B, N)`` of the selected
    segments of ``solved``, the linearized ones from its segments' systems at its solution
    (:attr:`~graphcal.pipeline.methods.whole_log.WholeLog.systems`)."""
    corrected = solved.corrected
    settings = corrected.settings
    step1 = step1_thetas(corrected.data, batches, settings, workers)
    warnings = []
    step1_failed = int((~np.all(np.isfinite(step1), axis=1)).sum())
    if step1_failed:
        warnings.append(
            f"step1: {step1_failed} of {len(batches)} batch solves of the Step 1 "
            "baseline failed and are left out of its statistics"
        )
    if settings.batches.joint_solve == "linearized":
        estimates = linearized_batches(solved.systems, batches, solved.batch_settings())
    else:
        estimates = solve_joint_batches(
            solved.batch_data(), batches, solved.batch_settings(), "exact", workers=workers
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
