"""Rows of a bag's topics: the few numbers of each message, gathered while the bag is read.

A :class:`TopicRows` keeps each message's stamp and numbers, from deserialized messages
(through an extractor: :data:`EXTRACT`, :func:`imu_row`, :func:`joint_extractor`) or from
raw bytes decoded in chunks (:mod:`graphcal.recording.bag.layout`); :data:`POSE_FIELDS` and
:data:`IMU_FIELDS` name the message fields behind the columns of each row.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from graphcal.recording.bag.topics import NAVSATFIX, ODOMETRY, POSE_COVARIANCE, POSE_STAMPED

_NAN2 = (math.nan, math.nan)


#: Raw messages of a high-rate topic decoded together (:mod:`graphcal.recording.bag.layout`).
RAW_CHUNK = 65536


@dataclass
class TopicRows:
    """Rows of one topic: stamps and the message's numbers.

    Messages come deserialized (:meth:`add`) or raw (:meth:`add_raw`, for a topic with a
    ``decode`` of whole chunks of raw messages; a chunk it cannot decode is deserialized
    message by message with ``deserialize``).
    """

    extract: Callable[[Any], tuple | None]
    decode: Callable[[list[bytes]], tuple[np.ndarray, np.ndarray] | None] | None = None
    deserialize: Callable[[bytes], Any] | None = None
    stamps: list[tuple[int, int, int]] = field(default_factory=list)
    rows: list[tuple] = field(default_factory=list)
    skipped: int = 0
    pending: list[tuple[int, bytes]] = field(default_factory=list)
    decoded: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    #: Messages offered so far, and the number (1-based, in the topic's order in the bag) of
    #: each kept row, for messages that name one.
    offered: int = 0
    row_numbers: list[int] = field(default_factory=list)
    decoded_numbers: list[np.ndarray] = field(default_factory=list)
    #: Whether the messages have a ``header`` (else the bag's receive times are their times).
    stamped: bool = True

    def add(self, timestamp: int, msg: Any, number: int | None = None) -> None:
        """Keep the numbers of one message (``timestamp``: receive time [ns]; ``number``: its
        place in the topic, counted here when not given)."""
        if number is None:
            self.offered += 1
            number = self.offered
        row = self.extract(msg)
        if row is None:
            self.skipped += 1
            return
        if self.stamped:
            stamp = msg.header.stamp
            self.stamps.append((stamp.sec, stamp.nanosec, timestamp))
        else:
            self.stamps.append((0, 0, timestamp))
        self.rows.append(row)
        self.row_numbers.append(number)

    def add_raw(self, timestamp: int, raw: bytes) -> None:
        """Keep one raw message; decoded in chunks of :data:`RAW_CHUNK`."""
        self.pending.append((timestamp, raw))
        if len(self.pending) >= RAW_CHUNK:
            self.flush()

    def flush(self) -> None:
        """Decode the pending raw messages (vectorized, or one by one if they differ)."""
        if not self.pending:
            return
        pending, self.pending = self.pending, []
        assert self.decode is not None and self.deserialize is not None
        first = self.offered + 1
        self.offered += len(pending)
        result = self.decode([raw for _, raw in pending])
        if result is None:
            for number, (timestamp, raw) in enumerate(pending, start=first):
                self.add(timestamp, self.deserialize(raw), number)
            return
        stamp, values = result
        received = np.array([timestamp for timestamp, _ in pending], dtype=np.int64)
        self.decoded.append((np.column_stack([stamp, received]), values))
        self.decoded_numbers.append(np.arange(first, first + len(pending)))

    def __len__(self) -> int:
        return len(self.rows) + sum(len(values) for _, values in self.decoded)

    def values(self) -> np.ndarray:
        """The rows as floats, ``(M, fields)``."""
        parts = [values for _, values in self.decoded]
        if self.rows or not parts:
            parts.insert(0, np.array(self.rows, dtype=float, ndmin=2))
        return np.concatenate(parts) if len(parts) > 1 else parts[0]

    def numbers(self) -> np.ndarray:
        """Each row's message number (1-based, in the topic's order in the bag), in the order
        of :meth:`values`."""
        parts = [np.asarray(self.row_numbers, dtype=np.int64), *self.decoded_numbers]
        return np.concatenate(parts)

    def times(self, source: str, notes: list[str]) -> np.ndarray:
        """Header stamps [s]; the receive times if every stamp is zero."""
        parts = [stamps for stamps, _ in self.decoded]
        if self.stamps or not parts:
            parts.insert(0, np.array(self.stamps, dtype=np.int64, ndmin=2).reshape(-1, 3))
        stamps = np.concatenate(parts) if len(parts) > 1 else parts[0]
        sec, nanosec = stamps[:, 0], stamps[:, 1]
        if len(sec) and not (sec.any() or nanosec.any()):
            sec, nanosec = np.divmod(stamps[:, 2], 1_000_000_000)
            if self.stamped:
                notes.append(f"{source}: header stamps all zero, used the bag's receive times")
            else:
                notes.append(f"{source}: the messages have no header, used the bag's receive times")
        return sec.astype(float) + 1e-9 * nanosec.astype(float)


def navsatfix(msg: Any) -> tuple:
    """``(latitude, longitude, status)`` of a NavSatFix."""
    return msg.latitude, msg.longitude, msg.status.status


def pose_of(get: Callable[[Any], Any]) -> Callable[[Any], tuple]:
    """The extractor of ``(x, y, qx, qy, qz, qw)`` of the pose that ``get`` finds in a message."""

    def extract(msg: Any) -> tuple:
        pose = get(msg)
        p, q = pose.position, pose.orientation
        return p.x, p.y, q.x, q.y, q.z, q.w

    return extract


def odometry(msg: Any) -> tuple:
    """``(x, y, qx, qy, qz, qw, vx, vy)`` of an Odometry: its pose and body-frame twist."""
    p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    return p.x, p.y, q.x, q.y, q.z, q.w, v.x, v.y


#: The extractor of each pose message type's row (:data:`POSE_FIELDS`).
EXTRACT = {
    NAVSATFIX: navsatfix,
    ODOMETRY: odometry,
    POSE_COVARIANCE: pose_of(lambda m: m.pose.pose),
    POSE_STAMPED: pose_of(lambda m: m.pose),
}


def imu_row(msg: Any) -> tuple:
    """The row of an Imu message, in the order of :data:`IMU_FIELDS`."""
    q = msg.orientation
    return (
        msg.linear_acceleration.y,
        msg.angular_velocity.z,
        msg.linear_acceleration_covariance[0],
        msg.angular_velocity_covariance[0],
        msg.orientation_covariance[0],
        q.x,
        q.y,
        q.z,
        q.w,
    )


def joint_extractor(left: str, right: str) -> tuple[Callable[[Any], tuple | None], set[str]]:
    """Per-message ``(position l, r, velocity l, r)`` of two joints, looked up by name.

    The joint indices are found once per distinct name list; messages without both joints
    give ``None`` (skipped). Also returns the set that collects every joint name seen.
    """
    indices: dict[tuple[str, ...], tuple[int, int, int] | None] = {}
    seen: set[str] = set()

    def extract(msg: Any) -> tuple | None:
        key = tuple(msg.name)
        try:
            found = indices[key]
        except KeyError:
            seen.update(key)
            found = (
                (key.index(left), key.index(right), max(key.index(left), key.index(right)))
                if left in key and right in key
                else None
            )
            indices[key] = found
        if found is None:
            return None
        il, ir, last = found
        pos, vel = msg.position, msg.velocity
        p = (pos[il], pos[ir]) if len(pos) > last else _NAN2
        v = (vel[il], vel[ir]) if len(vel) > last else _NAN2
        return (*p, *v)

    return extract, seen


#: The message fields behind the columns of each message type's rows (:data:`EXTRACT`,
#: :func:`imu_row`, :func:`joint_extractor`), as the user would look them up.
POSE_FIELDS = {
    NAVSATFIX: ("latitude", "longitude", "status.status"),
    ODOMETRY: (
        *(f"pose.pose.position.{a}" for a in "xy"),
        *(f"pose.pose.orientation.{a}" for a in "xyzw"),
        *(f"twist.twist.linear.{a}" for a in "xy"),
    ),
    POSE_COVARIANCE: (
        *(f"pose.pose.position.{a}" for a in "xy"),
        *(f"pose.pose.orientation.{a}" for a in "xyzw"),
    ),
    POSE_STAMPED: (
        *(f"pose.position.{a}" for a in "xy"),
        *(f"pose.orientation.{a}" for a in "xyzw"),
    ),
}
IMU_FIELDS = (
    "linear_acceleration.y",
    "angular_velocity.z",
    "linear_acceleration_covariance[0]",
    "angular_velocity_covariance[0]",
    "orientation_covariance[0]",
    *(f"orientation.{a}" for a in "xyzw"),
)
