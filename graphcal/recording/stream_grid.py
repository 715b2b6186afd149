"""Streams on a uniform grid, one step at a time: the grid's rate, each stream's gaps and the
span all streams cover, a signal's integral and means over the grid's intervals, the wheels'
rotations per interval (integrated, never sampled), and the rows a pose stream's fixes go in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.recording.streams import ImuStream, PoseStream, StreamError, WheelStream

#: Rates [Hz] a drive log may be written at.
RATE_RANGE = (1.0, 1000.0)
#: The drive log's rate [Hz] when none is given (the paper's), unless the pose stream is
#: faster (:func:`grid_rate`).
DEFAULT_RATE = 40.0
#: A pose stream's intervals shorter than this share of its median are jitter: the grid
#: of :func:`grid_rate` is at most 1 / this times the stream's median rate.
POSE_JITTER_SHARE = 0.8
#: Smallest gap [s] between two samples of a stream that counts as a gap; a slower stream's
#: threshold is :data:`GAP_INTERVALS` of its own median interval.
MAX_GAP_S = 0.5
GAP_INTERVALS = 2.5
#: The streams must overlap for at least this share of the shortest stream's time span.
MIN_OVERLAP_SHARE = 0.5
#: Window [s] of the heading difference that gives the yaw rate when no IMU is logged.
YAW_RATE_WINDOW_S = 1.0
#: A fix within this [s] of a grid row is at the row (float time stamps of a Unix epoch
#: resolve 0.24 µs; at 40 m/s a microsecond is 40 µm).
FIX_TIME_TOLERANCE = 1e-6


@dataclass(frozen=True)
class StreamSummary:
    """What the import found in one stream: rate, span and gaps."""

    role: str
    source: str
    samples: int
    rate: float
    start: float
    end: float
    gaps: tuple[tuple[float, float], ...]

    def line(self) -> str:
        """One line for the import's printout."""
        gaps = f", {len(self.gaps)} gap(s) {_gap_text(self.gaps)}" if self.gaps else ", no gaps"
        return (
            f"{self.role:<6} {self.source}: {self.samples} samples at {self.rate:.1f} Hz, "
            f"t = {self.start:.3f} … {self.end:.3f} s{gaps}"
        )


def grid_rate(
    pose: PoseStream, default: float = DEFAULT_RATE, wheels: WheelStream | None = None
) -> float:
    """The drive log's rate [Hz] when none is given: ``default``, or the ``wheels``' own rate
    when they are sampled slower (a robot's 20 Hz encoders: interpolated onto 40 Hz, each
    count difference would be split in two halves whose errors are one error), or for a pose
    stream faster than either a grid interval just shorter than the stream's shortest
    interval, so that no two fixes share a grid interval and none is left out. A rate is
    rounded up to 4 significant digits (a 50 Hz stream whose stamps are 0.02 s apart within
    float rounding gets 50.01 Hz); pose intervals shorter than :data:`POSE_JITTER_SHARE` of
    the median are jitter and not followed."""
    if wheels is not None and len(wheels.t) > 1:
        wheel_step = float(np.median(np.diff(np.asarray(wheels.t, dtype=float))))
        if wheel_step > 0 and 1.0 / wheel_step < default:
            default = max(_rounded_up(1.0 / wheel_step), RATE_RANGE[0])
    step = np.diff(np.asarray(pose.t, dtype=float))
    if len(step) == 0:
        return default
    median = float(np.median(step))
    if not median > 0 or 1.0 / median <= default:
        return default
    shortest = max(float(step.min()), POSE_JITTER_SHARE * median)
    return min(_rounded_up((1.0 + 1e-6) / shortest), RATE_RANGE[1])


def _rounded_up(rate: float) -> float:
    """``rate`` [Hz] rounded up to 4 significant digits."""
    decimals = 3 - int(np.floor(np.log10(rate)))
    return float(np.ceil(rate * 10.0**decimals) / 10.0**decimals)


def gap_threshold(t: np.ndarray, max_gap: float = MAX_GAP_S) -> float:
    """Longest step [s] between samples of a stream that is not a gap."""
    return max(max_gap, GAP_INTERVALS * float(np.median(np.diff(t))))


def stream_gaps(t: np.ndarray, max_gap: float = MAX_GAP_S) -> list[tuple[float, float]]:
    """``[(last sample before, first sample after), ...]`` of each gap of a stream [s]."""
    step = np.diff(t)
    at = np.flatnonzero(step > gap_threshold(t, max_gap))
    return [(float(t[k]), float(t[k + 1])) for k in at]


def summarize(role: str, stream: PoseStream | WheelStream | ImuStream, max_gap: float):
    """The :class:`StreamSummary` of one stream."""
    t = stream.t
    return StreamSummary(
        role=role,
        source=stream.source,
        samples=len(t),
        rate=1.0 / float(np.median(np.diff(t))),
        start=float(t[0]),
        end=float(t[-1]),
        gaps=tuple(stream_gaps(t, max_gap)),
    )


def _gap_text(gaps: tuple[tuple[float, float], ...], shown: int = 3) -> str:
    parts = [f"{b - a:.1f} s at t = {a:.1f}" for a, b in gaps[:shown]]
    more = f", … ({len(gaps) - shown} more)" if len(gaps) > shown else ""
    return "(" + ", ".join(parts) + more + ")"


def overlap(summaries: list[StreamSummary], source: str) -> tuple[float, float]:
    """The time span [s] all streams cover; :class:`StreamError` if it is empty or short."""
    start = max(s.start for s in summaries)
    end = min(s.end for s in summaries)
    spans = ", ".join(f"{s.role} {s.start:.3f} … {s.end:.3f} s" for s in summaries)
    if end <= start:
        raise StreamError(
            f"{source}: the streams' clocks do not overlap ({spans}); give every stream's time "
            "on one time base (same unit and epoch; a manifest's time_unit and time_offset)"
        )
    shortest = min(s.end - s.start for s in summaries)
    if end - start < MIN_OVERLAP_SHARE * shortest:
        raise StreamError(
            f"{source}: the streams overlap for only {end - start:.1f} s ({spans}), less than "
            f"{MIN_OVERLAP_SHARE:.0%} of the shortest; check that the clocks share one time "
            "base (a manifest's time_unit and time_offset)"
        )
    return start, end


def interval_means(t: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Mean of a signal over each grid interval ``[grid[k], grid[k+1]]``, ``(len(grid),)``.

    The signal is integrated with the trapezoid rule, the integral interpolated at the grid
    times and differenced; the last sample repeats the last interval's mean.
    """
    integral = cumulative_integral(t, values)
    return _differenced(np.interp(grid, t, integral), grid) / _repeat_last(np.diff(grid))


def cumulative_integral(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """∫ values dt from ``t[0]`` to each sample (trapezoid rule), ``(M,)``."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (values[1:] + values[:-1]) * np.diff(t))])


def _repeat_last(x: np.ndarray) -> np.ndarray:
    return np.append(x, x[-1])


def _differenced(cumulative_at_grid: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Increments over each grid interval, the last repeated so that rows match the grid."""
    return _repeat_last(np.diff(cumulative_at_grid))


def wheel_rotations(wheels: WheelStream, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation [rev] of each rear wheel during each grid interval (integrated, never sampled)."""
    out = []
    for signal in (wheels.left, wheels.right):
        cumulative = signal if wheels.cumulative else cumulative_integral(wheels.t, signal)
        out.append(_differenced(np.interp(grid, wheels.t, cumulative), grid))
    return out[0], out[1]


def rate_over_window(values: np.ndarray, dt: float) -> np.ndarray:
    """Rate of change [per s] of a sampled angle (a heading, the wheels' cumulative yaw): the
    yaw rate, as a central difference over :data:`YAW_RATE_WINDOW_S`."""
    n = len(values)
    half = max(1, round(0.5 * YAW_RATE_WINDOW_S / dt))
    ahead = np.minimum(np.arange(n) + half, n - 1)
    behind = np.maximum(np.arange(n) - half, 0)
    return (values[ahead] - values[behind]) / ((ahead - behind) * dt)


def fixes_on_grid(
    t: np.ndarray, grid: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Where the samples ``t`` of a pose stream go on the grid: each in the first grid row
    at or after it. Returns the samples kept (indices into ``t``), their rows, their lags
    [s] (row time minus sample time, in ``[0, dt)``) and how many samples inside the grid
    were left out (an earlier one of two in one interval)."""
    tolerance = FIX_TIME_TOLERANCE
    inside = np.flatnonzero((t >= grid[0] - tolerance) & (t <= grid[-1] + tolerance))
    rows = np.minimum(np.searchsorted(grid, t[inside] - tolerance, side="left"), len(grid) - 1)
    last = np.concatenate([rows[1:] != rows[:-1], [True]])  # the latest sample of each row
    kept, rows = inside[last], rows[last]
    lag = np.maximum(grid[rows] - t[kept], 0.0)
    lag[lag <= tolerance] = 0.0
    return kept, rows, lag, int(len(inside) - len(kept))


def grid_mask(grid: np.ndarray, gaps: list[tuple[float, float]]) -> np.ndarray:
    """Grid samples whose interval to a neighbour overlaps one of ``gaps``, ``(len(grid),)``."""
    masked = np.zeros(len(grid), dtype=bool)
    if not gaps:
        return masked
    a = np.array([g[0] for g in gaps])
    b = np.array([g[1] for g in gaps])
    first = np.searchsorted(grid, a, side="right") - 1  # last sample at or before the gap
    last = np.searchsorted(grid, b, side="left")  # first sample at or after it
    cover = np.zeros(len(grid) + 1, dtype=np.int64)
    np.add.at(cover, np.clip(first, 0, len(grid)), 1)
    np.add.at(cover, np.clip(last + 1, 0, len(grid)), -1)
    return np.cumsum(cover[:-1]) > 0


def lag_at_rows(lag: np.ndarray, rows: np.ndarray, count: int) -> np.ndarray | None:
    """Per grid row, the lag [s] of its fix (0 without one), or ``None`` if all are 0."""
    if not (lag > 0).any():
        return None
    out = np.zeros(count)
    out[rows] = lag
    return out
