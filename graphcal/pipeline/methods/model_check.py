"""Which model a recording supports: theta with the defect model's sensor terms, or theta
alone — judged by how well each predicts segments it did not see.

The joint solve estimates, with theta, what real recordings get wrong: the wheels' time
offset, the GNSS antenna's lever arm, a fused heading's bias per segment and slow wheel slip
(:mod:`graphcal.pipeline.solvers.joint`). Each is a direction the solve may also use for something
else — the model's own misfit, a skid-steer robot's scrubbing, noise of the fixes — and then
takes what belongs to theta.

So when the whole-log solve found one of them (a time offset or lever arm detected, slip
modelled), :func:`check_model` cross-validates: the selected segments, in time order, are
cut into :data:`GROUPS` groups, alternately in two folds; each model calibrates from one
fold and dead-reckons the other's segments (eq. 16 / K), each path fitted to its fixes
rigidly (:func:`~graphcal.pipeline.methods.validation.position_errors` with ``aligned``: the shape
of the path is judged, not a start heading whose noise alone is metres over a segment), with
theta and the lever arm the fold found (the antenna is a point of the car wherever it
drives: a real 1.2 m arm left out of the prediction favoured the theta that had absorbed
it, c_e 3.8σ off on a 3 km drive); the other sensor terms are the segments' own (heading
biases, slip) or shift its wheels (a time offset), and both thetas are judged on the same
uncorrected segments. When theta alone predicts them better (by more than
:data:`MARGIN`), the simpler model is the right one for this recording and the run
calibrates with it (:class:`ModelCheck`). A longer log is checked on
:data:`~graphcal.pipeline.methods.whole_log.CHECK_SEGMENTS` segments spread over it: a model's
fit does not need every segment. Each fold's solve starts from the whole log's solution of
its segments: the optimum is the fold's either way.

Theta alone is chosen on evidence that a short log gives only roughly: where its theta
differs from the defect model's, that difference is part of theta's uncertainty
(:func:`with_the_other_model`). Six 150 m segments under fixes sharing 1.9 m of error over
a minute predicted 0.517 m with theta alone and 0.636 m with a lever arm the solve had found
at 3.4σ; theta alone, blind to
the 0.36 m arm, put c_e 25 mm from the truth with σ 6.4 mm (3.9σ), 8.1 mm from the defect
model's c_e; with that difference σ is 10.4 mm (2.4σ; campaign seed 43's shape 38).

Slip is judged apart from the other terms before theta alone wins: where the defect model
with slip predicts worse than theta alone, it is tried without slip. Slip scales free per
chunk can follow what the fixes share over tens of seconds: on the twin's town drive with
fixes sharing 0.5 m of error over 48 s and an antenna 0.33 m to the side, slip was "found"
(z 4.1), the defect model with it predicted 0.997 m, theta alone 0.393 m — and theta alone,
blind to the arm, put c_e 4.9σ off; the arm without slip predicts 0.341 m, c_e −0.2σ.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed
from graphcal.graph.construction.keys import (
    LEVER_ARM,
    REAR_SLIP_GAIN,
    THETA,
    TIME_OFFSET,
)
from graphcal.graph.construction.moved_values import renumbered, with_corrections_shifted
from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, gather_segments
from graphcal.log.timing import shift_wheel_rotations, whole_samples
from graphcal.model import AY, BETA, PARAMETER_NAMES
from graphcal.pipeline.methods.prepare import PreparedLog
from graphcal.pipeline.methods.sensor_estimates import detected_offsets
from graphcal.pipeline.methods.validation import position_errors
from graphcal.pipeline.methods.whole_log import WholeLog, check_segments
from graphcal.pipeline.solvers.joint import solve_joint
from graphcal.pipeline.solvers.joint_settings import JointSettings, without_sensor_terms
from graphcal.progress import muted, say

#: Groups of consecutive segments, alternately in the two folds.
GROUPS = 4
#: Segments a check needs at least (one per fold).
MIN_SEGMENTS = 2
#: Theta alone is chosen when it predicts the held-apart segments better than the defect
#: model by more than this share: less is within what two folds of a short log can tell
#: apart.
MARGIN = 0.05
#: A fold's solve stops when an iteration lowers χ² by less than this share: its theta
#: predicts the other fold, which a last 10⁻⁴ of χ² does not change (a 12 km drive with every
#: defect: 3–4 of each fold's 6–8 iterations polished below it at the joint solve's 10⁻⁷).
FOLD_TOLERANCE = 1e-4


@dataclass(frozen=True)
class ModelCheck:
    """How well each model predicted the segments it did not see.

    Attributes:
        found: what the defect model found that made the check run (``"time offset"``,
            ``"lever arm"``, ``"slow wheel slip"``).
        defect_model_error: mean position error [m] of the held-apart segments with theta
            from the defect model (``inf`` where a fold's solve failed).
        theta_alone_error: the same with theta from theta alone.
        segments: segments checked.
        without_slip_error: the same with the defect model without slip, where it was
            tried (slip found with other terms, the defect model beaten by theta alone);
            else ``None``.
    """

    found: tuple[str, ...]
    defect_model_error: float
    theta_alone_error: float
    segments: int
    without_slip_error: float | None = None

    @property
    def without_slip(self) -> bool:
        """The defect model without slip predicted the held-apart segments better than with
        it and not worse than theta alone, each by :data:`MARGIN`: the run uses it."""
        error = self.without_slip_error
        return (
            error is not None
            and error < (1.0 - MARGIN) * self.defect_model_error
            and not self.theta_alone_error < (1.0 - MARGIN) * error
        )

    @property
    def theta_alone(self) -> bool:
        """Theta alone predicted the held-apart segments better than the defect model (and
        than it without slip, where tried), by more than :data:`MARGIN`: the run uses it."""
        beaten = self.theta_alone_error < (1.0 - MARGIN) * self.defect_model_error
        return beaten and not self.without_slip

    @property
    def chosen(self) -> str:
        """The model the run calibrates with."""
        if self.theta_alone:
            return "theta alone"
        return "defect model without slip" if self.without_slip else "defect model"

    def line(self) -> str:
        """One progress line: the errors and the model chosen."""
        errors = (
            f"{self.theta_alone_error:.3g} m with theta alone, {self.defect_model_error:.3g} m "
            f"with the {', '.join(self.found)} modelled"
        )
        if self.without_slip_error is not None:
            errors += f", {self.without_slip_error:.3g} m with them but slip"
        chosen = {
            "theta alone": "theta alone (the defect model's terms do not help theta on this "
            "recording)",
            "defect model": "the defect model",
            "defect model without slip": "the defect model without slip (slip scales "
            "followed what the fixes share, not the wheels)",
        }[self.chosen]
        return (
            f"model check: {self.segments} segments predicted from the others: {errors}; "
            f"calibrating with {chosen}"
        )

    def to_dict(self) -> dict:
        """Plain data for ``calibration.json`` (an ``inf`` error is written as ``None``)."""

        def finite(x: float) -> float | None:
            return float(x) if np.isfinite(x) else None

        return {
            "found": list(self.found),
            "defect_model_error_m": finite(self.defect_model_error),
            "theta_alone_error_m": finite(self.theta_alone_error),
            "without_slip_error_m": (
                None if self.without_slip_error is None else finite(self.without_slip_error)
            ),
            "segments": self.segments,
            "chosen": self.chosen,
        }


def with_the_other_model(chosen: WholeLog, other: WholeLog) -> WholeLog:
    """``chosen`` (the solve with theta alone) with theta's covariance widened by its
    difference ``Δ`` from ``other``'s theta (the defect model's): ``Σ + ΔΔᵀ``, and its
    verdicts judged on it (those it left out for a reason stay out, their ``Δ`` not
    added). The check chose between the models on held-apart segments whose errors are
    mostly the fixes' own; which one holds is not known beyond that, so theta's σ covers
    both."""
    whole = chosen.whole
    difference = np.asarray(whole.theta, float) - np.asarray(other.whole.theta, float)
    if whole.covariance is None or not np.all(np.isfinite(difference)):
        return chosen
    reasons = whole.observability.reasons
    difference[[name in reasons for name in PARAMETER_NAMES]] = 0.0
    covariance = whole.covariance + np.outer(difference, difference)
    settings = dataclasses.replace(chosen.corrected.settings.joint, held_at_prior=())
    observability = settings.observability(covariance)
    for name, reason in reasons.items():
        observability = observability.without(name, reason)
    sigma = np.sqrt(np.diag(whole.covariance))
    widened = [
        f"{name} by {abs(d) / s:.1f}σ"
        for name, d, s in zip(PARAMETER_NAMES, difference, sigma, strict=True)
        if s > 0 and abs(d) > 0.5 * s
    ]
    if widened:
        say(
            "model check: theta alone differs from the defect model's theta ("
            f"{', '.join(widened)}): theta's σ includes the difference"
        )
    return dataclasses.replace(
        chosen, whole=dataclasses.replace(whole, covariance=covariance, observability=observability)
    )


def theta_alone(settings: JointSettings) -> JointSettings:
    """``settings`` without the defect model's sensor terms (time offset, lever arm, heading
    biases, rear slip gain, slip); the noise levels and the robust weighting of fixes stay."""
    return without_sensor_terms(settings)


def folds(count: int) -> np.ndarray:
    """``(count,)`` fold 0 or 1 of each of ``count`` segments in time order:
    :data:`GROUPS` groups of consecutive segments, alternately."""
    groups = min(GROUPS, count)
    return (np.arange(count) * groups // count) % 2


def check_model(prepared: PreparedLog, solved: WholeLog, workers: int) -> ModelCheck | None:
    """Cross-validate the defect model against theta alone (module docstring) when the
    whole-log solve ``solved`` of ``prepared`` found a sensor term; ``None`` when it found
    none, or the log has too few segments to check."""
    found = solved.defects_found()
    selected = prepared.selected
    if not found or len(selected) < MIN_SEGMENTS:
        return None
    settings = solved.corrected.settings.joint
    segments = selected.subset(check_segments(len(selected)))
    log = solved.solved_log
    weights = solved.corrected.fix_weights
    # As the corrected log: an offset not detected is not corrected, and its estimate (one
    # the drive does not show, run to −1.4 s through the time-offset rounds on a robot) is
    # no prior mean
    value = detected_offsets(solved.estimated, log.runs)
    shift = np.array([whole_samples(o, log.dt) for o in value])
    shifted = shift_wheel_rotations(log, shift)
    # The folds weight the fixes as the whole log found them, and model slip as it decided:
    # a fold re-deciding either from half the segments costs 5–6 solves for what it knows.
    settings = dataclasses.replace(settings, robust_threshold=0.0)
    full = dataclasses.replace(
        settings,
        time_offset_means=tuple(value - shift),
        time_offset_sigma=prepared.settings.joint.time_offset_sigma,
        slip="on" if solved.whole.slip_modelled else "off",
    )
    fold = folds(len(segments))
    say(f"model check: {len(segments)} segments in 2 folds ({', '.join(found)} found)")

    def cross_validated(model: JointSettings, source: DriveLog, moved: np.ndarray) -> float:
        """Mean error [m] of each fold's segments predicted by ``model`` calibrated from the
        other fold's, taken from ``source`` (its wheels shifted by ``moved`` [s])."""
        errors = []
        for f in (0, 1):
            train = gather_segments(source, segments.subset(fold == f), weights)
            held = gather_segments(source, segments.subset(fold != f))  # its wheels too
            members = np.flatnonzero(fold == f)
            start, own = _fold_start(solved, members, train, moved, value - shift)
            errors.append(_held_apart_error(train, held, model, workers, start, own))
        return float(np.mean(errors))

    check = ModelCheck(
        found,
        cross_validated(full, shifted, shift),
        cross_validated(theta_alone(settings), log, np.zeros_like(shift)),
        len(segments),
    )
    if not check.theta_alone or "slow wheel slip" not in found or len(found) == 1:
        return check
    no_slip = dataclasses.replace(full, slip="off")
    return dataclasses.replace(check, without_slip_error=cross_validated(no_slip, shifted, shift))


def _fold_start(
    solved: WholeLog,
    members: np.ndarray,
    train: SegmentData,
    moved: np.ndarray,
    offsets: np.ndarray,
) -> tuple[gtsam.Values, bool]:
    """Where a fold of the checked segments ``members`` (indices among them) starts: the
    whole log's solution of its segments (:attr:`WholeLog.check_start`), else its theta. The
    optimum is the fold's either way; from theta alone, every pose and correction on the
    nominal odometry, the real car's folds took 5–8 iterations, the real robot's 4 from
    χ²/dof 14,000–30,000 (from a warm start of their own, more). The wheels' time offset
    starts at ``offsets`` [s], each run's in the fold's frame (its wheels shifted by
    ``moved`` [s]), and the wheel corrections move with the wheels where that shift is not
    the whole log's (the real car's fold started at χ² 15,082 with the solution's −15.7 ms
    and its corrections a sample off, at 1,954 with both moved, at 248,000 from theta
    alone). With whether it holds the segments' variables (``train``: the fold's
    segments)."""
    at = solved.check_start
    if at is not None and at.values is not None:
        lag = np.rint((np.asarray(moved, float) - np.asarray(at.shift, float)) / train.dt)
        lag = np.broadcast_to(lag.astype(int), (train.runs,))
        runs = [train.run_of(s) for s in range(len(train))]
        start = with_corrections_shifted(renumbered(at.values, members), len(train), lag[runs])
        if start.exists(TIME_OFFSET):
            start.update(TIME_OFFSET, np.asarray(offsets, float))
        return start, True
    start = gtsam.Values()
    start.insert(THETA, np.asarray(solved.whole.theta, float))
    return start, False


def _held_apart_error(
    train: SegmentData,
    held: SegmentData,
    settings: JointSettings,
    workers: int,
    start: gtsam.Values | None = None,
    same_segments: bool = False,
) -> float:
    """Mean position error [m] of ``held`` dead-reckoned with theta calibrated from
    ``train`` under ``settings`` (every parameter its posterior), the fixes taken as
    the antenna's on the lever arm that solve found (none without one), the rear axle
    slipping at the gain it found (none without one); ``inf`` if that calibration fails.
    ``start``: the values the solve starts from, of ``train``'s very segments (with
    ``same_segments``; :func:`_fold_start`) or only graph-wide ones (``None``: a warm
    start's)."""
    try:
        with muted():  # a fold's solve: its lines are not the user's concern
            fold = dataclasses.replace(settings, tolerance=FOLD_TOLERANCE)
            solve, values = solve_joint(
                train, fold, workers, start=start, same_segments=same_segments
            )
    except CalibrationFailed:
        return float("inf")
    arm = np.asarray(values.atVector(LEVER_ARM)) if values.exists(LEVER_ARM) else None
    if values.exists(REAR_SLIP_GAIN):  # the car's tyres slip on the held segments too
        inputs = held.inputs.copy()
        inputs[..., BETA] -= float(values.atVector(REAR_SLIP_GAIN)[0]) * inputs[..., AY]
        held = dataclasses.replace(held, inputs=inputs)
    return float(np.mean(position_errors(held, solve.theta, aligned=True, arm=arm)))
