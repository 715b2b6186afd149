"""The paper's five-step calibration (§4.3, Fig. 3), each step a GTSAM graph solve.

1. Prior parameter estimation: a batch solve per batch, measured inputs, the first pose of each
   segment held at its measurement → theta_I.
2. Orientation correction: per segment of each batch, input estimation with theta_I;
   Δψ at k = 10 (eq. 15; see ``StagedSettings.heading_correction`` for the two forms).
3. Compensated parameter estimation: the batch solve with the corrected heading → theta_II.
4. Rotation input estimation: per segment, input estimation with 12 theta_II values (q_ψ = 10);
   the compensated rotations are the mean of the middle 80 % of the estimates.
5. Final parameter estimation: the batch solve with compensated rotations and corrected
   heading → theta_F. The recommended theta is the median of theta_F over the batches.

Batches and segments are independent tasks; they run in worker processes and come back in
order, so the result does not depend on the number of workers.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.log.segments import SegmentData
from graphcal.model import integrate
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.solvers.batch_calibration import (
    BatchSettings,
    calibrate_batch,
    held_start_batches,
)
from graphcal.pipeline.solvers.input_estimation import InputEstimationSettings, estimate_inputs
from graphcal.pipeline.solvers.parallel import map_tasks


@dataclass(frozen=True)
class StagedResult:
    """What the five steps produced (SI).

    Attributes:
        batches: ``(B, N)`` segment indices of each batch (into the selected segments).
        theta: ``{"step1"|"step3"|"step5": (B, 4)}``; rows of failed batches are NaN and
            marked in ``failed``.
        failed: ``{step: (B,) bool}`` batches whose solve failed.
        heading_correction: ``(B, N)`` Δψ [rad] of each segment of each batch (eq. 15).
        compensated_rotations: ``(S, K, 2)`` Step 4's compensated ``[n_rl, n_rr]`` per selected
            segment (padded like the segment data; measured values for unused segments).
        step4_estimates: the Step 4 estimates ``(E, K, 2)`` of ``example_segment``.
        example_segment: index of the segment whose estimates are kept (for Fig. 4).
        warnings: messages about steps that fell back (e.g. a failed input estimation).
    """

    batches: np.ndarray
    theta: dict[str, np.ndarray]
    failed: dict[str, np.ndarray]
    heading_correction: np.ndarray
    compensated_rotations: np.ndarray
    step4_estimates: np.ndarray
    example_segment: int
    warnings: list[str]

    @property
    def final_theta(self) -> np.ndarray:
        """The recommended theta: the median of Step 5 over the batches that solved."""
        good = self.theta["step5"][~self.failed["step5"]]
        if len(good) == 0:
            raise GraphcalError("every Step 5 batch solve failed; no calibration to report")
        return np.median(good, axis=0)


def _batch_task(data: SegmentData, settings: BatchSettings) -> tuple[np.ndarray, np.ndarray] | None:
    try:
        result = calibrate_batch(data, settings)
    except GraphcalError:
        return None
    return result.theta, result.start_states


def step1_thetas(
    data: SegmentData,
    batches: np.ndarray,
    settings: Settings,
    workers: int = 1,
) -> np.ndarray:
    """Step 1 alone: theta ``(B, 4)`` of each batch from the measured signals with the start
    poses held at their measurement; NaN rows for failed solves. The uncompensated baseline
    that the joint method is shown against."""
    if not settings.calibration.estimate_start_poses:
        try:
            return held_start_batches(data, batches, settings.calibration, workers)
        except GraphcalError:
            pass  # the solve over all segments failed: each batch its own, as they did
    tasks = [(data.take(batch), settings.calibration) for batch in batches]
    results = map_tasks(_batch_task, tasks, workers, "step1 batch solves")
    return np.array([np.full(4, np.nan) if r is None else r[0] for r in results])


def _heading_task(
    poses: np.ndarray,
    inputs: np.ndarray,
    theta: np.ndarray,
    settings: InputEstimationSettings,
    k: int,
    form: str,
) -> float | None:
    if not np.all(np.isfinite(theta)):
        return None
    try:
        estimate = estimate_inputs(poses, inputs, theta, settings)
    except GraphcalError:
        return None
    k = min(k, len(inputs))
    if form == "paper":  # eq. (15) verbatim
        return float(estimate.states[k, 2] - poses[k, 2])
    # The yaw the estimated inputs add over the first k steps corrects the start heading.
    nominal = integrate(poses[0], inputs[:k], theta)
    return float(estimate.states[k, 2] - nominal[k, 2])


def apply_heading_correction(poses: np.ndarray, correction: np.ndarray, form: str) -> np.ndarray:
    """Poses ``(..., K+1, 3)`` with heading corrections ``(...)`` applied (eq. 15).

    ``"paper"`` shifts every heading, ``"start"`` only the first (held) one.
    """
    corrected = poses.copy()
    if form == "paper":
        corrected[..., 2] += np.asarray(correction)[..., None]
    else:
        corrected[..., 0, 2] += correction
    return corrected


def _rotation_task(
    poses: np.ndarray, inputs: np.ndarray, theta: np.ndarray, settings: InputEstimationSettings
) -> np.ndarray | None:
    try:
        estimate = estimate_inputs(poses, inputs, theta, settings)
    except GraphcalError:
        return None
    return inputs[:, :2] + estimate.corrections


def trimmed_mean(values: np.ndarray, trim_fraction: float, axis: int = 0) -> np.ndarray:
    """Mean after dropping ``round(trim_fraction * n)`` of the lowest and highest values."""
    values = np.sort(values, axis=axis)
    n = values.shape[axis]
    cut = min(round(trim_fraction * n), (n - 1) // 2)
    kept = np.take(values, np.arange(cut, n - cut), axis=axis)
    return kept.mean(axis=axis)


def run_staged(
    data: SegmentData,
    batches: np.ndarray,
    settings: Settings,
    workers: int = 1,
) -> StagedResult:
    """Run Steps 1–5 on the selected segments ``data`` and the ``batches`` of their indices."""
    n_batches, batch_size = batches.shape

    def batch_solves(step: str, heading: np.ndarray, rotations: np.ndarray | None) -> _Step:
        return _batch_solves(step, data, batches, heading, rotations, settings, workers)

    # Step 1: prior parameters, measured signals, start held at the measurement.
    step1 = batch_solves("step1", np.zeros((n_batches, batch_size)), None)
    # Step 2: orientation correction per segment of each batch (eq. 15).
    heading, step2_warnings = _orientation_corrections(
        data, batches, step1.theta, settings, workers
    )
    # Step 3: batch solves with the corrected heading.
    step3 = batch_solves("step3", heading, None)
    # Step 4: compensated rotations per used segment from several theta_II values.
    step4 = _compensated_rotations(data, batches, heading, step3, settings, workers)
    # Step 5: batch solves with compensated rotations and corrected heading.
    step5 = batch_solves("step5", heading, step4.rotations)
    steps = {"step1": step1, "step3": step3, "step5": step5}
    return StagedResult(
        batches,
        {name: step.theta for name, step in steps.items()},
        {name: step.failed for name, step in steps.items()},
        heading,
        step4.rotations,
        step4.example_estimates,
        step4.example,
        [*step1.warnings, *step2_warnings, *step3.warnings, *step4.warnings, *step5.warnings],
    )


@dataclass(frozen=True)
class _Step:
    """One step's batch solves: theta ``(B, 4)`` and the start states ``(B, N, 3)`` each
    used or estimated (NaN where it failed), which failed ``(B,)``, and a warning if any."""

    theta: np.ndarray
    starts: np.ndarray
    failed: np.ndarray
    warnings: list[str]


def _batch_solves(
    step: str,
    data: SegmentData,
    batches: np.ndarray,
    heading: np.ndarray,
    rotations: np.ndarray | None,
    settings: Settings,
    workers: int,
) -> _Step:
    """Step 1, 3 or 5: a batch solve per batch with the heading corrections ``(B, N)`` and
    the compensated ``rotations`` ``(S, K, 2)`` (``None``: the measured ones)."""
    form = settings.staged.heading_correction
    n_batches, batch_size = batches.shape
    tasks = []
    for b, batch in enumerate(batches):
        sub = data.take(batch)
        inputs = sub.inputs.copy()
        if rotations is not None:
            inputs[..., :2] = rotations[batch][:, : inputs.shape[1]]
        sub = dataclasses.replace(
            sub, poses=apply_heading_correction(sub.poses, heading[b], form), inputs=inputs
        )
        solve = settings.calibration
        if step != "step1" and settings.staged.estimate_start_poses:
            solve = dataclasses.replace(solve, estimate_start_poses=True)
        tasks.append((sub, solve))
    results = map_tasks(_batch_task, tasks, workers, f"{step} batch solves")
    failed = np.array([r is None for r in results])
    theta = np.array([np.full(4, np.nan) if r is None else r[0] for r in results])
    starts = np.array([np.full((batch_size, 3), np.nan) if r is None else r[1] for r in results])
    warnings = []
    if failed.any():
        warnings.append(f"{step}: {int(failed.sum())} of {n_batches} batch solves failed")
    return _Step(theta, starts, failed, warnings)


def _orientation_corrections(
    data: SegmentData,
    batches: np.ndarray,
    theta: np.ndarray,
    settings: Settings,
    workers: int,
) -> tuple[np.ndarray, list[str]]:
    """Step 2: the heading correction Δψ [rad] ``(B, N)`` of each segment of each batch with
    its batch's Step 1 ``theta`` ``(B, 4)`` (0 where it failed), and a warning if any did."""
    n_batches, batch_size = batches.shape
    tasks = []
    for b, batch in enumerate(batches):
        for s in batch:
            poses, inputs = data.segment(s)
            tasks.append(
                (
                    poses,
                    inputs,
                    theta[b],
                    settings.staged.step2,
                    settings.staged.heading_correction_step,
                    settings.staged.heading_correction,
                )
            )
    results = map_tasks(_heading_task, tasks, workers, "step2 orientation corrections")
    heading = np.array([0.0 if r is None else r for r in results]).reshape(n_batches, batch_size)
    n_failed = sum(r is None for r in results)
    if not n_failed:
        return heading, []
    return heading, [
        f"step2: {n_failed} input estimations failed or were skipped (their batch's Step 1 "
        "failed); their heading was left uncorrected"
    ]


@dataclass(frozen=True)
class _Step4:
    """Step 4's compensated rotations ``(S, K, 2)`` (measured ones for unused segments), the
    estimates ``(E, K, 2)`` of the ``example`` segment, and warnings."""

    rotations: np.ndarray
    example_estimates: np.ndarray
    example: int
    warnings: list[str]


def _compensated_rotations(
    data: SegmentData,
    batches: np.ndarray,
    heading: np.ndarray,
    step3: _Step,
    settings: Settings,
    workers: int,
) -> _Step4:
    """Step 4: per segment used by a batch, input estimations with the thetas of several
    Step 3 batches (those with the segment first), averaged (trimmed mean)."""
    used = np.unique(batches)
    estimations = settings.staged.estimations
    good_batches = np.flatnonzero(~step3.failed)
    if len(good_batches) == 0:
        raise GraphcalError("every Step 3 batch solve failed; cannot estimate the inputs")
    tasks, owners = [], []
    fewest = estimations
    for s in used:
        chosen, containing = _estimating_batches(int(s), batches, good_batches, settings)
        fewest = min(fewest, len(chosen))
        poses, inputs = data.segment(s)
        own, fallback = _held_starts(poses, int(s), containing, batches, heading, step3, settings)
        for b in chosen:
            corrected = own.get(b, fallback)
            tasks.append((corrected, inputs, step3.theta[b], settings.staged.step4))
            owners.append(int(s))
    warnings = []
    if fewest < estimations:
        warnings.append(
            f"step4: only {fewest} of {estimations} input estimations per segment were possible "
            f"({len(good_batches)} batches); the compensated rotations average fewer estimates"
        )
    results = map_tasks(_rotation_task, tasks, workers, "step4 input estimations")
    step4 = _averaged(data, used, np.asarray(owners), results, settings.staged.trim_fraction)
    return dataclasses.replace(step4, warnings=warnings + step4.warnings)


def _estimating_batches(
    s: int, batches: np.ndarray, good_batches: np.ndarray, settings: Settings
) -> tuple[list, list]:
    """The Step 3 batches whose theta estimates segment ``s``'s inputs in Step 4 (a seeded
    draw: those containing it first, then others), and the good batches containing it."""
    estimations = settings.staged.estimations
    rng = np.random.default_rng([settings.batches.seed, s])
    containing = [b for b in good_batches if s in batches[b]]
    others = [b for b in good_batches if s not in batches[b]]
    chosen = list(rng.permutation(containing))[:estimations]
    if len(chosen) < estimations and others:
        extra = rng.permutation(others)[: estimations - len(chosen)]
        chosen += list(extra)
    return chosen, containing


def _held_starts(
    poses: np.ndarray,
    s: int,
    containing: list,
    batches: np.ndarray,
    heading: np.ndarray,
    step3: _Step,
    settings: Settings,
) -> tuple[dict, np.ndarray]:
    """The held start of each estimation of segment ``s`` (measured ``poses``): per batch
    containing it, the start Step 3 estimated in that batch when it estimates starts, else
    the Step 2 heading correction; for batches without the segment, the median over those
    with it (the poses uncorrected if none)."""
    form = settings.staged.heading_correction
    own = {}
    for b in containing:
        i = list(batches[b]).index(s)
        if settings.staged.estimate_start_poses:
            own[b] = poses.copy()
            own[b][0] = step3.starts[b, i]
        else:
            own[b] = apply_heading_correction(poses, heading[b][i], form)
    fallback = (
        np.median(np.stack(list(own.values())), axis=0)
        if own
        else apply_heading_correction(poses, 0.0, form)
    )
    return own, fallback


def _averaged(
    data: SegmentData,
    used: np.ndarray,
    owners: np.ndarray,
    results: list,
    trim_fraction: float,
) -> _Step4:
    """The compensated rotations: per used segment, the trimmed mean of its estimates
    ``results`` (``owners``: the segment of each), with a warning about failed ones."""
    compensated = data.inputs[..., :2].copy()
    example = int(used[0])
    example_estimates = np.zeros((0, int(data.n_steps[example]), 2))
    n_failed = 0
    for s in used:
        estimates = [results[i] for i in np.flatnonzero(owners == s) if results[i] is not None]
        n_failed += int((owners == s).sum()) - len(estimates)
        if not estimates:
            continue
        stack = np.stack(estimates)
        k = stack.shape[1]
        compensated[s, :k] = trimmed_mean(stack, trim_fraction)
        if s == example:
            example_estimates = stack
    warnings = []
    if n_failed:
        warnings.append(f"step4: {n_failed} input estimations failed and were left out")
    return _Step4(compensated, example_estimates, example, warnings)
