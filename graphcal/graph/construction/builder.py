"""The one graph builder for segments of a drive: multiple shooting over chunks.

Every calibration graph of graphcal is an instance of this shape, chosen by a
:class:`~graphcal.graph.construction.graph_spec.SegmentGraphSpec`:

* per segment, its start: held at the measured pose, or a Pose2 variable under world-frame
  position and heading priors at the measured pose (the paper's W);
* the segment cut into chunks (:func:`~graphcal.graph.construction.chunking.chunk_bounds`); one
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
  fixes (robust estimation by iterative reweighting, :mod:`graphcal.pipeline.solvers.robust`).

Users: the batch solve (one chunk per segment, no corrections), input estimation (one
segment, theta fixed, corrections), the joint solve (start poses, corrections and theta)
and the naive per-step benchmark (chunks of one step).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field

import gtsam
import numpy as np

from graphcal.alignment import aligned_trajectory
from graphcal.factors import (
    ChunkBatch,
    ChunkNoise,
    ChunkOdometryFactor,
    DefectKeys,
    MeasuredPoseFactor,
    OdometryChunk,
    chunk_boundary_smoothness,
    chunk_correction_prior,
    theta_prior_factor,
)
from graphcal.graph.construction import keys
from graphcal.graph.construction.built_graph import (
    BuiltGraph,
    ChunkFactorSlot,
    insert_nuisance,
    insert_segment,
    with_heading,
)
from graphcal.graph.construction.chunk_processes import (
    add_fix_error_priors,
    add_slip_priors,
    fix_error_keys,
)
from graphcal.graph.construction.chunking import chunk_bounds
from graphcal.graph.construction.graph_spec import SegmentGraphSpec
from graphcal.log.segments import SegmentData
from graphcal.log.timing import rotation_rate_changes
from graphcal.model import integrate


@dataclass(frozen=True)
class _GraphWide:
    """The graph-wide variables as every segment's factors see them.

    Attributes:
        theta_key: theta's key, or ``None`` when theta is not a variable.
        fixed_theta: theta's value when it is not a variable (``spec.theta``).
        integrate_with: the theta the boundary poses' initial values are integrated with.
        time_offset_key, lever_arm_key, rear_slip_gain_key: those variables' keys, or
            ``None``.
        align: move each free start (with its path) to fit the fixes (a solved start theta).
        arm: the lever arm to align with, or ``None``.
        tracking, continuity: the spec's sigmas as arrays.
    """

    theta_key: int | None
    fixed_theta: np.ndarray
    integrate_with: np.ndarray
    time_offset_key: int | None
    lever_arm_key: int | None
    rear_slip_gain_key: int | None
    align: bool
    arm: np.ndarray | None
    tracking: np.ndarray
    continuity: np.ndarray


@dataclass(frozen=True)
class _Segment:
    """One segment's measurements, initial states ``nominal`` and chunk ``bounds``; whether
    its start's position and heading are measured, and whether it is tied to the segment
    before (its start is that one's end, measured there) and after (its last chunk ends at
    that one's start)."""

    index: int
    poses: np.ndarray
    inputs: np.ndarray
    weights: np.ndarray | None
    measured: np.ndarray | None
    fractions: np.ndarray | None
    nominal: np.ndarray
    bounds: np.ndarray
    run: int = 0
    start_measured: np.ndarray = field(default_factory=lambda: np.ones(2, bool))
    tied_before: bool = False
    tied_after: bool = False


def _vector_prior(key: int, size: int, sigma: float, mean: float = 0.0) -> gtsam.PriorFactorVector:
    return gtsam.PriorFactorVector(
        key, np.full(size, float(mean)), gtsam.noiseModel.Isotropic.Sigma(size, float(sigma))
    )


def build_segment_graph(
    data: SegmentData,
    spec: SegmentGraphSpec,
    shared_start: dict[int, np.ndarray] | None = None,
) -> BuiltGraph:
    """The graph of ``spec`` over ``data``'s segments and its initial values.

    Boundary poses start on the odometry (measured inputs, initial theta) from the measured
    start, corrections at zero, theta at ``spec.theta``. ``shared_start`` gives other initial
    values of graph-wide variables (by key: theta, time offset, lever arm; the priors stay at
    ``spec``'s); with a start theta, an estimated start is moved (with its path, rigidly) to
    fit the measured positions.
    """
    spec = spec.for_runs(data.runs)
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    wide = _add_graph_wide(graph, values, spec, shared_start or {})
    all_bounds = []
    slots: list[ChunkFactorSlot] = []
    start_measured = data.start_measured()
    tied = spec.tied(data)
    nominals = _chain_nominals(data, tied, wide)
    for s in range(len(data)):
        segment = dataclasses.replace(
            _segment(data, s, spec, nominals[s]),
            start_measured=start_measured[s],
            tied_before=bool(tied[s]),
            tied_after=s + 1 < len(data) and bool(tied[s + 1]),
        )
        all_bounds.append(segment.bounds)
        _add_segment(graph, values, data, segment, spec, wide, slots)
    return BuiltGraph(graph, values, all_bounds, spec, data, tuple(slots))


def _add_graph_wide(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    spec: SegmentGraphSpec,
    shared_start: dict[int, np.ndarray],
) -> _GraphWide:
    """Theta (if a variable), the time offset and the lever arm with their priors, started
    at ``shared_start``'s values where it has them."""
    theta0 = np.asarray(spec.theta, float)
    theta_key = None
    integrate_with = theta0
    if spec.estimate_theta:
        theta_key = keys.THETA
        integrate_with = np.asarray(shared_start.get(keys.THETA, theta0), float)
        values.insert(keys.THETA, integrate_with)
        if spec.theta_prior_sigmas is not None:
            graph.add(theta_prior_factor(keys.THETA, np.asarray(spec.theta_prior_sigmas), theta0))
    insert_nuisance(values, spec)
    for key, value in shared_start.items():
        if key != keys.THETA and values.exists(key):
            values.update(key, np.asarray(value, float))
    time_offset_key = lever_arm_key = None
    if spec.time_offset_sigma is not None:
        time_offset_key = keys.TIME_OFFSET
        graph.add(
            gtsam.PriorFactorVector(
                time_offset_key,
                spec.time_offset_means(),
                gtsam.noiseModel.Isotropic.Sigma(spec.time_offset_runs, spec.time_offset_sigma),
            )
        )
    if spec.lever_arm_sigma is not None:
        lever_arm_key = keys.LEVER_ARM
        graph.add(_vector_prior(lever_arm_key, 2, spec.lever_arm_sigma))
    rear_slip_gain_key = None
    if spec.rear_slip_gain_sigma is not None:
        rear_slip_gain_key = keys.REAR_SLIP_GAIN
        graph.add(_vector_prior(rear_slip_gain_key, 1, spec.rear_slip_gain_sigma))
    # With a theta already solved (a warm start) the odometry has the path's shape, and its
    # start is moved to fit the fixes: a measured start heading is 1.5° off, 4 m of drift over
    # 150 m. The nominal theta's path is bent (c_d), and fitting it moves the start away from
    # where the solve converges fast (31 → 50+ iterations on a straight road).
    align = spec.start_prior_sigmas is not None and keys.THETA in shared_start
    arm = shared_start.get(keys.LEVER_ARM) if spec.lever_arm_sigma is not None else None
    return _GraphWide(
        theta_key,
        theta0,
        integrate_with,
        time_offset_key,
        lever_arm_key,
        rear_slip_gain_key,
        align,
        arm,
        np.asarray(spec.tracking_sigmas, float),
        np.asarray(spec.continuity_sigmas, float),
    )


def _chain_nominals(data: SegmentData, tied: np.ndarray, wide: _GraphWide) -> list[np.ndarray]:
    """Each segment's states on the odometry ``(K+1, 3)``: integrated from its measured start,
    or, tied, from the end of the one before, so that a chain of tied segments is one path;
    with a solved start theta each chain is moved as one rigid body to fit its fixes."""
    out: list[np.ndarray] = []
    heads = [*np.flatnonzero(~tied), len(data)]
    for head, stop in itertools.pairwise(heads):
        paths, fitted, measured = [], [], []
        state = data.segment(head)[0][0]
        for s in range(head, stop):
            poses, inputs = data.segment(s)
            path = integrate(state, inputs, wide.integrate_with)
            state = path[-1]
            weights, which = data.weights_of(s), data.measured_of(s)
            weight = np.ones(len(poses)) if weights is None else weights
            if which is not None:  # the fixes, not the track between them
                weight = weight * which[:, 0]
            if s > head:  # the shared sample counted once, in the segment before
                path, poses, weight = path[1:], poses[1:], weight[1:]
            paths.append(path)
            measured.append(poses)
            fitted.append(weight)
        chain = np.concatenate(paths)
        if wide.align:  # a solved theta's path, from where it fits the fixes best
            chain = aligned_trajectory(
                chain, np.concatenate(measured), np.concatenate(fitted), wide.arm
            )
        offset = 0  # each segment starts at the sample the one before ends at
        for s in range(head, stop):
            steps = int(data.n_steps[s])
            out.append(chain[offset : offset + steps + 1])
            offset += steps
    return out


def _segment(data: SegmentData, s: int, spec: SegmentGraphSpec, nominal: np.ndarray) -> _Segment:
    """Segment ``s``'s measurements, its states on the odometry (``nominal``) and its
    chunking."""
    poses, inputs = data.segment(s)
    weights = data.weights_of(s)
    measured, fractions = data.measured_of(s), data.fractions_of(s)
    bounds = chunk_bounds(len(inputs), spec.chunk_steps)
    return _Segment(s, poses, inputs, weights, measured, fractions, nominal, bounds, data.run_of(s))


def _add_segment(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    data: SegmentData,
    segment: _Segment,
    spec: SegmentGraphSpec,
    wide: _GraphWide,
    slots: list[ChunkFactorSlot],
) -> None:
    """Segment ``segment``'s variables, priors and chunk factors (their slots appended to
    ``slots``)."""
    s, bounds = segment.index, segment.bounds
    heading = with_heading(data, s)
    insert_segment(values, s, bounds, segment.nominal, spec, heading, segment.tied_before)
    if spec.slip_sigma is not None:
        add_slip_priors(graph, s, bounds, data.dt, spec)
    bias_key = None
    if spec.heading_bias_sigma is not None and heading:
        bias_key = keys.segment_heading_bias(s)
        graph.add(_vector_prior(bias_key, 1, spec.heading_bias_sigma))
    start_measured = segment.start_measured
    if spec.start_prior_sigmas is not None and start_measured.any() and not segment.tied_before:
        weights = segment.weights
        start_weight = 1.0 if weights is None else float(weights[0])
        _add_start_prior(
            graph,
            s,
            segment.poses[0],
            spec,
            wide.lever_arm_key,
            bias_key,
            start_weight,
            (bool(start_measured[0]), bool(start_measured[1])),
        )
    rates = None
    if wide.time_offset_key is not None:
        rates = rotation_rate_changes(segment.inputs[:, :2], data.dt)
    errors = None
    if spec.fix_error_sigma is not None:
        errors = fix_error_keys(data, s, bounds, segment.tied_before, spec.chunk_steps)
        add_fix_error_priors(graph, errors, bounds, data.dt, segment.tied_before, spec)
    _add_chunks(graph, values, segment, spec, wide, (bias_key, errors), rates, slots)


def _add_chunks(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    segment: _Segment,
    spec: SegmentGraphSpec,
    wide: _GraphWide,
    segment_keys: tuple[int | None, list[int] | None],
    rates: np.ndarray | None,
    slots: list[ChunkFactorSlot],
) -> None:
    """The chunk factors of ``segment`` (with their correction variables), evaluated together
    (vectorized); ``segment_keys``: its heading bias's key and its fixes' error's keys at the
    chunk boundaries (each or ``None``); ``rates``: the wheels' rotation rate changes (with a
    time offset). A
    segment tied to the next ends its last chunk at that one's start."""
    s, bounds, poses, inputs = segment.index, segment.bounds, segment.poses, segment.inputs
    bias_key, errors = segment_keys  # the heading bias, the fixes' error at the boundaries
    weights, measured, fractions = segment.weights, segment.measured, segment.fractions
    theta = wide.fixed_theta if wide.theta_key is None else wide.theta_key
    next_start = keys.segment_pose(s + 1) if segment.tied_after else None
    n_chunks = len(bounds) - 1
    batch = ChunkBatch()  # the segment's chunk factors evaluated together, vectorized
    for j in range(n_chunks):
        a, b = int(bounds[j]), int(bounds[j + 1])
        last = j == n_chunks - 1
        correction_key = None
        if spec.corrections is not None:
            correction_key = _add_corrections(graph, values, s, j, bounds, inputs, spec)
        held_start = j == 0 and spec.start_prior_sigmas is None
        chunk = OdometryChunk(
            inputs[a:b],
            poses[a : b + 1],
            float(segment.nominal[a, 2]),
            None if rates is None else rates[a:b],
            None if fractions is None else fractions[a + 1 : b + 1],
            None if measured is None else measured[a : b + 1],
        )
        factor = ChunkOdometryFactor(
            chunk,
            poses[0] if held_start else keys.segment_pose(s, j),
            theta,
            corrections=correction_key,
            end=next_start if last else keys.segment_pose(s, j + 1),
            noise=ChunkNoise(
                wide.tracking,
                wide.continuity,
                None if weights is None else weights[a + 1 : b + 1],
            ),
            defects=DefectKeys(
                slip=None if spec.slip_sigma is None else keys.segment_slip(s, j),
                time_offset=wide.time_offset_key,
                lever_arm=wide.lever_arm_key,
                heading_bias=bias_key,
                fix_offset=None if spec.fix_error_sigma is None else (errors[j], errors[j + 1]),
                time_offset_slot=(segment.run, spec.time_offset_runs),
                rear_slip_gain=wide.rear_slip_gain_key,
            ),
            batch=batch,
        )
        slots.append(ChunkFactorSlot(int(graph.size()), s, a, b, factor.rows, factor))
        graph.add(factor.factor())


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
    heading bias when those are variables; the position sigma widened by a fix weight (and
    by the fixes' shared error when it is modelled). Only
    the measured ``components`` [position, heading] enter (a start without a measured
    heading stays free in heading: the fixes after it determine it)."""
    prior = np.asarray(spec.start_prior_sigmas, float).copy()
    prior[:2] /= np.sqrt(weight)
    if spec.fix_error_sigma is not None:  # the start's fix shares its chunk's error too
        prior[:2] = np.hypot(prior[:2], spec.fix_error_sigma)
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
