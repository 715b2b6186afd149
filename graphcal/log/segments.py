"""Segments and batches of a drive log (paper §5.1).

A log is cut by travelled distance (from the wheel rotations) into calibration segments
(default 150 m) and validation segments (default 300 m), optionally overlapping (a stride
shorter than the length). Calibration segments are selected by their yaw rate, because c_d,
t_r and d are observable only through the yaw-rate equation (2b). Batches are sets of N
distinct segments drawn with a seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from graphcal.log.drive_log import DriveLog
from graphcal.model import THETA_NOMINAL, step_increments

YawRateStatistic = Literal["mean", "median", "rms"]


@dataclass(frozen=True)
class Segments:
    """Sample ranges of one drive log.

    Segment ``i`` covers samples ``start[i] .. stop[i]`` inclusive, i.e. ``stop - start`` steps
    of the model; its first sample is the segment's initial state.
    """

    start: np.ndarray
    stop: np.ndarray
    length: float

    def __len__(self) -> int:
        return len(self.start)

    @property
    def n_steps(self) -> np.ndarray:
        """Number of model steps per segment."""
        return self.stop - self.start

    def subset(self, index: np.ndarray) -> Segments:
        """The segments picked by a boolean mask or an index array."""
        return Segments(self.start[index], self.stop[index], self.length)


#: Consecutive segments tied into one trajectory at most (:meth:`SegmentData.tied`): a chain
#: is one part of the partitioned solve, and every call of a Python factor copies its part's
#: variables (``docs/performance.md``), so a chain's cost grows with its square. 16 of the
#: car's 150 m segments are 2.4 km, of a robot's 53 m 850 m: longer chains add next to
#: nothing to what is known of theta.
TIED_CHAIN = 16


@dataclass(frozen=True)
class SegmentData:
    """Measured signals of segments, padded to a common length for vectorized evaluation.

    Attributes:
        poses: measured states, ``(S, K+1, 3)``; padding repeats each segment's last pose.
        inputs: measured inputs, ``(S, K, 4)``; padding is zero (a zero step leaves the pose as is).
        n_steps: true number of steps of each segment, ``(S,)``.
        valid: ``(S, K+1)`` mask of real (not padded) samples.
        dt: the log's sampling interval [s].
        sample_index: ``(S, K+1)`` row of each sample in the log (padding repeats the last),
            or ``None`` when not gathered from a log.
        fix_weights: ``(S, K+1)`` weight in (0, 1] of each measured pose (robust
            down-weighting of outlying fixes), or ``None`` for all 1.
        measured: ``(S, K+1, 2)`` which samples measured the position and the heading
            (``DriveLog.measured``; elsewhere ``poses`` holds the track), or ``None`` for all.
        fix_fraction: ``(S, K+1)`` in ``(0, 1]``: each sample's measurement was taken at this
            fraction of the step before it (``DriveLog.fix_fraction``), or ``None`` for all 1.
        run: ``(S,)`` the run of the log each segment lies in (``DriveLog.run``; a segment
            never spans two), or ``None`` for all in run 0; ``runs`` the log's number of runs.
    """

    poses: np.ndarray
    inputs: np.ndarray
    n_steps: np.ndarray
    valid: np.ndarray
    dt: float = 0.025
    sample_index: np.ndarray | None = None
    fix_weights: np.ndarray | None = None
    measured: np.ndarray | None = None
    fix_fraction: np.ndarray | None = None
    run: np.ndarray | None = None
    runs: int = 1

    def __len__(self) -> int:
        return len(self.n_steps)

    def run_of(self, index: int) -> int:
        """The run segment ``index`` lies in."""
        return 0 if self.run is None else int(self.run[index])

    def position_fixes(self) -> np.ndarray:
        """``(S, K+1)``: real samples whose position was measured at the sample itself or
        within the step before it (padding excluded)."""
        if self.measured is None:
            return self.valid.copy()
        return self.valid & self.measured[..., 0]

    def headings_measured(self) -> np.ndarray:
        """``(S, K+1)``: real samples whose heading was measured (padding excluded)."""
        if self.measured is None:
            return self.valid.copy()
        return self.valid & self.measured[..., 1]

    def start_measured(self) -> np.ndarray:
        """``(S, 2)``: each segment's first sample measured the position / heading at the
        sample itself (a measurement within the step before it lies outside the segment)."""
        found = np.ones((len(self), 2), bool)
        if self.measured is not None:
            found &= self.measured[:, 0]
        if self.fix_fraction is not None:
            found &= (self.fix_fraction[:, 0] == 1.0)[:, None]
        return found

    def has_heading(self) -> bool:
        """Some sample measured the heading."""
        return self.measured is None or bool(self.headings_measured().any())

    @classmethod
    def single(cls, poses: np.ndarray, inputs: np.ndarray) -> SegmentData:
        """One segment from its poses ``(K+1, 3)`` and inputs ``(K, 4)``."""
        poses, inputs = np.asarray(poses, float), np.asarray(inputs, float)
        if poses.ndim != 2 or inputs.ndim != 2 or len(poses) != len(inputs) + 1:
            raise ValueError(
                f"a segment needs poses (K+1, 3) and inputs (K, 4), got {poses.shape} and "
                f"{inputs.shape}"
            )
        return cls(
            poses[None], inputs[None], np.array([len(inputs)]), np.ones((1, len(poses)), bool)
        )

    def segment(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """Segment ``index`` without padding: measured poses ``(k+1, 3)`` and inputs ``(k, 4)``."""
        k = int(self.n_steps[index])
        return self.poses[index, : k + 1], self.inputs[index, :k]

    def take(self, index: np.ndarray) -> SegmentData:
        """The segments at ``index`` (trimmed to their own longest length)."""
        k = int(self.n_steps[index].max())

        def rows(array: np.ndarray | None) -> np.ndarray | None:
            return None if array is None else array[index, : k + 1]

        return SegmentData(
            self.poses[index, : k + 1],
            self.inputs[index, :k],
            self.n_steps[index],
            self.valid[index, : k + 1],
            self.dt,
            rows(self.sample_index),
            rows(self.fix_weights),
            rows(self.measured),
            rows(self.fix_fraction),
            None if self.run is None else self.run[index],
            self.runs,
        )

    def tied(self, longest: int = TIED_CHAIN) -> np.ndarray:
        """``(S,)`` True where a segment starts at the sample where the one before it ends
        (consecutive segments of one continuous stretch: one trajectory), in chains of at
        most ``longest`` segments (the next one starts a chain of its own). All False
        without sample indices."""
        tied = np.zeros(len(self), bool)
        if self.sample_index is None or len(self) < 2:
            return tied
        ends = self.sample_index[np.arange(len(self)), self.n_steps]
        tied[1:] = self.sample_index[1:, 0] == ends[:-1]
        if self.run is not None:
            tied[1:] &= self.run[1:] == self.run[:-1]
        chain = 0
        for s in range(len(self)):  # a loop over segments, not samples
            chain = chain + 1 if tied[s] else 1
            if chain > longest:
                tied[s], chain = False, 1
        return tied

    def measured_of(self, index: int) -> np.ndarray | None:
        """Measured components ``(k+1, 2)`` of segment ``index`` without padding, or ``None``."""
        if self.measured is None:
            return None
        return self.measured[index, : int(self.n_steps[index]) + 1]

    def fractions_of(self, index: int) -> np.ndarray | None:
        """Fix fractions ``(k+1,)`` of segment ``index`` without padding, or ``None``."""
        if self.fix_fraction is None:
            return None
        return self.fix_fraction[index, : int(self.n_steps[index]) + 1]

    def weights_of(self, index: int) -> np.ndarray | None:
        """Fix weights ``(k+1,)`` of segment ``index`` without padding, or ``None``."""
        if self.fix_weights is None:
            return None
        return self.fix_weights[index, : int(self.n_steps[index]) + 1]


def split_segments(
    log: DriveLog,
    length: float = 150.0,
    stride: float | None = None,
    wheel_circumference: float = THETA_NOMINAL[0],
    min_length: float | None = None,
) -> Segments:
    """Cut ``log`` into segments of ``length`` metres of travelled distance.

    Segments follow the recording: each stretch between masked samples (a run of a robot,
    the driving between two gaps of an import) is cut from its own start, and a stretch
    shorter than ``length`` but at least ``min_length`` long is one segment of its own
    length. A log without masked samples is one stretch, cut from its start.

    Args:
        log: the drive log.
        length: segment length [m] (paper: 150 m for calibration, 300 m for validation).
        stride: distance [m] between segment starts; ``None`` means ``length`` (disjoint
            segments), shorter values give overlapping segments.
        wheel_circumference: circumference [m] used to turn wheel rotations into distance.
        min_length: shortest stretch [m] used as a segment of its own (default
            :data:`SHORT_STRETCH_SHARE` of ``length``).
    """
    if length <= 0:
        raise ValueError(f"segment length must be positive, got {length}")
    stride = length if stride is None else stride
    if stride <= 0:
        raise ValueError(f"segment stride must be positive, got {stride}")
    min_length = SHORT_STRETCH_SHARE * length if min_length is None else min_length
    distance = log.travelled_distance(wheel_circumference)
    starts, stops = [], []
    for first, last in _stretches(log.masked, log.run, len(distance)):
        start, stop = _cut(distance, first, last, length, stride)
        if not len(start) and distance[last] - distance[first] >= min_length:
            start, stop = np.array([first]), np.array([last])
        starts.append(start)
        stops.append(stop)
    if not starts:
        return Segments(np.zeros(0, np.int64), np.zeros(0, np.int64), float(length))
    start, stop = np.concatenate(starts), np.concatenate(stops)
    return Segments(start.astype(np.int64), stop.astype(np.int64), float(length))


#: A stretch between masked samples shorter than a segment is a segment of its own when it
#: is at least this share of the segment length (a robot's runs of 7–16 m, its 19.4 m
#: segments and 38.7 m validation segments).
SHORT_STRETCH_SHARE = 0.1


def _stretches(masked: np.ndarray | None, run: np.ndarray | None, n: int) -> list[tuple[int, int]]:
    """``[first, last]`` sample ranges (inclusive, at least one step) of the unmasked samples,
    each within one run: a run's first sample starts a stretch of its own (the step into it
    crosses from one run to the next). One range for a log without masked samples or runs."""
    free = np.ones(n, bool) if masked is None else ~np.asarray(masked, bool)
    starts_new = free.copy()
    starts_new[1:] &= ~free[:-1]
    if run is not None:
        starts_new[1:] |= free[1:] & (np.diff(np.asarray(run)) != 0)
    continues = np.append(free[1:] & ~starts_new[1:], False)  # sample i+1 in i's stretch
    first = np.flatnonzero(starts_new)
    last = np.flatnonzero(free & ~continues)
    return [(int(a), int(b)) for a, b in zip(first, last, strict=True) if b > a]


def _cut(
    distance: np.ndarray, first: int, last: int, length: float, stride: float
) -> tuple[np.ndarray, np.ndarray]:
    """Segments of ``length`` [m] every ``stride`` [m] from sample ``first`` that end at
    sample ``last`` at the latest (``distance``: travelled [m] at each sample).

    The offsets are looked up in the stretch's own distances: the travelled distance is flat
    across a standstill or a gap, so a lookup in the whole log would land where an earlier
    stretch stopped and cut a segment across the gap."""
    stretch = distance[first : last + 1]
    offsets = stretch[0] + np.arange(0.0, stretch[-1] - stretch[0] - length + 1e-9, stride)
    # Both ends come from the nominal offsets, so with stride == length consecutive segments
    # share their boundary sample but no step.
    start = first + np.searchsorted(stretch, offsets, side="left")
    stop = first + np.searchsorted(stretch, offsets + length, side="left")
    start, unique = np.unique(start, return_index=True)  # standstill can repeat a start
    stop = stop[unique]
    keep = (stop <= last) & (stop > start)
    return start[keep], stop[keep]


def smoothed_yaw_rate(
    log: DriveLog, window_s: float = 1.0, theta: np.ndarray | None = None
) -> np.ndarray:
    """Yaw rate [rad/s] from the measured heading, as a central difference over ``window_s``;
    from the wheels with ``theta`` (default the paper's car's nominal) where the log
    measured the heading at fewer than half its samples (its ``psi`` is then the track of
    the fixes, whose noise reads as turns: a robot's 2.5 Hz fixes of 1.5 m).

    Differencing over a window keeps heading noise (1.5° per sample in the paper) from
    dominating the per-sample rate.
    """
    half = max(1, round(0.5 * window_s / log.dt))
    index = np.arange(len(log))
    ahead = np.minimum(index + half, len(log) - 1)
    behind = np.maximum(index - half, 0)
    heading = log.psi
    if log.measured is not None and np.mean(log.measured[:, 1]) < 0.5:
        theta = THETA_NOMINAL if theta is None else np.asarray(theta, float)
        _, omega = step_increments(log.inputs[:-1], theta)
        heading = np.concatenate([[0.0], np.cumsum(omega)])
    return (heading[ahead] - heading[behind]) / (log.t[ahead] - log.t[behind])


def yaw_rate_statistic(
    log: DriveLog,
    segments: Segments,
    statistic: YawRateStatistic = "mean",
    window_s: float = 1.0,
    theta: np.ndarray | None = None,
) -> np.ndarray:
    """Per-segment statistic of the absolute smoothed yaw rate [rad/s], shape ``(S,)``
    (:func:`smoothed_yaw_rate`, the wheels' with ``theta`` in a log without a heading)."""
    rate = np.abs(smoothed_yaw_rate(log, window_s, theta))
    if len(segments) == 0:
        return np.zeros(0)
    if statistic == "mean":
        prefix = np.concatenate([[0.0], np.cumsum(rate)])
        return (prefix[segments.stop + 1] - prefix[segments.start]) / (segments.n_steps + 1)
    if statistic == "rms":
        prefix = np.concatenate([[0.0], np.cumsum(rate**2)])
        return np.sqrt(
            (prefix[segments.stop + 1] - prefix[segments.start]) / (segments.n_steps + 1)
        )
    if statistic == "median":
        index, valid = _sample_index(segments)
        return np.nanmedian(np.where(valid, rate[index], np.nan), axis=1)
    raise ValueError(f"unknown yaw-rate statistic {statistic!r}; use 'mean', 'median' or 'rms'")


def select_segments(
    log: DriveLog,
    segments: Segments,
    min_yaw_rate: float = 0.15,
    statistic: YawRateStatistic = "mean",
    window_s: float = 1.0,
) -> Segments:
    """Keep the segments whose absolute yaw-rate ``statistic`` exceeds ``min_yaw_rate`` [rad/s]."""
    return segments.subset(yaw_rate_statistic(log, segments, statistic, window_s) > min_yaw_rate)


def make_batches(
    n_segments: int, batch_size: int = 9, n_batches: int = 1000, seed: int = 0
) -> np.ndarray:
    """Draw up to ``n_batches`` distinct batches of ``batch_size`` distinct segment indices.

    Returns an ``(B, batch_size)`` integer array, each row sorted, no two rows equal;
    ``B = min(n_batches, C(n_segments, batch_size))`` since a repeated batch adds no
    information. The same arguments always give the same batches.
    """
    if batch_size < 1 or n_batches < 1:
        raise ValueError("batch size and number of batches must be at least 1")
    if n_segments < batch_size:
        raise ValueError(
            f"only {n_segments} segment(s) available for batches of {batch_size}: use a longer "
            "drive, overlapping segments (smaller stride), a lower yaw-rate threshold or a "
            "smaller batch size"
        )
    wanted = min(n_batches, math.comb(n_segments, batch_size))
    rng = np.random.default_rng(seed)
    batches = np.zeros((0, batch_size), dtype=np.int64)
    while len(batches) < wanted:
        keys = rng.random((2 * wanted, n_segments))
        draws = np.sort(np.argpartition(keys, batch_size - 1, axis=1)[:, :batch_size], axis=1)
        pooled = np.concatenate([batches, draws])
        _, first = np.unique(pooled, axis=0, return_index=True)
        batches = pooled[np.sort(first)]
    return batches[:wanted]


def spread(count: int, size: int) -> np.ndarray:
    """Indices of ``min(size, count)`` of ``count`` segments spread evenly over them, first
    and last included (a sample of a long log that sees all of its route)."""
    if size >= count:
        return np.arange(count)
    return np.unique(np.round(np.linspace(0, count - 1, max(size, 1))).astype(np.int64))


def _sample_index(segments: Segments) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices ``(S, K+1)`` of each segment, clipped to its end, and the valid mask."""
    k = int(segments.n_steps.max()) if len(segments) else 0
    offsets = np.arange(k + 1)
    index = segments.start[:, None] + offsets[None, :]
    valid = offsets[None, :] <= segments.n_steps[:, None]
    return np.minimum(index, segments.stop[:, None]), valid


def gather_segments(
    log: DriveLog, segments: Segments, fix_weights: np.ndarray | None = None
) -> SegmentData:
    """Measured poses and inputs of ``segments``, padded to a common number of steps, with
    the log's per-sample ``fix_weights`` ``(N,)`` if given."""
    if len(segments) == 0:
        raise ValueError("no segments to gather")
    index, valid = _sample_index(segments)
    poses = log.poses[index]
    inputs = log.inputs[index[:, :-1]]
    inputs[~valid[:, 1:]] = 0.0
    weights = None if fix_weights is None else np.asarray(fix_weights, float)[index]
    measured = None if log.measured is None else np.asarray(log.measured, bool)[index]
    fraction = log.fix_fraction
    if fraction is not None:
        fraction = fraction[index]
    return SegmentData(
        poses,
        inputs,
        segments.n_steps.copy(),
        valid,
        log.dt,
        index,
        weights,
        measured,
        fraction,
        None if log.run is None else log.run[segments.start],
        log.runs,
    )
