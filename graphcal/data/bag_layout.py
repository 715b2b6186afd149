"""Vectorized decoding of the high-rate messages of a bag (Imu, JointState) from raw bytes.

rosbags deserializes one message at a time (about 8 µs each); a 3-hour drive has two million
Imu and JointState messages. Within one topic these messages usually have one byte layout —
the same frame id, the same joint names — so the numbers sit at the same offsets in every
message. :func:`decode_fixed` finds the offsets by walking the first message (ROS 2 CDR or
ROS 1 serialization), checks that every message has the same length and the same bytes
outside the stamp and the numbers, and gathers the numbers with numpy. When a topic does
not have one layout it returns ``None`` and the caller deserializes message by message.
"""

from __future__ import annotations

import struct

import numpy as np

IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
#: Index of each Imu number among its 37 doubles (orientation xyzw, its covariance, angular
#: velocity, its covariance, linear acceleration, its covariance), in the order the reader's
#: rows use: ay, wz, cov(ay), cov(wz), cov(orientation), qx, qy, qz, qw.
IMU_DOUBLES = (26, 15, 28, 16, 4, 0, 1, 2, 3)


class _Walker:
    """Offsets of a message's fields (ROS 2 CDR little-endian, or ROS 1)."""

    def __init__(self, raw: bytes, ros1: bool) -> None:
        self.raw, self.ros1 = raw, ros1
        self.base = 0 if ros1 else 4  # CDR's encapsulation header
        self.pos = 0

    def align(self, size: int) -> None:
        if not self.ros1:
            self.pos += -self.pos % size

    def take(self, size: int) -> int:
        """Offset (in ``raw``) of the next field of ``size`` bytes."""
        self.align(size)
        offset = self.base + self.pos
        self.pos += size
        if self.base + self.pos > len(self.raw):
            raise ValueError("message shorter than its layout")
        return offset

    def uint32(self) -> int:
        return struct.unpack_from("<I", self.raw, self.take(4))[0]

    def string(self) -> bytes:
        length = self.uint32()
        start = self.base + self.pos
        self.pos += length
        return self.raw[start : start + length]

    def header(self) -> tuple[int, int]:
        """Offsets of the stamp's seconds and nanoseconds; skips the frame id."""
        if self.ros1:
            self.take(4)  # seq
        sec, nanosec = self.take(4), self.take(4)
        self.string()
        return sec, nanosec


def _layout(raw: bytes, msgtype: str, ros1: bool, joints: tuple[str, str] | None):
    """``(stamp offsets, number offsets, variable byte ranges)`` of ``raw``, or None.

    The variable ranges are every float array (all of them may change from message to
    message); the rest — frame id, joint names, array lengths — must be the same in every
    message of one layout."""
    if not ros1 and raw[:2] != b"\x00\x01":  # only little-endian CDR
        return None
    walker = _Walker(raw, ros1)
    sec, nanosec = walker.header()
    variable = [(sec, sec + 4), (nanosec, nanosec + 4)]
    if ros1:
        variable.append((0, 4))  # seq
    if msgtype == IMU:
        first = walker.take(8)
        walker.pos += 36 * 8
        if walker.base + walker.pos > len(raw):
            return None
        numbers = [first + 8 * i for i in IMU_DOUBLES]
        variable.append((first, first + 37 * 8))
    elif msgtype == JOINT_STATE and joints is not None:
        names = [walker.string().rstrip(b"\x00").decode() for _ in range(walker.uint32())]
        if joints[0] not in names or joints[1] not in names:
            return None
        left, right = names.index(joints[0]), names.index(joints[1])
        arrays = []
        for _ in ("position", "velocity", "effort"):
            count = walker.uint32()
            first = walker.take(8) if count else 0
            walker.pos += 8 * max(count - 1, 0)
            arrays.append((first, count))
            variable.append((first, first + 8 * count))
        numbers = []
        for first, count in arrays[:2]:
            for index in (left, right):
                numbers.append(first + 8 * index if count == len(names) else -1)
    else:
        return None
    if walker.base + walker.pos != len(raw):
        return None
    return (sec, nanosec), numbers, variable


def decode_fixed(
    raws: list[bytes], msgtype: str, ros1: bool, joints: tuple[str, str] | None = None
) -> tuple[np.ndarray, np.ndarray] | None:
    """Stamps ``(M, 2)`` [s, ns] and numbers ``(M, fields)`` of same-layout raw messages.

    Fields as the bag reader's rows: Imu ``(ay, wz, cov ay, cov wz, cov orientation, qx, qy,
    qz, qw)``; JointState ``(position left, right, velocity left, right)`` (NaN where the
    message has no such array). ``None`` if the messages do not share one layout.
    """
    if not raws:
        return None
    try:
        layout = _layout(raws[0], msgtype, ros1, joints)
    except (ValueError, UnicodeDecodeError, struct.error):
        return None
    if layout is None:
        return None
    (sec, nanosec), numbers, variable = layout
    length = len(raws[0])
    if any(len(raw) != length for raw in raws):
        return None
    data = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), length)
    # Everything but the stamp and the float arrays (frame id, names, lengths) must match.
    fixed = np.ones(length, dtype=bool)
    for start, end in variable:
        fixed[start:end] = False
    if not (data[:, fixed] == data[0, fixed]).all():
        return None
    stamp = np.column_stack(
        [
            data[:, sec : sec + 4].copy().view("<i4")[:, 0].astype(np.int64),
            data[:, nanosec : nanosec + 4].copy().view("<u4")[:, 0].astype(np.int64),
        ]
    )
    values = np.full((len(raws), len(numbers)), np.nan)
    for column, offset in enumerate(numbers):
        if offset >= 0:
            values[:, column] = data[:, offset : offset + 8].copy().view("<f8")[:, 0]
    return stamp, values
