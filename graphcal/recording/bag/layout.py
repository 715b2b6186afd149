"""Vectorized decoding of the high-rate messages of a bag from raw bytes: Imu and JointState
(:func:`decode_fixed`), and the numbers of any message type at field paths, found through
the bag's own message definition (:func:`decode_fields`).

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


# --- any message type, through its definition -------------------------------------------------

#: Size [bytes] and little-endian numpy dtype of each primitive of a message definition
#: (``string`` is a length-prefixed run of bytes; ``wstring`` is not walked).
PRIMITIVES = {
    "bool": (1, "<u1"),
    "byte": (1, "<u1"),
    "char": (1, "<u1"),
    "int8": (1, "<i1"),
    "uint8": (1, "<u1"),
    "int16": (2, "<i2"),
    "uint16": (2, "<u2"),
    "int32": (4, "<i4"),
    "uint32": (4, "<u4"),
    "int64": (8, "<i8"),
    "uint64": (8, "<u8"),
    "float32": (4, "<f4"),
    "float64": (8, "<f8"),
}
#: rosbags' node types of a message definition (``rosbags.interfaces.Nodetype``).
BASE, NAME, ARRAY, SEQUENCE = 1, 2, 3, 4
#: A field path's steps: field names and array indices (``("wheels", 2, "speed")``).
Steps = tuple[str | int, ...]


class _DefinitionWalker(_Walker):
    """Walks one raw message along its definition (rosbags' ``fielddefs``), noting the
    offset and dtype of the wanted primitives and where every length prefix is (the only
    bytes that decide where the later fields are)."""

    def __init__(self, raw: bytes, ros1: bool, fielddefs: dict, wanted: set[Steps]) -> None:
        super().__init__(raw, ros1)
        self.fielddefs, self.wanted = fielddefs, wanted
        self.found: dict[Steps, tuple[int, str]] = {}
        self.lengths: list[int] = []

    def length(self) -> int:
        offset = self.take(4)
        self.lengths.append(offset)
        return struct.unpack_from("<I", self.raw, offset)[0]

    def message(self, msgtype: str, path: Steps) -> None:
        for name, (nodetype, desc) in self.fielddefs[msgtype][1]:
            self.node(nodetype, desc, (*path, name))

    def node(self, nodetype: int, desc, path: Steps) -> None:
        if nodetype == NAME:
            self.message(desc, path)
        elif nodetype == BASE:
            self.primitive(desc[0], path)
        else:
            (subtype, subdesc), bound = desc
            count = bound if nodetype == ARRAY else self.length()
            if subtype == BASE and subdesc[0] in PRIMITIVES:  # numbers: skipped at once
                size, dtype = PRIMITIVES[subdesc[0]]
                first = self.take(size) if count else 0
                self.pos += size * max(count - 1, 0)
                if self.base + self.pos > len(self.raw):
                    raise ValueError("message shorter than its definition")
                for index in range(count):
                    if (*path, index) in self.wanted:
                        self.found[(*path, index)] = (first + size * index, dtype)
                return
            for index in range(count):
                self.node(subtype, subdesc, (*path, index))

    def primitive(self, typename: str, path: Steps) -> None:
        if typename == "string":
            length = self.length()  # (before += reads pos: the prefix moves it)
            self.pos += length
            if self.base + self.pos > len(self.raw):
                raise ValueError("string beyond the message's end")
            return
        if typename not in PRIMITIVES:
            raise ValueError(f"{typename} is not walked")
        size, dtype = PRIMITIVES[typename]
        offset = self.take(size)
        if path in self.wanted:
            self.found[path] = (offset, dtype)


def decode_fields(
    raws: list[bytes],
    msgtype: str,
    fielddefs: dict,
    paths: list[Steps],
    ros1: bool,
    stamped: bool,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Stamps ``(M, 2)`` [s, ns] and the numbers at ``paths`` ``(M, len(paths))`` of raw
    messages of any type, found through its definition ``fielddefs`` (rosbags' typestore).

    The offsets come from walking the first message; the others share them when they have
    its length and the same length prefixes (of strings and sequences) at the same places,
    which is checked. ``stamped``: the message has a ``std_msgs/Header`` ``header`` (else the
    stamps are zero). ``None`` if the messages do not share one layout (or a path is not in
    the first message, such as an index beyond a sequence's end): then the caller
    deserializes them one by one.
    """
    if not raws or (not ros1 and raws[0][:2] != b"\x00\x01"):  # only little-endian CDR
        return None
    stamp_paths: list[Steps] = [("header", "stamp", "sec"), ("header", "stamp", "nanosec")]
    wanted = [*paths, *(stamp_paths if stamped else [])]
    walker = _DefinitionWalker(raws[0], ros1, fielddefs, set(wanted))
    try:
        walker.message(msgtype, ())
    except (ValueError, KeyError, struct.error):
        return None
    if walker.base + walker.pos != len(raws[0]) or any(p not in walker.found for p in wanted):
        return None
    length = len(raws[0])
    if any(len(raw) != length for raw in raws):
        return None
    data = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), length)
    if walker.lengths:
        prefix = np.concatenate([np.arange(o, o + 4) for o in walker.lengths])
        if not (data[:, prefix] == data[0, prefix]).all():
            return None

    def column(path: Steps) -> np.ndarray:
        offset, dtype = walker.found[path]
        size = np.dtype(dtype).itemsize
        return data[:, offset : offset + size].copy().view(dtype)[:, 0]

    values = np.column_stack([column(p).astype(float) for p in paths])
    if stamped:
        stamp = np.column_stack([column(p).astype(np.int64) for p in stamp_paths])
    else:
        stamp = np.zeros((len(raws), 2), dtype=np.int64)
    return stamp, values
