"""Sensor streams of a recording, each at its own rate: the types every reader fills, and the
checks of their time stamps.

A recording holds a pose stream (GNSS or a fused pose), a rear-wheel stream and optionally
an IMU stream, all with time in seconds on one time base but sampled at their own instants.
Every reader (:mod:`graphcal.recording.manifest` for CSV streams, :mod:`graphcal.recording.bag`
for ROS bags) converts its units into the SI quantities of these classes, so that
:func:`graphcal.recording.resampling.resample` does one job: put them on the drive log's grid.
Each stream's :class:`Provenance` names the user's files, columns and lines behind its
samples, for messages in the user's terms.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.units import time_text


class StreamError(GraphcalError, ValueError):
    """A sensor stream that cannot be used; the message is one line: what, where, how to fix."""


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
            when not logged (then positions only are measured).
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


def check_time(
    t: np.ndarray, source: str, provenance: Provenance | None = None, unit: str = "s"
) -> None:
    """Raise :class:`StreamError` unless ``t`` is finite and strictly increasing.

    The message names the sample's file line (or message number) from ``provenance`` and
    prints both times with every digit (:func:`~graphcal.units.time_text`), in ``unit``
    (the file's).
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
