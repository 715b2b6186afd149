"""Validation error of a calibration (paper §5.2, eq. 16).

Each validation segment is dead-reckoned with the odometry model from its measured first pose
with the measured inputs; the error is the distance between odometry and measured positions.
Eq. (16) sums over the K samples; graphcal reports the mean over the samples (the sum divided
by K), which is what the paper's figures in metres (e.g. the 2.42 m reachable limit) show.

In a log with sparse fixes the error is the mean over the segment's fixes, each compared with
the odometry at its own time (:func:`graphcal.model.partial_steps`). A segment whose first
sample has no measured pose starts at the track there (:mod:`graphcal.log.track`) when a
position and a heading were measured within :data:`TRACK_START_S` of it (a fused pose at
20 Hz on the 40 Hz grid: the track is the pose interpolated over 50 ms); otherwise (no
heading logged, or none near) it starts where its dead-reckoned path fits the fixes best
(rigidly, :func:`graphcal.alignment.aligned_trajectory`). A rigid fit forgives a heading drift
that a start at the measured pose shows: on the real car's minute of highway, nominal theta
drifts 1.2 m on average over 300 m aligned, 4 m from the fused pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.alignment import aligned_trajectory
from graphcal.log.segments import SegmentData
from graphcal.model import StepInputs, integrate_steps, lever_offset, partial_steps

#: A segment starts at the track's pose [s] when a position fix and a heading were measured
#: this close after its first sample (else it is fitted to its fixes rigidly).
TRACK_START_S = 0.1

#: Segments whose odometry :func:`position_errors` integrates at once, in order of their
#: length and each block trimmed to its longest: bounds its arrays (a 200 km log's 672
#: validation segments of 1,500 steps took ~120 MB a theta at once) and the padding it
#: integrates (a 24 km log's 81 segments of 640–1,620 steps: 47 → 20 ms a theta).
BLOCK_SEGMENTS = 16


def odometry_paths(
    data: SegmentData, theta: np.ndarray, aligned: bool = False, arm: np.ndarray | None = None
) -> np.ndarray:
    """The dead-reckoned states ``(S, K+1, 3)`` the validation compares: from each
    segment's measured start pose, or the track's where a position and a heading were
    measured just after its first sample, else moved rigidly to fit its fixes; with
    ``aligned``, every segment moved rigidly to fit its fixes (the shape of its path is
    judged, not its start: a single heading's noise of 1.5° is 2 m over 150 m). With
    ``arm`` ``[ahead, left]`` [m] the positions are those of the GNSS antenna on that lever
    arm from the centre of gravity (the path is fitted as the antenna's)."""
    return _Paths.of(data, aligned).states(theta, arm)


@dataclass(frozen=True)
class _Paths:
    """:func:`odometry_paths` of a block of segments, what no theta changes taken out once:
    the inputs taken apart, the segments moved onto their fixes (``refit``) and the fixes'
    weights ``(S, K+1)`` they are fitted with."""

    data: SegmentData
    steps: StepInputs
    refit: np.ndarray
    fixes: np.ndarray | None

    @classmethod
    def of(cls, data: SegmentData, aligned: bool) -> _Paths:
        """The paths of ``data``'s segments (every one fitted to its fixes if ``aligned``)."""
        steps = StepInputs.of(data.inputs)
        if not aligned and data.measured is None and data.fix_fraction is None:
            return cls(data, steps, np.zeros(0, int), None)
        started = data.start_measured().all(axis=1) | _measured_near_start(data)
        refit = np.flatnonzero(~started | aligned)
        return cls(data, steps, refit, data.position_fixes().astype(float))

    def states(self, theta: np.ndarray, arm: np.ndarray | None = None) -> np.ndarray:
        """The states ``(S, K+1, 3)`` with ``theta`` (the antenna's positions with ``arm``)."""
        data = self.data
        states = np.stack(integrate_steps(data.poses[:, 0], self.steps, theta), axis=-1)
        if arm is not None:
            states[..., :2] += lever_offset(states[..., 2], arm)
        for s in self.refit:
            k = int(data.n_steps[s])
            states[s, : k + 1] = aligned_trajectory(
                states[s, : k + 1], data.poses[s, : k + 1], self.fixes[s, : k + 1]
            )
        return states


def _measured_near_start(data: SegmentData) -> np.ndarray:
    """``(S,)``: a position and a heading were measured within :data:`TRACK_START_S` after
    the segment's first sample."""
    if data.measured is None:
        return np.ones(len(data), bool)
    near = max(1, int(np.ceil(TRACK_START_S / data.dt - 1e-9))) + 1
    head = data.measured[:, :near] & data.valid[:, :near, None]
    return head.any(axis=1).all(axis=1)


def position_errors(
    data: SegmentData, theta: np.ndarray, aligned: bool = False, arm: np.ndarray | None = None
) -> np.ndarray:
    """Mean position error [m] per segment of odometry with ``theta`` (eq. 16 / K), ``(S,)``;
    for thetas ``(T, 4)``, ``(T, S)`` (each block of segments prepared once for all of them:
    its inputs taken apart, its fixes found). ``aligned``: every path fitted to its fixes
    rigidly; ``arm``: the fixes are an antenna's on that lever arm (:func:`odometry_paths`).
    Computed :data:`BLOCK_SEGMENTS` segments of like length at a time (a segment's error is
    its own to 10⁻¹⁵: the padding of its block is the only other segments' part in it)."""
    thetas = np.asarray(theta, float)
    errors = np.empty((len(thetas.reshape(-1, 4)), len(data)))
    if len(data) <= BLOCK_SEGMENTS:
        blocks = [np.arange(len(data))]
    else:
        order = np.argsort(data.n_steps, kind="stable")
        blocks = np.array_split(order, -(-len(data) // BLOCK_SEGMENTS))
    for index in blocks:
        block = data if len(blocks) == 1 else data.take(index)
        paths = _Paths.of(block, aligned)
        sparse = block.measured is not None or block.fix_fraction is not None
        fixes = _SparseFixes.of(block) if sparse else _DenseFixes.of(block)
        for row, one in zip(errors, thetas.reshape(-1, 4), strict=True):
            if isinstance(fixes, _DenseFixes) and arm is None and not aligned:
                # no (S, K+1, 3) states: the positions alone
                row[index] = fixes.errors(*integrate_steps(block.poses[:, 0], paths.steps, one)[:2])
            else:
                row[index] = fixes.errors_of(paths.states(one, arm), one, arm)
    return errors if thetas.ndim == 2 else errors[0]


@dataclass(frozen=True)
class _DenseFixes:
    """A block of segments with a measured pose at every sample: its measured positions and
    the samples compared (all valid ones but the start, the measured pose itself) over its
    steps."""

    x: np.ndarray
    y: np.ndarray
    compared: np.ndarray
    n_steps: np.ndarray

    @classmethod
    def of(cls, data: SegmentData) -> _DenseFixes:
        """``data``'s (a log measured at every sample)."""
        compared = data.valid.copy()
        compared[:, 0] = False
        x, y = (np.ascontiguousarray(data.poses[..., i]) for i in (0, 1))
        return cls(x, y, compared, data.n_steps)

    def errors(self, px: np.ndarray, py: np.ndarray) -> np.ndarray:
        """The mean position error [m] of each segment of the odometry ``px, py``
        ``(S, K+1)``."""
        distance = np.hypot(px - self.x, py - self.y)
        return (distance * self.compared).sum(axis=1) / self.n_steps

    def errors_of(
        self, states: np.ndarray, theta: np.ndarray, arm: np.ndarray | None
    ) -> np.ndarray:
        """:meth:`errors` of :func:`odometry_paths` ``states`` (``theta``, ``arm``: theirs)."""
        return self.errors(states[..., 0], states[..., 1])


@dataclass(frozen=True)
class _SparseFixes:
    """A block of segments with sparse fixes: each fix after a segment's start (its segment,
    sample, measured position and, with fix times, its step's inputs and the fraction of it)
    and each segment's count of them. The mean over a segment's fixes, each compared with the
    odometry at its own time (a fix between samples predicted part-way through its step, the
    antenna moved with the body). Only the fixes' steps are predicted (a 10 Hz receiver's
    fixes on a 100 Hz log are one step in ten)."""

    segment: np.ndarray
    k: np.ndarray
    measured: np.ndarray
    counts: np.ndarray
    inputs: np.ndarray | None
    fraction: np.ndarray | None

    @classmethod
    def of(cls, data: SegmentData) -> _SparseFixes:
        """``data``'s fixes."""
        used = data.position_fixes()
        used[:, 0] = False
        segment, k = np.nonzero(used)
        counts = np.maximum(np.bincount(segment, minlength=len(data)), 1)
        inputs = fraction = None
        if data.fix_fraction is not None:
            # the fix at sample k, part-way through step k − 1 from the centre of gravity there
            inputs = data.inputs[segment, k - 1][:, None]
            fraction = data.fix_fraction[segment, k][:, None]
        return cls(segment, k, data.poses[segment, k, :2], counts, inputs, fraction)

    def errors_of(
        self, states: np.ndarray, theta: np.ndarray, arm: np.ndarray | None
    ) -> np.ndarray:
        """The mean position error [m] of each segment of :func:`odometry_paths` ``states``
        (with ``theta``; the antenna's on ``arm``)."""
        segment, k = self.segment, self.k
        predicted = states[segment, k]
        if self.fraction is not None:
            pair = states[segment[:, None], k[:, None] + np.array([-1, 0])]  # (N, 2, 3)
            if arm is not None:
                pair[..., :2] -= lever_offset(pair[..., 2], arm)
            predicted = partial_steps(pair, self.inputs, theta, self.fraction)[0][:, 0]
            if arm is not None:
                predicted[:, :2] += lever_offset(predicted[:, 2], arm)
        distance = np.hypot(*(predicted[:, :2] - self.measured).T)
        return np.bincount(segment, weights=distance, minlength=len(self.counts)) / self.counts


def position_error_spread(
    data: SegmentData, theta: np.ndarray, covariance: np.ndarray | None
) -> float:
    """σ [m] of the segments' mean position error (:func:`position_errors`) that theta's
    own uncertainty makes, ``covariance`` ``(4, 4)`` [SI] (0 without one): to first order,
    with each parameter's slope taken as the secant over ±1σ (the error is about ``|x|``
    near its minimum, where a tangent would say nothing)."""
    if covariance is None or not np.all(np.isfinite(covariance)):
        return 0.0
    sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    varied = np.flatnonzero(sigma > 0.0)
    if len(varied) == 0:
        return 0.0
    steps = np.zeros((2 * len(varied), len(theta)))
    steps[np.arange(len(varied)), varied] = sigma[varied]
    steps[len(varied) + np.arange(len(varied)), varied] = -sigma[varied]
    errors = position_errors(data, theta + steps).mean(axis=1)
    slope = (errors[: len(varied)] - errors[len(varied) :]) / (2.0 * sigma[varied])
    variance = slope @ covariance[np.ix_(varied, varied)] @ slope
    return float(np.sqrt(max(variance, 0.0)))
