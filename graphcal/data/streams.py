"""Sensor streams of a recording, each at its own rate, and their resampling onto a uniform grid.

A recording holds a pose stream (GNSS or a fused pose), a rear-wheel stream and optionally
an IMU stream, all with time in seconds on one time base but sampled at their own instants.
Every reader (:mod:`graphcal.data.manifest` for CSV streams, :mod:`graphcal.data.bags` for
ROS bags) converts its units into the SI quantities of these classes, so that
:func:`resample` does one job: put them on the drive log's grid ``t_k = t_0 + k / rate``.

* Wheel rotation per interval is **integrated**, never sampled: a cumulative angle is
  interpolated at the grid times and differenced; a rotation rate is first integrated with
  the trapezoid rule.
* **Each fix once, at its own time**: a pose sample is written in the first grid row at or
  after it, with its own time (``t_fix``) when it falls between rows; rows without one leave
  the position (and a heading not logged there) empty. Nothing is interpolated into a
  measurement and no heading is derived as one: a stream without a heading gives positions
  only (:mod:`graphcal.data.drive_log`, sparse measurements). Where two fixes fall in one
  grid interval (a pose stream faster than the grid) the later one is kept, with a note.
* The columns of :attr:`Resampled.columns` are the *track* at every row (positions
  interpolated, the heading on the circle or the GNSS course minus the sideslip): the
  import's cross-checks of the streams read it; :meth:`Resampled.frame` is the drive log.
* The sideslip, an input of the model, is interpolated onto the grid.
* Lateral acceleration and yaw rate are the IMU's means over each interval; without an IMU,
  lateral acceleration is speed × yaw rate (speed from the wheels, yaw rate from the logged
  heading, else from the wheels with the nominal c_e and t_r).
* A gap in any stream longer than :func:`gap_threshold` masks the grid samples around it.
* Wheels turning backwards are motion for a vehicle that reverses (a robot's spins and
  reversing: ``VehicleProfile.reverses``), else masked as reversing and set to 0.
* Without a given rate the grid runs at 40 Hz, or just faster than a faster pose stream
  (:func:`grid_rate`), so that no fix is left out.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from graphcal.data.consistency import runs
from graphcal.data.track import COURSE_MIN_REVS, course
from graphcal.errors import GraphcalError
from graphcal.model import wheel_lateral_acceleration

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
#: Most negative wheel rotation [rev] per grid interval accepted before a sample counts as
#: reversing (masked, its rotation set to 0) on a vehicle that does not reverse (a car).
REVERSING_TOLERANCE = 0.005
#: What a recording whose wheels turn backwards is told to set when it is a robot's.
REVERSES_HINT = (
    "a car's model covers forward driving only; if the vehicle is a robot that spins on the "
    "spot or reverses, set reverses = true in its vehicle profile (--vehicle)"
)


class StreamError(GraphcalError, ValueError):
    """A sensor stream that cannot be used; the message is one line: what, where, how to fix."""


def time_text(t: float) -> str:
    """A time [s] with every digit it has (the shortest text that reads back as the same
    float), so that two different stamps never print alike: ``1763856111.5369999``."""
    return repr(float(t))


@dataclass(frozen=True)
class Field:
    """One quantity of a stream as the user gave it, for messages in the user's terms.

    Attributes:
        name: the CSV column (``"wz"``) or the message field (``"angular_velocity.z"``).
        key: the manifest key that named it (``"[imu] yaw_rate"``), or ``None`` (a bag read
            without a manifest section naming it).
        unit: how its unit was declared, the key to change (``'yaw_rate_unit = "rad/s"'``), or
            the unit the message type fixes (``"rad/s (REP 103)"``); ``None`` if none applies.
        declared: ``((unit key, value), ...)`` as the manifest gave them (or defaulted).
    """

    name: str
    key: str | None = None
    unit: str | None = None
    declared: tuple[tuple[str, str], ...] = ()

    def declares(self, key: str) -> str | None:
        """The value the manifest gave the unit key ``key`` (or its default), or ``None``."""
        return dict(self.declared).get(key)

    @property
    def section(self) -> str:
        """The manifest section of :attr:`key` (``"[imu]"``), or ``""``."""
        return self.key.split("]", 1)[0] + "]" if self.key and self.key.startswith("[") else ""

    def text(self, word: str = "column") -> str:
        """``column 'wz' ([imu] yaw_rate, yaw_rate_unit = "rad/s")``."""
        inside = ", ".join(part for part in (self.key, self.unit) if part)
        return f"{word} '{self.name}'" + (f" ({inside})" if inside else "")


@dataclass(frozen=True)
class Provenance:
    """Where a stream's samples are in the user's files: the file (or bag topic), the column
    or field of each quantity, and each kept sample's file line (1-based, the header is line
    1) or message number (1-based, in the topic's order in the bag).

    Attributes:
        file: the CSV's path, or ``bag:topic``.
        fields: by quantity, named as the manifest's keys (``"latitude"``, ``"x"``,
            ``"heading"``, ``"sideslip"``, ``"rear_left"``, ``"rear_right"``,
            ``"lateral_acceleration"``, ``"yaw_rate"``, ``"time"``).
        lines: ``(M,)`` the line or message number of each sample of the stream.
        unit: ``"line"`` (a CSV) or ``"message"`` (a bag topic); a CAN log's ``"line"``
            (candump) or ``"frame"``.
        quantity: what a quantity is called when not a CSV's column or a message's field
            (``"signal"`` of a CAN log's DBC message), or ``None``.
    """

    file: str
    fields: dict[str, Field]
    lines: np.ndarray
    unit: str = "line"
    quantity: str | None = None

    @property
    def word(self) -> str:
        """What a quantity is in this kind of file: ``column``, ``field`` or ``signal``."""
        if self.quantity is not None:
            return self.quantity
        return "column" if self.unit == "line" else "field"

    def line(self, k: int) -> str:
        """``line 1118`` (or ``message 1117``) of sample ``k``."""
        return f"{self.unit} {int(self.lines[int(k)])}"

    def columns(self, *quantities: str) -> str:
        """The user's names of ``quantities``: ``column 'wz' ([imu] yaw_rate, ...)``."""
        found = [self.fields[q] for q in quantities if q in self.fields]
        same = len({(f.section, f.unit) for f in found}) == 1 and all(f.key for f in found)
        if len(found) < 2 or not same:
            return ", ".join(f.text(self.word) for f in found)
        # columns 'rl', 'rr' ([wheels] rear_left, rear_right; kind = "speed", ...)
        names = ", ".join(f"'{f.name}'" for f in found)
        keys = ", ".join(f.key.split("] ", 1)[-1] for f in found if f.key)
        unit = f"; {found[0].unit}" if found[0].unit else ""
        section = f"{found[0].section} " if found[0].section else ""  # none: flags (a bag's)
        return f"{self.word}s {names} ({section}{keys}{unit})"

    def at(self, quantities: tuple[str, ...], k: int | None = None) -> str:
        """``imu.csv: column 'wz' ([imu] yaw_rate, ...), line 266`` (no line if ``k`` is
        None)."""
        columns = self.columns(*quantities)
        where = self.file + (f": {columns}" if columns else "")
        return where if k is None else f"{where}, {self.line(k)}"

    def take(self, keep: np.ndarray) -> Provenance:
        """The provenance of the samples ``keep`` (indices or a mask) of the stream."""
        return dataclasses.replace(self, lines=np.asarray(self.lines)[keep])


def provenance_of(stream) -> Provenance:
    """A stream's :class:`Provenance`, or one naming its ``source`` and sample numbers when
    it was built in memory (no file behind it)."""
    if stream.provenance is not None:
        return stream.provenance
    return Provenance(stream.source, {}, np.arange(1, len(stream.t) + 1), "sample")


@dataclass(frozen=True)
class PoseStream:
    """Measured pose of the vehicle (GNSS fixes or a fused pose), in a local metric frame.

    Attributes:
        t: time [s], strictly increasing, ``(M,)``.
        x, y: position [m], east and north of ``origin`` (or any local metric frame).
        heading: heading [rad], ENU convention (0 = east, counter-clockwise), or ``None``
            when not logged (then the course is used).
        sideslip: sideslip angle [rad], or ``None`` (then 0).
        source: where the stream came from, for messages (``"gnss.csv"``, ``"bag:/fix"``).
        origin: ``(latitude, longitude)`` [deg] of the local frame's origin when the fixes
            were geodetic, else ``None``.
        provenance: the file, columns and lines behind the samples, for messages.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray | None
    sideslip: np.ndarray | None
    source: str
    origin: tuple[float, float] | None = None
    provenance: Provenance | None = None


@dataclass(frozen=True)
class WheelStream:
    """Rear-wheel rotation, either cumulative [rev] or as a rate [rev/s].

    Attributes:
        t: time [s], strictly increasing, ``(M,)``.
        left, right: rear-left and rear-right wheel, ``(M,)``: revolutions since an arbitrary
            start when ``cumulative`` (ticks / ticks per revolution, angle / 2π), else
            revolutions per second (speed / circumference, rpm / 60, ...).
        cumulative: which of the two the arrays hold.
        source: where the stream came from, for messages.
        resolution: one count [rev] of a tick counter (1 / ticks per revolution), or ``None``.
        provenance: the file, columns and lines behind the samples, for messages.
    """

    t: np.ndarray
    left: np.ndarray
    right: np.ndarray
    cumulative: bool
    source: str
    resolution: float | None = None
    provenance: Provenance | None = None


@dataclass(frozen=True)
class ImuStream:
    """IMU signals in the vehicle frame (x forward, y left, z up; ROS REP 103).

    Attributes:
        t: time [s], strictly increasing, ``(M,)``.
        lateral_acceleration: [m/s²], positive to the left, or ``None``.
        yaw_rate: [rad/s], positive counter-clockwise, or ``None``.
        source: where the stream came from, for messages.
        provenance: the file, columns and lines behind the samples, for messages.
    """

    t: np.ndarray
    lateral_acceleration: np.ndarray | None
    yaw_rate: np.ndarray | None
    source: str
    provenance: Provenance | None = None


@dataclass(frozen=True)
class Recording:
    """The streams of one drive, read from a manifest or a bag; :func:`resample` grids them."""

    pose: PoseStream
    wheels: WheelStream
    imu: ImuStream | None
    source: str
    notes: tuple[str, ...] = ()

    def streams(self) -> dict[str, PoseStream | WheelStream | ImuStream]:
        """The present streams by role (``pose``, ``wheels``, ``imu``)."""
        found = {"pose": self.pose, "wheels": self.wheels, "imu": self.imu}
        return {name: stream for name, stream in found.items() if stream is not None}


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


@dataclass(frozen=True)
class Resampled:
    """A recording on the uniform grid: drive-log columns, masked samples and what was done."""

    columns: dict[str, np.ndarray]
    masked: np.ndarray
    mask_notes: tuple[str, ...]
    streams: tuple[StreamSummary, ...]
    overlap: tuple[float, float]
    notes: tuple[str, ...] = field(default=())
    heading_derived: bool = False
    ay_from_wheels: bool = False
    measured: np.ndarray | None = None
    fix_lag: np.ndarray | None = None

    def frame(self):
        """The drive log as a DataFrame: the track's position and heading only where measured
        (else empty), each fix's own time in ``t_fix`` where it falls between rows."""
        from graphcal.data.drive_log import measurement_frame

        return measurement_frame(self.columns, self.measured, self.fix_lag)


def check_time(
    t: np.ndarray, source: str, provenance: Provenance | None = None, unit: str = "s"
) -> None:
    """Raise :class:`StreamError` unless ``t`` is finite and strictly increasing.

    The message names the sample's file line (or message number) from ``provenance`` and
    prints both times with every digit (:func:`time_text`), in ``unit`` (the file's).
    """
    t = np.asarray(t, dtype=float)
    if provenance is None:
        provenance = Provenance(source, {}, np.arange(1, len(t) + 1), "sample")
    where = provenance.at(("time",))
    if len(t) < 2:
        raise StreamError(f"{where}: only {len(t)} sample(s); a stream needs many samples")
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise StreamError(
            f"{where}, {provenance.line(k)}: time is {t[k]}; fill or drop that {provenance.unit}"
        )
    step = np.diff(t)
    if (step <= 0).any():
        k = int(np.flatnonzero(step <= 0)[0]) + 1
        before, after = provenance.line(k - 1), provenance.line(k)
        if step[k - 1] == 0:
            what = f"time {time_text(t[k])} {unit} repeats {before}'s"
        else:
            what = (
                f"time {time_text(t[k])} {unit} is {t[k - 1] - t[k]:.6g} {unit} before "
                f"{before}'s {time_text(t[k - 1])} {unit}"
            )
        raise StreamError(
            f"{where}, {after}: {what}; the time must increase: sort the stream by time"
        )


def unique_samples(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    provenance: Provenance,
    notes: list[str],
    *,
    sort: bool = False,
    unit: str = "s",
) -> np.ndarray:
    """Indices of a stream's samples to keep: sorted by time if ``sort`` (a bag's messages
    come in receive order), and of each run of samples with one time stamp only the first.

    The one rule for a time stamp written twice, in a CSV or a bag: when the samples agree in
    every value (``values``: by the quantity's name in ``provenance.fields``) the repeats are
    dropped, said in one note per stream; when they differ, which one is right cannot be
    told, and :class:`StreamError` names both lines (or messages) and their values.
    """
    t = np.asarray(t, dtype=float)
    order = np.argsort(t, kind="stable") if sort else np.arange(len(t))
    ts = t[order]
    repeat = np.flatnonzero(ts[1:] == ts[:-1]) + 1  # positions in `order` repeating the one before
    if not len(repeat):
        return order
    # the first of its run each repeat is compared with
    first = np.maximum.accumulate(
        np.where(np.concatenate([[True], ts[1:] != ts[:-1]]), np.arange(len(ts)), 0)
    )[repeat]

    def same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return (a == b) | (np.isnan(a) & np.isnan(b))

    differ = np.zeros(len(repeat), dtype=bool)
    for column in values.values():
        differ |= ~same(column[order[first]], column[order[repeat]])
    if differ.any():
        j = int(np.flatnonzero(differ)[0])
        i, k = int(order[first[j]]), int(order[repeat[j]])
        others = [
            f"{provenance.fields.get(n, Field(n)).name} {float(c[i])!r} vs {float(c[k])!r}"
            for n, c in values.items()
            if not same(c[i : i + 1], c[k : k + 1])[0]
        ]
        raise StreamError(
            f"{provenance.file}: {provenance.line(i)} and {provenance.line(k)} have the "
            f"same time {time_text(t[i])} {unit} but different values ({'; '.join(others)}); "
            f"which one is right cannot be told: remove the wrong {provenance.unit}"
        )
    keep = np.ones(len(ts), dtype=bool)
    keep[repeat] = False
    lines = provenance.lines[order[repeat]]
    notes.append(
        f"{provenance.file}: dropped {len(repeat)} {provenance.unit}(s) repeating the time "
        f"and values of the one before (first: {provenance.unit} {int(lines.min())})"
    )
    return order[keep]


def grid_rate(pose: PoseStream, default: float = DEFAULT_RATE) -> float:
    """The drive log's rate [Hz] when none is given: ``default``, or for a pose stream faster
    than that (motion capture, a lidar pose at 50–100 Hz) a grid interval just shorter than
    the stream's shortest interval, so that no two fixes share a grid interval and none is
    left out. The rate is rounded up to 4 significant digits (a 50 Hz stream whose stamps
    are 0.02 s apart within float rounding gets 50.01 Hz); intervals shorter than
    :data:`POSE_JITTER_SHARE` of the median are jitter and not followed."""
    step = np.diff(np.asarray(pose.t, dtype=float))
    if len(step) == 0:
        return default
    median = float(np.median(step))
    if not median > 0 or 1.0 / median <= default:
        return default
    shortest = max(float(step.min()), POSE_JITTER_SHARE * median)
    needed = (1.0 + 1e-6) / shortest
    decimals = 3 - int(np.floor(np.log10(needed)))
    rate = float(np.ceil(needed * 10.0**decimals) / 10.0**decimals)
    return min(rate, RATE_RANGE[1])


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


def resample(
    recording: Recording,
    rate: float = 40.0,
    max_gap: float = MAX_GAP_S,
    wheel_circumference: float = 2.0,
    track_width: float = 1.55,
    *,
    reverses: bool = False,
) -> Resampled:
    """Put a recording on the uniform grid of a drive log (see the module docstring).

    Args:
        recording: the streams, SI units, one time base.
        rate: samples per second of the drive log [Hz] (the paper: 40).
        max_gap: shortest gap [s] in a stream that masks the grid around it (a slower stream
            uses :data:`GAP_INTERVALS` of its own interval if longer).
        wheel_circumference: [m] the vehicle's nominal c_e: for the speed in speed × yaw rate
            when no IMU lateral acceleration is logged, and the travel of a derived course.
        track_width: [m] the vehicle's nominal t_r: for the wheels' yaw rate when neither an
            IMU nor a heading is logged.
        reverses: wheels turning backwards are motion (``VehicleProfile.reverses``: a robot
            spinning on the spot or reversing), kept as they are; else (a car) samples where a
            wheel turns backwards are masked as reversing and their rotations set to 0.

    Raises:
        StreamError: streams whose times do not overlap (enough).
    """
    low, high = RATE_RANGE
    if not (np.isfinite(rate) and low <= rate <= high):
        raise StreamError(
            f"{recording.source}: rate {rate:g} Hz is outside {low:g} … {high:g} Hz; the paper's "
            "drive log runs at 40 Hz"
        )
    summaries = [summarize(role, s, max_gap) for role, s in recording.streams().items()]
    start, end = overlap(summaries, recording.source)
    dt = 1.0 / rate
    count = int(np.floor((end - start) * rate + 1e-9)) + 1
    if count < 3:
        raise StreamError(
            f"{recording.source}: the streams overlap for only {end - start:.3f} s, fewer than "
            f"3 samples at {rate:g} Hz"
        )
    since_start = dt * np.arange(count)  # the drive log's time: 0 at the overlap's start
    grid = start + since_start
    notes: list[str] = [f"time of the drive log: seconds since t = {start:.6f} s of the streams"]

    pose = recording.pose
    px = np.interp(grid, pose.t, pose.x)
    py = np.interp(grid, pose.t, pose.y)
    beta = np.interp(grid, pose.t, pose.sideslip) if pose.sideslip is not None else np.zeros(count)
    if pose.sideslip is None:
        notes.append(
            "sideslip not logged: set to 0 — right for a pose at the rear axle; a pose at the "
            "centre of gravity moves off its heading in bends, which biases t_r and d "
            "(docs/import.md)"
        )
    n_rl, n_rr = wheel_rotations(recording.wheels, grid)
    reversing = np.zeros(count, dtype=bool)
    if not reverses:
        reversing = (n_rl < -REVERSING_TOLERANCE) | (n_rr < -REVERSING_TOLERANCE)
        n_rl, n_rr = np.maximum(n_rl, 0.0), np.maximum(n_rr, 0.0)

    if pose.heading is not None:
        psi = np.interp(grid, pose.t, np.unwrap(pose.heading))
    else:
        psi = course(px, py, dt, min_distance=COURSE_MIN_REVS * wheel_circumference) - beta
        notes.append(
            "heading not logged: positions only are measured (each segment's start heading is "
            "estimated from its fixes)"
        )
    kept, rows, lag, dropped = fixes_on_grid(pose.t, grid)
    measured = np.zeros((count, 2), dtype=bool)
    measured[rows, 0] = True
    measured[rows, 1] = pose.heading is not None
    fix_px, fix_py, fix_psi = px.copy(), py.copy(), psi.copy()
    fix_px[rows], fix_py[rows] = pose.x[kept], pose.y[kept]
    if pose.heading is not None:
        fix_psi[rows] = np.unwrap(pose.heading)[kept]
    if dropped > 0:
        notes.append(
            f"{dropped} pose sample(s) share a {dt * 1e3:g} ms grid interval with a later one "
            "and are left out (a pose stream faster than the drive log: raise its rate)"
        )

    imu = recording.imu
    if imu is not None and imu.lateral_acceleration is not None:
        ay = interval_means(imu.t, imu.lateral_acceleration, grid)
    else:
        speed = 0.5 * (n_rl + n_rr) * wheel_circumference / dt
        if imu is not None and imu.yaw_rate is not None:
            yaw_rate = interval_means(imu.t, imu.yaw_rate, grid)
            notes.append("lateral acceleration not logged: speed × the IMU's yaw rate")
        elif pose.heading is not None:
            yaw_rate = rate_over_window(psi, dt)
            notes.append(
                "lateral acceleration not logged: speed × yaw rate from the heading over "
                f"{YAW_RATE_WINDOW_S:g} s"
            )
        else:
            yaw_rate = None
            notes.append(
                "lateral acceleration not logged: speed × yaw rate of the wheels over "
                f"{YAW_RATE_WINDOW_S:g} s (nominal theta; derived again with the solved one)"
            )
        if yaw_rate is None:
            nominal = np.array([wheel_circumference, 0.0, track_width, 0.0])
            ay = wheel_lateral_acceleration(n_rl, n_rr, nominal, dt, YAW_RATE_WINDOW_S)
        else:
            ay = speed * yaw_rate

    masked = np.zeros(count, dtype=bool)
    mask_notes: list[str] = []
    for summary in summaries:
        gaps = [g for g in summary.gaps if g[1] > start and g[0] < end]
        gap_mask = grid_mask(grid, gaps)
        masked |= gap_mask
        for a, b in gaps:
            mask_notes.append(
                f"t = {a - start:.1f}–{b - start:.1f} s: gap of {b - a:.1f} s in the "
                f"{summary.role} stream ({summary.source})"
            )
    for i, (a, b) in enumerate(runs(reversing)):
        masked[a : b + 1] = True
        mask_notes.append(
            f"t = {since_start[a]:.1f}–{since_start[b]:.1f} s: wheels turning backwards "
            "(reversing), rotations set to 0" + ("" if i else f" ({REVERSES_HINT})")
        )
    columns = {
        "t": since_start,
        "px": fix_px,
        "py": fix_py,
        "psi": fix_psi,
        "n_rl": n_rl,
        "n_rr": n_rr,
        "beta": beta,
        "ay": ay,
    }
    return Resampled(
        columns=columns,
        masked=masked,
        mask_notes=tuple(mask_notes),
        streams=tuple(summaries),
        overlap=(start, end),
        notes=(*recording.notes, *notes),
        heading_derived=pose.heading is None,
        ay_from_wheels=(imu is None or imu.lateral_acceleration is None)
        and (imu is None or imu.yaw_rate is None)
        and pose.heading is None,
        measured=measured,
        fix_lag=lag_at_rows(lag, rows, count),
    )


def lag_at_rows(lag: np.ndarray, rows: np.ndarray, count: int) -> np.ndarray | None:
    """Per grid row, the lag [s] of its fix (0 without one), or ``None`` if all are 0."""
    if not (lag > 0).any():
        return None
    out = np.zeros(count)
    out[rows] = lag
    return out
