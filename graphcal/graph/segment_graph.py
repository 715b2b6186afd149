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
* theta: a 4-vector variable (optionally under a prior) or a fixed value;
* optionally the defects of real logs as variables under zero-mean priors: the wheels' time
  offset against the pose and the GNSS antenna's lever arm (one each for the graph) and a
  bias of the measured heading per segment; with a lever arm or heading bias, the free
  start poses are measured through them (:class:`~graphcal.factors.MeasuredPoseFactor`);
* optionally per-fix weights (``SegmentData.fix_weights``) that widen the sigmas of outlying
  fixes (robust estimation by iterative reweighting, :mod:`graphcal.graph.robust`).

Users: the batch solve (one chunk per segment, no corrections), input estimation (one
segment, theta fixed, corrections), the joint solve (start poses, corrections and theta)
and the naive per-step benchmark (chunks of one step).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.data.segments import SegmentData
from graphcal.data.timing import rotation_rate_changes
from graphcal.errors import CalibrationFailed, first_line
from graphcal.factors import (
    CONTINUITY_SIGMAS,
    ChunkBatch,
    ChunkOdometryFactor,
    MeasuredPoseFactor,
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
from graphcal.graph.segmented import SegmentedGraph, optimize_segmented
from graphcal.graph.slip import slip_prior_factor, slip_step_factor
from graphcal.graph.solve import marginal_covariance, solve_lm
from graphcal.model import aligned_trajectory, integrate, lever_offset


@dataclass(frozen=True)
class CorrectionPrior:
    """The prior on wheel-rotation corrections ``[dn_rl, dn_rr]`` [rev] of every step.

    Attributes:
        sigma: zero-mean size sigma [rev] (the wheel noise; or a floor with ``relative``).
        relative: size sigma as a fraction of the measured rotation, at least ``sigma``
            (the paper's ±5 % input bound, softened); 0 for an absolute sigma.
        smoothness_sigma: sigma [rev] of the change of a corrected rotation from one step to
            the next (the paper's R = 1000 is 0.032 rev), or ``None`` for no smoothness term.
        quantization: sigma [rev] of the rounding error of each wheel's cumulative count
            (tick quantization, :func:`~graphcal.factors.chunk_correction_prior`), or 0.
    """

    sigma: float
    relative: float = 0.0
    smoothness_sigma: float | None = None
    quantization: float = 0.0

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
        time_offset_sigma: prior sigma [s] of the wheels' time offset (a variable,
            :data:`~graphcal.graph.keys.TIME_OFFSET`), or ``None`` for none.
        time_offset_mean: that prior's mean [s] (and the variable's initial value).
        lever_arm_sigma: prior sigma [m] of each component of the antenna's lever arm (a
            variable, :data:`~graphcal.graph.keys.LEVER_ARM`), or ``None`` for none.
        heading_bias_sigma: prior sigma [rad] of a per-segment bias of the measured heading,
            or ``None`` for none.
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
    time_offset_sigma: float | None = None
    time_offset_mean: float = 0.0
    lever_arm_sigma: float | None = None
    heading_bias_sigma: float | None = None

    def nuisance_keys(self) -> dict[str, int]:
        """Graph-wide variables besides theta, by name: ``"time_offset"``, ``"lever_arm"``."""
        found = {}
        if self.time_offset_sigma is not None:
            found["time_offset"] = keys.TIME_OFFSET
        if self.lever_arm_sigma is not None:
            found["lever_arm"] = keys.LEVER_ARM
        return found


@dataclass(frozen=True)
class ChunkFactorSlot:
    """Where a chunk factor sits: its index in the graph, its segment and its steps
    ``first .. end`` (tracking the poses ``first+1 .. end``), and which rows of the full
    tracking error it keeps (``None``: all; :attr:`OdometryChunk.residual_rows`)."""

    index: int
    segment: int
    first: int
    end: int
    rows: np.ndarray | None = None


@dataclass(frozen=True)
class SegmentGraph:
    """A built segment graph: factors, initial values and the chunking of each segment."""

    graph: gtsam.NonlinearFactorGraph
    values: gtsam.Values
    bounds: list[np.ndarray]
    spec: SegmentGraphSpec
    data: SegmentData
    chunk_factors: tuple[ChunkFactorSlot, ...] = ()

    def fix_residuals(
        self, result: gtsam.Values, segmented: SegmentedGraph | None = None
    ) -> np.ndarray:
        """Position residuals ``(S, K+1, 2)`` [m] of every measured pose at ``result`` (the
        predicted antenna position minus the measured one; zero at padding and at held
        starts), for robust reweighting. With ``segmented`` (this graph split at the same
        values) each chunk is evaluated on its segment's own ``Values``: GTSAM copies the
        ``Values`` for every Python factor call."""
        data = self.data
        out = np.zeros((len(data), data.poses.shape[1], 2))
        values_of = {} if segmented is None else segmented.values_by_key()
        for slot in self.chunk_factors:
            factor = self.graph.at(slot.index)
            values = values_of.get(int(factor.keys()[0]), result)
            error = np.asarray(factor.unwhitenedError(values))
            n = slot.end - slot.first
            if slot.rows is not None:  # rows of unmeasured components stay zero
                full = np.zeros(3 * n + 3)
                full[slot.rows] = error
                error = full
            out[slot.segment, slot.first + 1 : slot.end + 1] = error[: 3 * n].reshape(n, 3)[:, :2]
        if self.spec.start_prior_sigmas is not None:
            starts = self.start_states(result)
            arm = np.zeros(2)
            if self.spec.lever_arm_sigma is not None:
                arm = np.asarray(result.atVector(keys.LEVER_ARM))
            antenna = starts[:, :2] + lever_offset(starts[:, 2], arm)
            out[:, 0] = np.where(data.start_measured()[:, :1], antenna - data.poses[:, 0, :2], 0.0)
        return out

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
        _insert_nuisance(values, self.spec)
        for s, bounds in enumerate(self.bounds):
            _insert_segment(values, s, bounds, states[s], self.spec, _with_heading(self.data, s))
            if self.spec.corrections is not None and corrections is not None:
                for j in range(len(bounds) - 1):
                    a, b = int(bounds[j]), int(bounds[j + 1])
                    values.insert(keys.segment_corrections(s, j), corrections[s][a:b].ravel())
        return values


def _with_heading(data: SegmentData, s: int) -> bool:
    """Segment ``s`` measures the heading somewhere (else it has no heading bias)."""
    measured = data.measured_of(s)
    return measured is None or bool(measured[:, 1].any())


def _insert_segment(
    values: gtsam.Values,
    s: int,
    bounds: np.ndarray,
    states: np.ndarray,
    spec: SegmentGraphSpec,
    with_heading: bool = True,
) -> None:
    """Insert the Pose2 variables of segment ``s`` (free start, chunk boundaries) and its
    slip scales (at zero) and heading bias (if it measures the heading)."""
    if spec.slip_sigma is not None:
        for j in range(len(bounds) - 1):
            values.insert(keys.segment_slip(s, j), np.zeros(2))
    if spec.heading_bias_sigma is not None and with_heading:
        values.insert(keys.segment_heading_bias(s), np.zeros(1))
    if spec.start_prior_sigmas is not None:
        values.insert(keys.segment_pose(s), pose2_from_state(states[0]))
    for j in range(1, len(bounds) - 1):
        values.insert(keys.segment_pose(s, j), pose2_from_state(states[int(bounds[j])]))


def _insert_nuisance(values: gtsam.Values, spec: SegmentGraphSpec) -> None:
    """Insert the graph-wide time offset (at its prior mean) and lever arm (at zero) if
    ``spec`` has them."""
    if spec.time_offset_sigma is not None:
        values.insert(keys.TIME_OFFSET, np.full(1, float(spec.time_offset_mean)))
    if spec.lever_arm_sigma is not None:
        values.insert(keys.LEVER_ARM, np.zeros(2))


def _vector_prior(key: int, size: int, sigma: float, mean: float = 0.0) -> gtsam.PriorFactorVector:
    return gtsam.PriorFactorVector(
        key, np.full(size, float(mean)), gtsam.noiseModel.Isotropic.Sigma(size, float(sigma))
    )


def build_segment_graph(
    data: SegmentData,
    spec: SegmentGraphSpec,
    shared_start: dict[int, np.ndarray] | None = None,
) -> SegmentGraph:
    """The graph of ``spec`` over ``data``'s segments and its initial values.

    Boundary poses start on the odometry (measured inputs, initial theta) from the measured
    start, corrections at zero, theta at ``spec.theta``. ``shared_start`` gives other initial
    values of graph-wide variables (by key: theta, time offset, lever arm; the priors stay at
    ``spec``'s); with a start theta, an estimated start is moved (with its path, rigidly) to
    fit the measured positions.
    """
    theta0 = np.asarray(spec.theta, float)
    shared_start = shared_start or {}
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    theta_slot: int | np.ndarray = theta0
    integrate_with = theta0
    if spec.estimate_theta:
        theta_slot = keys.THETA
        integrate_with = np.asarray(shared_start.get(keys.THETA, theta0), float)
        values.insert(keys.THETA, integrate_with)
        if spec.theta_prior_sigmas is not None:
            graph.add(theta_prior_factor(keys.THETA, np.asarray(spec.theta_prior_sigmas), theta0))
    _insert_nuisance(values, spec)
    for key, value in shared_start.items():
        if key != keys.THETA and values.exists(key):
            values.update(key, np.asarray(value, float))
    time_offset_key = lever_arm_key = None
    if spec.time_offset_sigma is not None:
        time_offset_key = keys.TIME_OFFSET
        graph.add(_vector_prior(time_offset_key, 1, spec.time_offset_sigma, spec.time_offset_mean))
    if spec.lever_arm_sigma is not None:
        lever_arm_key = keys.LEVER_ARM
        graph.add(_vector_prior(lever_arm_key, 2, spec.lever_arm_sigma))
    free_start = spec.start_prior_sigmas is not None
    # With a theta already solved (a warm start) the odometry has the path's shape, and its
    # start is moved to fit the fixes: a measured start heading is 1.5° off, 4 m of drift over
    # 150 m. The nominal theta's path is bent (c_d), and fitting it moves the start away from
    # where the solve converges fast (31 → 50+ iterations on a straight road).
    align = free_start and keys.THETA in shared_start
    arm = shared_start.get(keys.LEVER_ARM) if spec.lever_arm_sigma is not None else None
    continuity = np.asarray(spec.continuity_sigmas, float)
    tracking = np.asarray(spec.tracking_sigmas, float)
    all_bounds = []
    slots = []
    start_measured = data.start_measured()
    for s in range(len(data)):
        poses, inputs = data.segment(s)
        weights = data.weights_of(s)
        measured, fractions = data.measured_of(s), data.fractions_of(s)
        nominal = integrate(poses[0], inputs, integrate_with)
        if align:  # a solved theta's path, from where it fits the fixes best
            fitted = weights
            if measured is not None:  # the fixes, not the track between them
                fitted = measured[:, 0] * (1.0 if weights is None else weights)
            nominal = aligned_trajectory(nominal, poses, fitted, arm)
        bounds = chunk_bounds(len(inputs), spec.chunk_steps)
        all_bounds.append(bounds)
        with_heading = _with_heading(data, s)
        _insert_segment(values, s, bounds, nominal, spec, with_heading)
        if spec.slip_sigma is not None:
            _add_slip(graph, s, bounds, data.dt, spec)
        bias_key = None
        if spec.heading_bias_sigma is not None and with_heading:
            bias_key = keys.segment_heading_bias(s)
            graph.add(_vector_prior(bias_key, 1, spec.heading_bias_sigma))
        if free_start and start_measured[s].any():
            start_weight = 1.0 if weights is None else float(weights[0])
            _add_start_prior(
                graph,
                s,
                poses[0],
                spec,
                lever_arm_key,
                bias_key,
                start_weight,
                (bool(start_measured[s, 0]), bool(start_measured[s, 1])),
            )
        rates = None
        if time_offset_key is not None:
            rates = rotation_rate_changes(inputs[:, :2], data.dt)
        n_chunks = len(bounds) - 1
        batch = ChunkBatch()  # the segment's chunk factors evaluated together, vectorized
        for j in range(n_chunks):
            a, b = int(bounds[j]), int(bounds[j + 1])
            last = j == n_chunks - 1
            correction_key = None
            if spec.corrections is not None:
                correction_key = _add_corrections(graph, values, s, j, bounds, inputs, spec)
            start: int | np.ndarray = keys.segment_pose(s, j)
            if j == 0 and not free_start:
                start = poses[0]
            chunk = OdometryChunk(
                inputs[a:b],
                poses[a : b + 1],
                float(nominal[a, 2]),
                None if rates is None else rates[a:b],
                None if fractions is None else fractions[a + 1 : b + 1],
                None if measured is None else measured[a : b + 1],
            )
            factor = ChunkOdometryFactor(
                chunk,
                start,
                theta_slot,
                corrections=correction_key,
                end=None if last else keys.segment_pose(s, j + 1),
                tracking_sigmas=tracking,
                continuity_sigmas=continuity,
                slip=None if spec.slip_sigma is None else keys.segment_slip(s, j),
                time_offset=time_offset_key,
                lever_arm=lever_arm_key,
                heading_bias=bias_key,
                fix_weights=None if weights is None else weights[a + 1 : b + 1],
                batch=batch,
            )
            slots.append(ChunkFactorSlot(int(graph.size()), s, a, b, factor.rows))
            graph.add(factor.factor())
    return SegmentGraph(graph, values, all_bounds, spec, data, tuple(slots))


def _add_start_prior(
    graph: gtsam.NonlinearFactorGraph,
    s: int,
    measured: np.ndarray,
    spec: SegmentGraphSpec,
    lever_arm_key: int | None,
    bias_key: int | None,
    weight: float,
    components: tuple[bool, bool] = (True, True),
) -> None:
    """The measured start pose of segment ``s`` on its free start (the paper's W): GTSAM's
    priors, or a :class:`~graphcal.factors.MeasuredPoseFactor` through the lever arm and the
    heading bias when those are variables; the position sigma widened by a fix weight. Only
    the measured ``components`` [position, heading] enter (a start without a measured
    heading stays free in heading: the fixes after it determine it)."""
    prior = np.asarray(spec.start_prior_sigmas, float).copy()
    prior[:2] /= np.sqrt(weight)
    start_key = keys.segment_pose(s)
    position, heading = bool(components[0]), bool(components[1])
    if position and (lever_arm_key is not None or (bias_key is not None and heading)):
        factor = MeasuredPoseFactor(
            start_key,
            measured,
            prior,
            lever_arm_key,
            bias_key if heading else None,
            with_heading=heading,
        )
        graph.add(factor.factor())
        return
    if position:
        position_noise = gtsam.noiseModel.Isotropic.Sigma(2, float(prior[0]))
        graph.add(
            gtsam.PoseTranslationPrior2D(start_key, gtsam.Point2(*measured[:2]), position_noise)
        )
    if heading:  # (a heading without a position at the start: its bias is left out there)
        heading_noise = gtsam.noiseModel.Isotropic.Sigma(1, float(prior[2]))
        graph.add(gtsam.PoseRotationPrior2D(start_key, gtsam.Rot2(measured[2]), heading_noise))


def _add_slip(
    graph: gtsam.NonlinearFactorGraph,
    s: int,
    bounds: np.ndarray,
    dt: float,
    spec: SegmentGraphSpec,
) -> None:
    """Priors of segment ``s``'s slip scales, one 2-vector per chunk
    (:mod:`graphcal.graph.slip`: stationary at the first chunk, Gauss–Markov steps after)."""
    sigma = float(spec.slip_sigma)
    graph.add(slip_prior_factor(keys.segment_slip(s, 0), sigma))
    for j in range(1, len(bounds) - 1):
        duration = float((bounds[j] - bounds[j - 1]) * dt)
        graph.add(
            slip_step_factor(
                keys.segment_slip(s, j - 1),
                keys.segment_slip(s, j),
                duration,
                sigma,
                spec.slip_time,
            )
        )


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
    graph.add(
        chunk_correction_prior(
            key, measured[a:b], sizes, prior.smoothness_sigma, prior.quantization
        )
    )
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
class NuisanceEstimate:
    """A graph-wide variable besides theta (time offset, lever arm) estimated with it (SI).

    Attributes:
        value: the estimate ``(n,)``.
        covariance: its marginal covariance ``(n, n)``.
        prior_sigma: the sigma of its zero-mean prior.
    """

    value: np.ndarray
    covariance: np.ndarray
    prior_sigma: float

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviation of each component."""
        return np.sqrt(np.diag(self.covariance))

    def observable(self, max_sigma_ratio: float) -> np.ndarray:
        """Per component: the data shrank the prior sigma to at most ``max_sigma_ratio`` of
        it (the rule theta's parameters follow, :mod:`graphcal.graph.observability`)."""
        return self.sigma <= max_sigma_ratio * self.prior_sigma


@dataclass(frozen=True)
class ThetaEstimate:
    """Theta estimated from segments (SI).

    Attributes:
        theta: ``[c_e, c_d, t_r, d]`` (the fixed one if theta was not a variable).
        covariance: 4×4 marginal covariance of theta (every other variable marginalized),
            from the graph's information at the solution (or at the linearization of the
            solve's last Gauss–Newton step, :meth:`SegmentedGraph.optimize
            <graphcal.graph.segmented.SegmentedGraph.optimize>`); ``None`` if not computed.
        start_states: ``(S, 3)`` estimated (or held) start states.
        iterations, initial_error, final_error: of the solve (graph error is half the
            whitened squared residual; after a last Gauss–Newton step, the error it
            predicted, within far less than the solve's tolerance).
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
    #: Graph-wide variables estimated with theta, by name (``"time_offset"``, ``"lever_arm"``).
    nuisance: dict[str, NuisanceEstimate] = field(default_factory=dict, kw_only=True)

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
    """A solved segment graph: the estimate with the solution's values (``result``), the
    graph that was solved (``built``) and its split into segments at the solution
    (``segmented``, :class:`~graphcal.graph.segmented.SegmentedGraph`)."""

    result: gtsam.Values
    built: SegmentGraph
    segmented: SegmentedGraph | None = field(default=None, kw_only=True)

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
            nuisance=self.nuisance,
        )


def solve_segment_graph(
    data: SegmentData,
    spec: SegmentGraphSpec,
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    covariance: bool = True,
    initial: gtsam.Values | None = None,
    built: SegmentGraph | None = None,
    workers: int = 1,
    progress: Callable[[str], None] | None = None,
    shared_start: dict[int, np.ndarray] | None = None,
) -> SegmentSolution:
    """Build the graph of ``spec`` over ``data`` (or take ``built``, that graph already
    built) and solve it with Levenberg–Marquardt, from the builder's initial values (with
    ``shared_start``'s graph-wide variables, :func:`build_segment_graph`) or from
    ``initial`` (values of the same graph, e.g. an earlier solution: a warm start), segment by
    segment (:class:`~graphcal.graph.segmented.SegmentedGraph`), the segments shared out among
    ``workers`` processes (the result does not depend on it); ``progress`` gets a line per
    iteration of a long solve.

    From ``shared_start`` (graph built here) the first step is an undamped Gauss–Newton step.

    An estimated theta is checked for plausibility (for a vehicle whose nominal theta is the
    initial ``spec.theta``) and, with ``covariance``, gets its marginal covariance.

    Raises:
        CalibrationFailed: if the solve fails, or theta is non-finite or implausible.
    """
    from_shared_start = built is None and initial is None and bool(shared_start)
    if built is None:
        built = build_segment_graph(data, spec, shared_start)
    start = built.values if initial is None else initial
    segmented = SegmentedGraph(built.graph, start, shared_keys(spec))
    if len(segmented.parts) < 2:  # nothing to split: one graph under GTSAM's optimizer
        return _solve_whole_graph(
            built, start, max_iterations, relative_error_tol, label, covariance
        )
    theta = np.asarray(spec.theta, float)
    marginal, nuisance = None, {}
    with segmented.parallel(workers):
        iterations = optimize_segmented(
            segmented,
            max_iterations,
            relative_error_tol,
            label,
            CalibrationFailed,
            progress,
            gauss_newton_first=from_shared_start,
        )
        if spec.estimate_theta:
            theta = np.asarray(segmented.shared_values.atVector(keys.THETA))
            check_plausible(
                theta, label, spec.theta, lambda: implausibility_causes(built, segmented.values())
            )
            if covariance:
                marginal, nuisance = _marginals(segmented, spec, label)
    result = segmented.values()
    return SegmentSolution(
        theta=theta,
        covariance=marginal,
        start_states=built.start_states(result),
        iterations=iterations,
        initial_error=segmented.initial_error,
        final_error=segmented.error(),
        result=result,
        built=built,
        degrees_of_freedom=segmented.factor_dims() - segmented.dim(),
        nuisance=nuisance,
        segmented=segmented,
    )


def _solve_whole_graph(
    built: SegmentGraph,
    start: gtsam.Values,
    max_iterations: int,
    relative_error_tol: float,
    label: str,
    covariance: bool,
) -> SegmentSolution:
    """:func:`solve_segment_graph` for a graph that does not split into segments (theta
    alone, as in the batch solve of Step 1, or one segment with theta fixed, as in input
    estimation): GTSAM's optimizer and marginals, cheaper than the split machinery there."""
    spec = built.spec
    initial_error = float(built.graph.error(start))
    result, iterations = solve_lm(
        built.graph, start, max_iterations, relative_error_tol, label, CalibrationFailed
    )
    theta = np.asarray(spec.theta, float)
    marginal, nuisance = None, {}
    if spec.estimate_theta:
        theta = np.asarray(result.atVector(keys.THETA))
        check_plausible(theta, label, spec.theta, lambda: implausibility_causes(built, result))
        if covariance:
            marginal, nuisance = _whole_graph_marginals(built, result, label)
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
        nuisance=nuisance,
    )


def _whole_graph_marginals(
    built: SegmentGraph, result: gtsam.Values, label: str
) -> tuple[np.ndarray, dict[str, NuisanceEstimate]]:
    """Theta's marginal covariance and the nuisance estimates from GTSAM's marginals."""
    extra = built.spec.nuisance_keys()
    joint = marginal_covariance(
        built.graph, result, [keys.THETA, *extra.values()], label, CalibrationFailed
    )
    return joint[:4, :4], _nuisance(built.spec, result, joint)


def shared_keys(spec: SegmentGraphSpec) -> list[int]:
    """The variables every segment of ``spec``'s graph shares: theta (if estimated), then
    the time offset and the lever arm (if present)."""
    found = [keys.THETA] if spec.estimate_theta else []
    return [*found, *spec.nuisance_keys().values()]


def _marginals(
    segmented: SegmentedGraph, spec: SegmentGraphSpec, label: str
) -> tuple[np.ndarray, dict[str, NuisanceEstimate]]:
    """Theta's marginal covariance and the graph-wide nuisance estimates at ``segmented``'s
    values: the inverse of the shared variables' information, every segment's variables
    marginalized."""
    try:
        information = segmented.shared_information()
    except RuntimeError as exc:
        reason = first_line(str(exc)) or type(exc).__name__
        raise CalibrationFailed(f"{label} failed: covariance: {reason}") from exc
    joint = _inverse(0.5 * (information + information.T))
    if joint is None:
        raise CalibrationFailed(f"{label} failed: covariance: the information is singular")
    return joint[:4, :4], _nuisance(spec, segmented.shared_values, joint)


def _nuisance(
    spec: SegmentGraphSpec, values: gtsam.Values, joint: np.ndarray
) -> dict[str, NuisanceEstimate]:
    """The graph-wide nuisance estimates from ``values`` and the joint covariance of theta
    and them (in :meth:`SegmentGraphSpec.nuisance_keys` order after theta)."""
    priors = {"time_offset": spec.time_offset_sigma, "lever_arm": spec.lever_arm_sigma}
    nuisance, at = {}, 4
    for name, key in spec.nuisance_keys().items():
        value = np.asarray(values.atVector(key))
        n = len(value)
        nuisance[name] = NuisanceEstimate(value, joint[at : at + n, at : at + n], priors[name])
        at += n
    return nuisance


def _inverse(information: np.ndarray) -> np.ndarray | None:
    """The inverse of a symmetric positive definite ``information``, or ``None`` if it is
    not (or the inverse is not finite)."""
    try:
        root = np.linalg.cholesky(information)
    except np.linalg.LinAlgError:
        return None
    inverse_root = np.linalg.inv(root)
    covariance = inverse_root.T @ inverse_root
    return covariance if np.all(np.isfinite(covariance)) else None


def with_covariance(solution: SegmentSolution, label: str, workers: int = 1) -> SegmentSolution:
    """``solution`` with theta's marginal covariance and the nuisance estimates computed
    (segment by segment, in ``workers`` processes)."""
    if solution.covariance is not None or not solution.built.spec.estimate_theta:
        return solution
    segmented = solution.segmented
    if segmented is None:  # solved as one graph
        marginal, nuisance = _whole_graph_marginals(solution.built, solution.result, label)
        return dataclasses.replace(solution, covariance=marginal, nuisance=nuisance)
    with segmented.parallel(workers):
        marginal, nuisance = _marginals(segmented, solution.built.spec, label)
    return dataclasses.replace(solution, covariance=marginal, nuisance=nuisance)


def degrees_of_freedom(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> int:
    """Residual dimensions of ``graph`` minus the dimensions of the unknowns in ``values``."""
    residuals = sum(graph.at(i).dim() for i in range(graph.size()) if graph.at(i) is not None)
    return int(residuals - values.dim())


#: Fix rate [Hz] below which an implausible theta names the rate among its causes, and
#: heading sigma [rad] below which it names the heading's weight (0.05°).
SLOW_FIX_RATE = 2.0
TIGHT_HEADING_SIGMA = float(np.deg2rad(0.05))
#: Mean |yaw rate| [rad/s] of the segments below which the drive leaves t_r and d to priors.
STRAIGHT_YAW_RATE = 0.02


def implausibility_causes(built: SegmentGraph, result: gtsam.Values) -> tuple[str, ...]:
    """What in the data or the weights of ``built`` may have driven its solve to an
    implausible theta (one phrase each, with the key or option to change)."""
    data, spec = built.data, built.spec
    causes = []
    if data.has_heading() and float(spec.tracking_sigmas[2]) < TIGHT_HEADING_SIGMA:
        causes.append(
            f"the heading weighs as a {np.degrees(spec.tracking_sigmas[2]):.3f}° measurement "
            "(check heading_unit and the heading noise, [joint] heading_noise_from_log)"
        )
    fixes = data.position_fixes()
    seconds = float(data.n_steps.sum() * data.dt)
    rate = float(fixes.sum()) / seconds if seconds > 0 else 0.0
    if rate < SLOW_FIX_RATE:
        causes.append(f"position fixes at only {rate:.1f} Hz")
    if spec.time_offset_sigma is not None and result.exists(keys.TIME_OFFSET):
        offset = float(result.atVector(keys.TIME_OFFSET)[0])
        if abs(offset - spec.time_offset_mean) > 3.0 * spec.time_offset_sigma:
            causes.append(
                f"the wheels' time offset went to {offset:+.2f} s, beyond its prior "
                f"(±{spec.time_offset_sigma:g} s): check the streams' time bases"
            )
    turned = np.abs(np.diff(data.poses[..., 2], axis=1))[data.valid[:, 1:]].sum()
    if seconds > 0 and turned / seconds < STRAIGHT_YAW_RATE:
        causes.append(
            f"the drive barely turns (mean |yaw rate| {turned / seconds:.3f} rad/s), so t_r "
            "and d rest on their priors"
        )
    return tuple(causes)
