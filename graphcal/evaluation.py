"""Evaluation of a calibration against a known truth (synthetic drives), apart from calibration.

:func:`graphcal.pipeline.end_to_end.run.run_calibration` never sees the truth. Given a run and the
:class:`Truth` of its drive — the true theta and, optionally, the noise-free signals —
:func:`evaluate` computes what a researcher checks an estimator by:

* the error of the recommended theta and the reachable validation error (odometry with the
  true theta, the limit of eq. 16);
* the Cramér–Rao bound of the recommended theta and of every joint batch (needs the
  noise-free signals): the theta block of the inverse Fisher information of the
  measurements, the joint graph without the weak prior on theta linearized at the true
  values of every variable (each segment's information computed once and summed per batch);
* per batch, the normalized estimation error squared (NEES) ``eᵀ Σ⁻¹ e`` of each method that
  reports a covariance: 4 on average when the reported covariance matches the actual errors.

:func:`synthetic_truth` finds the truth of a synthetic log as ``graphcal calibrate`` does:
``theta_true`` in a synthetic drive's JSON sidecar (with its noise-free drive, for the
Cramér–Rao bound) or in an imported synthetic recording's manifest (or the ``truth.json``
beside a simulated bag); a real log has none.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.errors import GraphcalError, exception_reason
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.graph_spec import shared_keys
from graphcal.graph.optimization.partitioned import PartitionedGraph
from graphcal.graph.solution.reduced_systems import ReducedSystems, reduced_systems
from graphcal.log.drive_log import DriveLog
from graphcal.log.load import load_drive_log
from graphcal.log.segments import SegmentData, gather_segments
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.methods.validation import position_errors
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.progress import Progress, reports_progress, say
from graphcal.recording.importer import ImportedLog
from graphcal.simulate.drive import read_sidecar, truth_path


@dataclass(frozen=True)
class Truth:
    """What is known about a synthetic drive.

    Attributes:
        theta: the true ``[c_e, c_d, t_r, d]`` (SI).
        log: the noise-free signals of the drive (same samples as the measured log), or
            ``None``; needed for the Cramér–Rao bound.
    """

    theta: np.ndarray
    log: DriveLog | None = None


@dataclass(frozen=True)
class Evaluation:
    """A run compared with the truth (SI).

    Attributes:
        theta_true: the true theta.
        theta_error: recommended minus true theta.
        validation_errors: per validation segment, the mean position error [m] of odometry
            with the true theta (the reachable limit).
        crb: Cramér–Rao bound of the recommended theta ``(4, 4)``, or ``None`` (no noise-free
            signals, or theta not identifiable from the drive).
        batch_crb: per method, the bound of each batch ``(B, 4, 4)``; NaN where not computed.
        batch_nees: per method with covariances, the NEES of each batch ``(B,)``; NaN for
            failed or excluded batches.
    """

    theta_true: np.ndarray
    theta_error: np.ndarray
    validation_errors: np.ndarray
    crb: np.ndarray | None
    batch_crb: dict[str, np.ndarray]
    batch_nees: dict[str, np.ndarray]

    @property
    def reachable_error(self) -> float:
        """E_p [m] of the true theta: the validation error no calibration can beat."""
        return float(np.mean(self.validation_errors))


def cramer_rao_bound(
    data: SegmentData,
    truth: SegmentData,
    theta_true: np.ndarray,
    settings: JointSettings | None = None,
) -> np.ndarray:
    """The Cramér–Rao bound of theta for the measured segments ``data``: 4×4, SI.

    ``truth`` holds the same segments' noise-free signals. The joint graph without the prior
    on theta is linearized at the true start and boundary poses, the true minus measured
    wheel rotations as corrections, and ``theta_true``.

    Raises:
        GraphcalError: if theta is not identifiable from ``data`` (e.g. a straight drive):
            the information matrix is singular and there is no finite bound.
    """
    bound = cramer_rao_bounds(data, truth, theta_true, np.arange(len(data))[None], settings)[0]
    if not np.all(np.isfinite(bound)):
        raise GraphcalError(
            "Cramér–Rao bound: the information matrix of theta is singular (a parameter "
            "is not identifiable from these segments)"
        )
    return bound


def cramer_rao_bounds(
    data: SegmentData,
    truth: SegmentData,
    theta_true: np.ndarray,
    batches: np.ndarray,
    settings: JointSettings | None = None,
    workers: int = 1,
) -> np.ndarray:
    """The Cramér–Rao bound of theta of each batch of ``data``'s segments: ``(B, 4, 4)``, SI;
    NaN for a batch from which theta is not identifiable. ``batches`` ``(B, N)`` index
    ``data``; as :func:`cramer_rao_bound`, from one pass over the segments for all batches
    (:func:`cramer_rao_systems`)."""
    systems = cramer_rao_systems(data, truth, theta_true, settings, workers)
    return systems.solve(batches).covariance[:, :4, :4]


def cramer_rao_systems(
    data: SegmentData,
    truth: SegmentData,
    theta_true: np.ndarray,
    settings: JointSettings | None = None,
    workers: int = 1,
    tied: bool = False,
) -> ReducedSystems:
    """The measurements' information of every segment of ``data`` at the truth, reduced to
    the shared variables (:mod:`graphcal.graph.solution.reduced_systems`): the joint graph without
    the prior on theta linearized as :func:`cramer_rao_bound` does, each segment eliminated
    once (in ``workers`` processes). A batch's bound is the theta block of the inverse of
    its members' summed information: exactly the bound of the batch's own graph. With
    ``tied`` (and the settings' ``tie_segments``), consecutive segments are one trajectory,
    as the whole-log solve has them: only the sum over all segments is then meaningful.

    Raises:
        GraphcalError: if a segment's own variables are indeterminate.
    """
    settings = settings or JointSettings()
    settings = dataclasses.replace(settings, tie_segments=tied and settings.tie_segments)
    spec = settings.graph_spec(theta_prior=False)
    built = build_segment_graph(data, spec)
    states, corrections = [], []
    for s in range(len(data)):
        true_poses, true_inputs = truth.segment(s)
        states.append(true_poses)
        corrections.append(true_inputs[:, :2] - data.segment(s)[1][:, :2])
    values = built.values_at(states, corrections, theta_true)
    segmented = PartitionedGraph(built.graph, values, shared_keys(spec))
    try:
        with segmented.parallel(workers):
            return reduced_systems(segmented, len(data), joined=tied)
    except (RuntimeError, np.linalg.LinAlgError) as exc:
        reason = exception_reason(exc)
        raise GraphcalError(f"Cramér–Rao bound failed: {reason}") from exc


def nees(theta: np.ndarray, covariance: np.ndarray, theta_true: np.ndarray) -> np.ndarray:
    """Normalized estimation error squared of estimates ``(B, 4)`` with covariances
    ``(B, 4, 4)``; NaN where an estimate or covariance is not finite."""
    theta, covariance = np.asarray(theta, float), np.asarray(covariance, float)
    out = np.full(len(theta), np.nan)
    good = np.all(np.isfinite(theta), axis=1) & np.all(np.isfinite(covariance), axis=(1, 2))
    errors = theta[good] - theta_true
    out[good] = np.einsum("bi,bij,bj->b", errors, np.linalg.inv(covariance[good]), errors)
    return out


def _whole_log_bound(tied: ReducedSystems) -> np.ndarray | None:
    """The Cramér–Rao bound ``(4, 4)`` of all the segments of ``tied`` (their information tied
    as the whole-log solve ties them) together; ``None`` (said why) where it has none."""
    crb = tied.solve(np.arange(len(tied.segments))[None]).covariance[0, :4, :4]
    if not np.all(np.isfinite(crb)):
        say(
            "no Cramér–Rao bound: the measurements' information matrix of theta is "
            "singular (a parameter is not identifiable from this drive)"
        )
        return None
    return crb


def _own_systems(
    data: SegmentData,
    truth: SegmentData,
    theta_true: np.ndarray,
    settings: JointSettings,
    workers: int,
    tied: ReducedSystems | None,
) -> ReducedSystems:
    """Every segment's own information at the truth (:func:`cramer_rao_systems`): taken from
    ``tied`` (the whole log's, tied) where a segment is tied to no other — its graph the same
    either way — and eliminated alone for the segments of each chain.

    Raises:
        GraphcalError: as :func:`cramer_rao_systems`.
    """
    if tied is None:
        return cramer_rao_systems(data, truth, theta_true, settings, workers)
    starts = settings.graph_spec(theta_prior=False).tied(data)
    chained = np.flatnonzero(starts | np.append(starts[1:], False))
    if len(chained) == 0:
        return tied
    alone = cramer_rao_systems(
        data.take(chained), truth.take(chained), theta_true, settings, workers
    )
    segments = tied.segments.copy()
    segments[chained] = alone.segments
    return dataclasses.replace(tied, segments=segments)


@reports_progress
def evaluate(
    run: CalibrationRun,
    truth: Truth,
    progress: Progress | None = None,
    workers: int = 1,
) -> Evaluation:
    """Compare ``run`` with the ``truth`` of its drive (see the module docstring).

    Raises:
        GraphcalError: if the noise-free log does not match the measured one.
    """
    theta_true = np.asarray(truth.theta, float)
    if truth.log is not None and len(truth.log) != len(run.log):
        raise GraphcalError(
            f"the truth has {len(truth.log)} samples, the log {len(run.log)}; they must match"
        )
    crb = systems = tied = None
    batch_crb: dict[str, np.ndarray] = {}
    if truth.log is not None:
        true_data = gather_segments(truth.log, run.selected)
        settings = run.settings.joint
        joint_batches = run.batches is not None and "joint" in run.batch_theta
        if run.covariance is not None:
            say("Cramér–Rao bound: the whole log's information at the truth")
            try:
                tied = cramer_rao_systems(
                    run.data, true_data, theta_true, settings, workers, tied=True
                )
            except GraphcalError as exc:
                say(f"no Cramér–Rao bound: {exc}")
            else:
                crb = _whole_log_bound(tied)
        if joint_batches:
            say("Cramér–Rao bounds: every segment's information at the truth")
            try:
                systems = _own_systems(run.data, true_data, theta_true, settings, workers, tied)
            except GraphcalError as exc:
                say(f"no Cramér–Rao bound of the batches: {exc}")
        if systems is not None and joint_batches:
            solved = np.all(np.isfinite(run.batch_theta["joint"]), axis=1)
            bounds = systems.solve(run.batches).covariance[:, :4, :4]
            batch_crb["joint"] = np.where(solved[:, None, None], bounds, np.nan)
    batch_nees = {
        name: nees(run.batch_estimates(name), covariances, theta_true)
        for name, covariances in run.batch_covariance.items()
    }
    return Evaluation(
        theta_true=theta_true,
        theta_error=run.theta - theta_true,
        validation_errors=position_errors(run.validation, theta_true),
        crb=crb,
        batch_crb=batch_crb,
        batch_nees=batch_nees,
    )


@reports_progress
def synthetic_truth(
    run: CalibrationRun,
    log_path: str | os.PathLike[str],
    imported: ImportedLog | None,
    progress: Progress,
) -> Truth | None:
    """The truth of the log ``run`` calibrated (at ``log_path``; ``imported`` if it was a
    recording), or ``None`` for a real log; ``progress`` hears where it comes from and why
    there is no Cramér–Rao bound when the noise-free drive is missing or unusable."""
    if imported is not None:
        if imported.truth is None:
            return None
        where = "its manifest" if imported.truth_file is None else imported.truth_file
        say(f"synthetic recording: comparing with theta_true from {where}")
        return Truth(imported.truth)
    return _sidecar_truth(run, Path(log_path))


def _sidecar_truth(run: CalibrationRun, log_path: Path) -> Truth | None:
    """The truth in a synthetic drive's sidecar, or ``None`` for a real log."""
    sidecar = read_sidecar(log_path, len(run.log))
    if sidecar is None:
        return None
    say("synthetic drive: comparing with theta_true from its sidecar")
    path = truth_path(log_path)
    truth_log = None
    if not path.exists():
        # An imported recording's sidecar carries theta_true but no noise-free drive; only
        # `graphcal simulate` writes one, and only then is its absence worth a word.
        if str(sidecar.get("generator", "")).endswith("simulate"):
            say(f"no Cramér–Rao bound: the noise-free drive {path} is missing")
    else:
        try:
            truth_log = load_drive_log(path, reverses=run.settings.vehicle.reverses)
        except GraphcalError as exc:
            say(f"no Cramér–Rao bound: cannot use {path}: {exc}")
    if truth_log is not None and len(truth_log) != len(run.log):
        say(
            f"no Cramér–Rao bound: {path.name} has {len(truth_log)} samples, the log {len(run.log)}"
        )
        truth_log = None
    return Truth(sidecar["theta_true"], truth_log)
