"""The one graph builder for segments of a drive: multiple shooting over chunks.

Every calibration graph of graphcal is an instance of this shape, chosen by a
:class:`SegmentGraphSpec`:

* per segment, its start: held at the measured pose, or a Pose2 variable under world-frame
  position and heading priors at the measured pose (the paper's W);
* the segment cut into chunks (:func:`~graphcal.graph.chunking.chunk_bounds`); one
  :class:`~graphcal.factors.ChunkOdometryFactor` per chunk integrates eq. (1) from the chunk's
  start and tracks the measured poses; Pose2 variables at the chunk boundaries, initialized
  on the nominal odometry, carry a near-hard continuity residual;
* optionally per chunk one vector of wheel-rotation corrections under a size prior and the
  paper's smoothness prior on Δu (linear C++ factors);
* theta: a 4-vector variable (optionally under a prior) or a fixed value.

Users: the batch solve (one chunk per segment, no corrections), input estimation (one
segment, theta fixed, corrections), the joint solve (start poses, corrections and theta)
and the naive per-step benchmark (chunks of one step).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.errors import CalibrationFailed
from graphcal.factors import (
    CONTINUITY_SIGMAS,
    ChunkOdometryFactor,
    OdometryChunk,
    chunk_boundary_smoothness,
    chunk_correction_prior,
    pose2_from_state,
    state_from_pose2,
    theta_prior_factor,
)
from graphcal.graph import keys
from graphcal.graph.chunking import chunk_bounds
from graphcal.graph.plausibility import check_plausible
from graphcal.graph.solve import marginal_covariance, solve_lm
from graphcal.model import integrate


@dataclass(frozen=True)
class CorrectionPrior:
    """The prior on wheel-rotation corrections ``[dn_rl, dn_rr]`` [rev] of every step.

    Attributes:
        sigma: zero-mean size sigma [rev] (the wheel noise; or a floor with ``relative``).
        relative: size sigma as a fraction of the measured rotation, at least ``sigma``
            (the paper's ±5 % input bound, softened); 0 for an absolute sigma.
        smoothness_sigma: sigma [rev] of the change of a corrected rotation from one step to
            the next (the paper's R = 1000 is 0.032 rev), or ``None`` for no smoothness term.
    """

    sigma: float
    relative: float = 0.0
    smoothness_sigma: float | None = None

    def size_sigmas(self, measured: np.ndarray) -> np.ndarray:
        """Per step and wheel size sigmas ``(L, 2)`` [rev] for measured rotations ``(L, 2)``."""
        return np.maximum(self.relative * np.abs(np.asarray(measured, float)), self.sigma)


@dataclass(frozen=True)
class SegmentGraphSpec:
    """The shape of a segment graph (SI).

    Attributes:
        theta: theta's initial value, or its fixed value when ``estimate_theta`` is false.
        estimate_theta: theta is a variable (key :data:`~graphcal.graph.keys.THETA`).
        theta_prior_sigmas: sigmas of a prior on theta at ``theta``, or ``None``.
        tracking_sigmas: ``[m, m, rad]`` of the tracking residuals.
        start_prior_sigmas: ``[m, m, rad]`` of the priors on free start poses (x and y
            equal), or ``None`` to hold each start at its measured pose.
        chunk_steps: steps per chunk factor; ``None`` for one chunk per segment.
        continuity_sigmas: ``[m, m, rad]`` of the chunk-boundary continuity.
        corrections: the corrections' prior, or ``None`` for no correction variables.
        slip_sigma: stationary sigma of a relative slip scale of each wheel per chunk (the
            rotation of wheel w becomes ``n_w · (1 + s_w)``; slow slip, a tyre's load), or
            ``None`` for none. The scales follow a first-order Gauss–Markov process with
            correlation time ``slip_time`` [s] from chunk to chunk.
        slip_time: that correlation time [s].
    """

    theta: np.ndarray
    tracking_sigmas: np.ndarray
    estimate_theta: bool = True
    theta_prior_sigmas: np.ndarray | None = None
    start_prior_sigmas: np.ndarray | None = None
    chunk_steps: int | None = None
    continuity_sigmas: np.ndarray = field(default_factory=lambda: CONTINUITY_SIGMAS.copy())
    corrections: CorrectionPrior | None = None
    slip_sigma: float | None = None
    slip_time: float = 5.0


@dataclass(frozen=True)
class SegmentGraph:
    """A built segment graph: factors, initial values and the chunking of each segment."""

    graph: gtsam.NonlinearFactorGraph
    values: gtsam.Values
    bounds: list[np.ndarray]
    spec: SegmentGraphSpec
    data: SegmentData

    def start_states(self, result: gtsam.Values) -> np.ndarray:
        """Estimated (or held) start state of each segment, ``(S, 3)``."""
        starts = self.data.poses[:, 0].copy()
        if self.spec.start_prior_sigmas is not None:
            for s in range(len(self.data)):
                pose = result.atPose2(keys.segment_pose(s))
                starts[s] = state_from_pose2(pose, self.data.poses[s, 0, 2])
        return starts

    def corrections(self, result: gtsam.Values, segment: int) -> np.ndarray:
        """Estimated wheel-rotation corrections ``(K, 2)`` [rev] of ``segment``."""
        if self.spec.corrections is None:
            raise ValueError("this segment graph has no correction variables")
        chunks = range(len(self.bounds[segment]) - 1)
        parts = [result.atVector(keys.segment_corrections(segment, j)) for j in chunks]
        return np.concatenate(parts).reshape(-1, 2)

    def values_at(
        self,
        states: list[np.ndarray],
        corrections: list[np.ndarray] | None,
        theta: np.ndarray,
    ) -> gtsam.Values:
        """Values of every variable from per-segment states ``(K+1, 3)``, corrections
        ``(K, 2)`` and theta (e.g. at the truth of a synthetic drive)."""
        values = gtsam.Values()
        if self.spec.estimate_theta:
            values.insert(keys.THETA, np.asarray(theta, float))
        for s, bounds in enumerate(self.bounds):
            _insert_segment(values, s, bounds, states[s], self.spec)
            if self.spec.corrections is not None and corrections is not None:
                for j in range(len(bounds) - 1):
                    a, b = int(bounds[j]), int(bounds[j + 1])
                    values.insert(keys.segment_corrections(s, j), corrections[s][a:b].ravel())
        return values


def _insert_segment(
    values: gtsam.Values, s: int, bounds: np.ndarray, states: np.ndarray, spec: SegmentGraphSpec
) -> None:
    """Insert the Pose2 variables of segment ``s`` (free start, chunk boundaries) and its
    slip scales (at zero)."""
    if spec.slip_sigma is not None:
        for j in range(len(bounds) - 1):
            values.insert(keys.segment_slip(s, j), np.zeros(2))
    if spec.start_prior_sigmas is not None:
        values.insert(keys.segment_pose(s), pose2_from_state(states[0]))
    for j in range(1, len(bounds) - 1):
        values.insert(keys.segment_pose(s, j), pose2_from_state(states[int(bounds[j])]))


def build_segment_graph(data: SegmentData, spec: SegmentGraphSpec) -> SegmentGraph:
    """The graph of ``spec`` over ``data``'s segments and its initial values.

    Boundary poses start on the nominal odometry (measured start, measured inputs, initial
    theta), corrections at zero, theta at ``spec.theta``.
    """
    theta0 = np.asarray(spec.theta, float)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    theta_slot: int | np.ndarray = theta0
    if spec.estimate_theta:
        theta_slot = keys.THETA
        values.insert(keys.THETA, theta0)
        if spec.theta_prior_sigmas is not None:
            graph.add(theta_prior_factor(keys.THETA, np.asarray(spec.theta_prior_sigmas), theta0))
    free_start = spec.start_prior_sigmas is not None
    if free_start:
        prior = np.asarray(spec.start_prior_sigmas, float)
        position_noise = gtsam.noiseModel.Isotropic.Sigma(2, float(prior[0]))
        heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, float(prior[2]))
    continuity = np.asarray(spec.continuity_sigmas, float)
    tracking = np.asarray(spec.tracking_sigmas, float)
    all_bounds = []
    for s in range(len(data)):
        poses, inputs = data.segment(s)
        nominal = integrate(poses[0], inputs, theta0)
        bounds = chunk_bounds(len(inputs), spec.chunk_steps)
        all_bounds.append(bounds)
        _insert_segment(values, s, bounds, nominal, spec)
        if spec.slip_sigma is not None:
            _add_slip(graph, s, bounds, data.dt, spec)
        if free_start:
            start_key = keys.segment_pose(s)
            graph.add(
                gtsam.PoseTranslationPrior2D(start_key, gtsam.Point2(*poses[0, :2]), position_noise)
            )
            graph.add(gtsam.PoseRotationPrior2D(start_key, gtsam.Rot2(poses[0, 2]), heading_noise))
        n_chunks = len(bounds) - 1
        for j in range(n_chunks):
            a, b = int(bounds[j]), int(bounds[j + 1])
            last = j == n_chunks - 1
            correction_key = None
            if spec.corrections is not None:
                correction_key = _add_corrections(graph, values, s, j, bounds, inputs, spec)
            start: int | np.ndarray = keys.segment_pose(s, j)
            if j == 0 and not free_start:
                start = poses[0]
            chunk = OdometryChunk(inputs[a:b], poses[a : b + 1], float(nominal[a, 2]))
            factor = ChunkOdometryFactor(
                chunk,
                start,
                theta_slot,
                corrections=correction_key,
                end=None if last else keys.segment_pose(s, j + 1),
                tracking_sigmas=tracking,
                continuity_sigmas=continuity,
                slip=None if spec.slip_sigma is None else keys.segment_slip(s, j),
            )
            graph.add(factor.factor())
    return SegmentGraph(graph, values, all_bounds, spec, data)


def _add_slip(
    graph: gtsam.NonlinearFactorGraph,
    s: int,
    bounds: np.ndarray,
    dt: float,
    spec: SegmentGraphSpec,
) -> None:
    """Priors of segment ``s``'s slip scales: stationary (sigma ``spec.slip_sigma``) at the
    first chunk, then a first-order Gauss–Markov step between consecutive chunks,
    ``s_j − φ s_(j−1) ~ N(0, sigma² (1 − φ²))`` with ``φ = exp(−chunk duration / slip_time)``,
    so that every chunk's scale has the stationary sigma."""
    sigma = float(spec.slip_sigma)
    graph.add(
        gtsam.PriorFactorVector(
            keys.segment_slip(s, 0), np.zeros(2), gtsam.noiseModel.Isotropic.Sigma(2, sigma)
        )
    )
    zero = gtsam.Values()
    for j in range(len(bounds) - 1):
        zero.insert(keys.segment_slip(s, j), np.zeros(2))
    for j in range(1, len(bounds) - 1):
        phi = float(np.exp(-(bounds[j] - bounds[j - 1]) * dt / spec.slip_time))
        step_sigma = sigma * np.sqrt(max(1.0 - phi**2, 1e-12))
        linear = gtsam.JacobianFactor(
            keys.segment_slip(s, j - 1),
            -phi * np.eye(2),
            keys.segment_slip(s, j),
            np.eye(2),
            np.zeros(2),
            gtsam.noiseModel.Isotropic.Sigma(2, float(step_sigma)),
        )
        # Linear in the scales: linearized at zero, the container is exact everywhere.
        graph.add(gtsam.LinearContainerFactor(linear, zero))


def _add_corrections(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    s: int,
    j: int,
    bounds: np.ndarray,
    inputs: np.ndarray,
    spec: SegmentGraphSpec,
) -> int:
    """Correction variable of chunk ``j`` of segment ``s`` with its priors; returns its key."""
    prior = spec.corrections
    a, b = int(bounds[j]), int(bounds[j + 1])
    measured = inputs[:, :2]
    key = keys.segment_corrections(s, j)
    values.insert(key, np.zeros(2 * (b - a)))
    sizes = prior.size_sigmas(measured[a:b])
    graph.add(chunk_correction_prior(key, measured[a:b], sizes, prior.smoothness_sigma))
    if prior.smoothness_sigma is not None and j < len(bounds) - 2:
        c = int(bounds[j + 2])
        graph.add(
            chunk_boundary_smoothness(
                key,
                b - a,
                measured[b - 1],
                keys.segment_corrections(s, j + 1),
                c - b,
                measured[b],
                prior.smoothness_sigma,
            )
        )
    return key


@dataclass(frozen=True)
class ThetaEstimate:
    """Theta estimated from segments (SI).

    Attributes:
        theta: ``[c_e, c_d, t_r, d]`` (the fixed one if theta was not a variable).
        covariance: 4×4 marginal covariance of theta (every other variable marginalized),
            from the graph's information at the solution; ``None`` if not computed.
        start_states: ``(S, 3)`` estimated (or held) start states.
        iterations, initial_error, final_error: of the Levenberg–Marquardt run (graph error is
            half the whitened squared residual).
    """

    theta: np.ndarray
    covariance: np.ndarray | None
    start_states: np.ndarray
    iterations: int
    initial_error: float
    final_error: float
    #: Residual dimensions minus unknowns: the χ² of a solve that fits its noise model,
    #: ``2 * final_error``, is about this (0 when not known).
    degrees_of_freedom: int = field(default=0, kw_only=True)

    @property
    def chi2_per_dof(self) -> float | None:
        """``2 * final_error / degrees_of_freedom``: about 1 when the residuals fit the noise
        model, ``None`` when the degrees of freedom are not known."""
        if self.degrees_of_freedom <= 0:
            return None
        return 2.0 * self.final_error / self.degrees_of_freedom

    @property
    def theta_sigma(self) -> np.ndarray:
        """Standard deviation of each parameter (SI)."""
        return np.sqrt(np.diag(self.covariance))


@dataclass(frozen=True)
class SegmentSolution(ThetaEstimate):
    """A solved segment graph: the estimate with the solution's values (``result``) and the
    graph that was solved (``built``)."""

    result: gtsam.Values
    built: SegmentGraph

    def estimate(self) -> ThetaEstimate:
        """The estimate alone (picklable: no GTSAM objects)."""
        return ThetaEstimate(
            self.theta,
            self.covariance,
            self.start_states,
            self.iterations,
            self.initial_error,
            self.final_error,
            degrees_of_freedom=self.degrees_of_freedom,
        )


def solve_segment_graph(
    data: SegmentData,
    spec: SegmentGraphSpec,
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    covariance: bool = True,
) -> SegmentSolution:
    """Build the graph of ``spec`` over ``data`` and solve it with Levenberg–Marquardt.

    An estimated theta is checked for plausibility (for a vehicle whose nominal theta is the
    initial ``spec.theta``) and, with ``covariance``, gets its marginal covariance.

    Raises:
        CalibrationFailed: if the solve fails, or theta is non-finite or implausible.
    """
    built = build_segment_graph(data, spec)
    initial_error = float(built.graph.error(built.values))
    result, iterations = solve_lm(
        built.graph, built.values, max_iterations, relative_error_tol, label, CalibrationFailed
    )
    theta = np.asarray(spec.theta, float)
    marginal = None
    if spec.estimate_theta:
        theta = np.asarray(result.atVector(keys.THETA))
        check_plausible(theta, label, reference=spec.theta)
        if covariance:
            marginal = marginal_covariance(
                built.graph, result, keys.THETA, label, CalibrationFailed
            )
    return SegmentSolution(
        theta=theta,
        covariance=marginal,
        start_states=built.start_states(result),
        iterations=iterations,
        initial_error=initial_error,
        final_error=float(built.graph.error(result)),
        result=result,
        built=built,
        degrees_of_freedom=degrees_of_freedom(built.graph, result),
    )


def degrees_of_freedom(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> int:
    """Residual dimensions of ``graph`` minus the dimensions of the unknowns in ``values``."""
    residuals = sum(graph.at(i).dim() for i in range(graph.size()) if graph.at(i) is not None)
    return int(residuals - values.dim())
