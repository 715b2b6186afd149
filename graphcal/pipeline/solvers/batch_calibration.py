"""Batch calibration (paper §4.1, eqs. 10–11): theta from a batch of measured segments.

The segment graph (:mod:`graphcal.graph.construction.builder`) with one chunk per segment and no
correction variables: the shared theta under a weak prior at the nominal values (it keeps
elimination well posed when a batch does not excite every parameter, e.g. d needs lateral
acceleration) and, when start poses are estimated, a Pose2 per segment under its measurement.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.errors import CalibrationFailed, check_settings
from graphcal.factors import PAPER_POSE_WEIGHTS, pose_sigmas
from graphcal.factors.chunk_factor import ChunkOdometryFactor
from graphcal.graph.construction import keys
from graphcal.graph.construction.builder import build_segment_graph
from graphcal.graph.construction.built_graph import BuiltGraph
from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.graph.optimization.solve_options import SolveOptions
from graphcal.graph.solution.estimates import ThetaEstimate
from graphcal.graph.solution.plausibility import check_plausible
from graphcal.graph.solution.reduced_systems import ReducedSystems
from graphcal.graph.solution.segment_solve import solve_segment_graph
from graphcal.log.segments import SegmentData
from graphcal.model import THETA_NOMINAL, THETA_PRIOR_SIGMAS


@dataclass(frozen=True)
class BatchSettings:
    """Settings of a batch calibration solve (SI).

    Attributes:
        theta_initial: initial guess, the nominal theta of the paper by default.
        theta_prior_sigmas: standard deviations of the weak prior on theta at ``theta_initial``.
        pose_weights: the paper's W (§4.4); with ``position_sigma`` they give the pose sigmas.
        position_sigma: standard deviation of the measured position [m].
        estimate_start_poses: free each segment's start pose under its measurement prior;
            ``False`` holds it at the measurement, as the paper's Step 1.
        max_iterations: Levenberg–Marquardt iteration limit.
    """

    theta_initial: np.ndarray = field(default_factory=lambda: THETA_NOMINAL.copy())
    theta_prior_sigmas: np.ndarray = field(default_factory=lambda: THETA_PRIOR_SIGMAS.copy())
    pose_weights: tuple[float, float, float] = PAPER_POSE_WEIGHTS
    position_sigma: float = 0.2
    estimate_start_poses: bool = True
    max_iterations: int = 20

    def __post_init__(self) -> None:
        check_settings(
            "calibration",
            positive_vectors={
                "theta_prior_sigmas": self.theta_prior_sigmas,
                "pose_weights": self.pose_weights,
            },
            finite_vectors={"theta_initial": self.theta_initial},
            positive={"position_sigma": self.position_sigma},
            at_least_one={"max_iterations": self.max_iterations},
        )

    def graph_spec(self) -> SegmentGraphSpec:
        """The segment graph of a batch solve."""
        sigmas = pose_sigmas(self.pose_weights, self.position_sigma)
        return SegmentGraphSpec(
            theta=np.asarray(self.theta_initial, float),
            tracking_sigmas=sigmas,
            theta_prior_sigmas=np.asarray(self.theta_prior_sigmas, float),
            start_prior_sigmas=sigmas if self.estimate_start_poses else None,
        )


def calibrate_batch(data: SegmentData, settings: BatchSettings | None = None) -> ThetaEstimate:
    """Estimate theta from the segments in ``data`` (one batch, eq. 11) with Levenberg–Marquardt.

    Raises:
        CalibrationFailed: if the solve diverges, the system is singular or theta implausible.
    """
    settings = settings or BatchSettings()
    options = SolveOptions(settings.max_iterations, 1e-10, "batch solve")
    solved = solve_segment_graph(data, settings.graph_spec(), options)
    return solved.estimate()


def held_start_batches(
    data: SegmentData, batches: np.ndarray, settings: BatchSettings, workers: int = 1
) -> np.ndarray:
    """Theta ``(B, 4)`` of each batch of ``batches`` ``(B, N)`` (indices into ``data``) as
    :func:`calibrate_batch` gives it with the start poses held (the paper's Step 1), from
    one solve of all segments and two Gauss–Newton steps per batch; NaN rows where a batch's
    information is singular or its theta implausible.

    With the start held, a segment's factors are on theta alone, so a batch's system is the
    sum of its members' and the prior's. The first step is taken from every segment
    linearized once at the solution over all of them (:class:`ReducedSystems`); the second
    relinearizes the batch's members at the batch's own theta: the model bends over a batch's
    spread (a 24 km drive's batches one step from the whole log's solution were up to 0.29
    of their spread from their own solves; two steps, within 0.0014). Each segment is
    evaluated at the thetas of all the batches it is in at once
    (:meth:`~graphcal.factors.ChunkOdometryFactor.theta_augmented_hessians`): the 24 km
    drive's 900 member linearizations 3.5 → 1.2 s for the whole of Step 1."""
    spec = settings.graph_spec()
    if spec.start_prior_sigmas is not None:
        raise ValueError("held_start_batches needs settings that hold the start poses")
    options = SolveOptions(settings.max_iterations, 1e-10, "batch solve", workers)
    point = solve_segment_graph(data, spec, options, covariance=False).theta
    alone = dataclasses.replace(spec, theta=point, theta_prior_sigmas=None)
    graphs = [build_segment_graph(data.take([s]), alone) for s in range(len(data))]
    prior = _prior_graph(spec)
    prior_sigmas = spec.theta_prior_sigmas
    factors = [_theta_factor(built) for built in graphs]
    first = ReducedSystems(
        (keys.THETA,),
        point,
        np.concatenate([factor.theta_augmented_hessians(point[None]) for factor in factors]),
        _augmented_hessian(prior, gtsam.Values(), point),
    )
    batches = np.asarray(batches, int)
    out = first.solve(batches).values
    members = _members_at_batch_thetas(factors, batches, out)
    for b in range(len(batches)):
        if not np.all(np.isfinite(out[b])):
            continue
        system = _augmented_hessian(prior, gtsam.Values(), out[b]) + members[b]
        try:
            out[b] = out[b] + np.linalg.solve(system[:4, :4], system[:4, 4])
            check_plausible(out[b], "batch solve", spec.theta, prior_sigmas=prior_sigmas)
        except (np.linalg.LinAlgError, CalibrationFailed):
            out[b] = np.nan  # what a failed solve of its own gives
    return out


def _theta_factor(built: BuiltGraph) -> ChunkOdometryFactor:
    """The one chunk factor, on theta alone, of a held-start segment graph."""
    if built.graph.size() != 1 or len(built.chunk_factors) != 1:
        raise ValueError("a held-start segment graph is one chunk factor on theta")
    return built.chunk_factors[0].factor


def _members_at_batch_thetas(
    factors: list[ChunkOdometryFactor], batches: np.ndarray, thetas: np.ndarray
) -> np.ndarray:
    """``(B, 5, 5)``: the augmented Hessians of each batch's members (``factors``: one per
    segment, on theta alone) linearized at the batch's theta of ``thetas (B, 4)``, summed
    (zero for a batch whose theta is not finite): per segment, one vectorized evaluation at
    the thetas of every batch it is in."""
    out = np.zeros((len(batches), 5, 5))
    finite = np.all(np.isfinite(thetas), axis=1)
    for s, factor in enumerate(factors):
        times = np.sum(batches == s, axis=1) * finite  # a member once per draw of it
        rows = np.nonzero(times)[0]
        if len(rows) > 0:
            out[rows] += times[rows, None, None] * factor.theta_augmented_hessians(thetas[rows])
    return out


def _prior_graph(spec: SegmentGraphSpec) -> gtsam.NonlinearFactorGraph:
    """The weak prior on theta of ``spec``, alone."""
    graph = gtsam.NonlinearFactorGraph()
    sigmas = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(spec.theta_prior_sigmas, float))
    graph.add(gtsam.PriorFactorVector(keys.THETA, np.asarray(spec.theta, float), sigmas))
    return graph


def _augmented_hessian(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, theta: np.ndarray
) -> np.ndarray:
    """``[Λ η; ηᵀ c]`` of ``graph`` linearized at ``values`` with theta at ``theta``."""
    values = gtsam.Values(values)
    if values.exists(keys.THETA):
        values.update(keys.THETA, np.asarray(theta, float))
    else:
        values.insert(keys.THETA, np.asarray(theta, float))
    return graph.linearize(values).augmentedHessian()
