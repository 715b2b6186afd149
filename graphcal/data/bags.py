"""ROS 1 bags, ROS 2 bags (sqlite3 or mcap storage) and bare MCAP files, read with ``rosbags``.

``rosbags`` is pure Python (no ROS installation); it is the optional extra ``graphcal[ros]``
and is imported only inside the functions. :func:`read_bag` turns the bag's topics into the
streams of :mod:`graphcal.data.streams`:

* pose: ``sensor_msgs/NavSatFix`` (latitude/longitude → east/north [m] from the first fix,
  no heading), ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``geometry_msgs/PoseWithCovarianceStamped`` (x, y [m]; heading = yaw of the orientation);
* wheels: ``sensor_msgs/JointState`` of the two rear wheel joints, ``position`` [rad,
  cumulative] → revolutions, or ``velocity`` [rad/s] → revolutions per second;
* IMU (optional): ``sensor_msgs/Imu``, ``linear_acceleration.y`` [m/s²] and
  ``angular_velocity.z`` [rad/s] in the vehicle frame (x forward, y left; REP 103).

Time is each message's ``header.stamp``; when every stamp of a topic is zero, the time the bag
recorded the message. Every topic is read in one pass over the bag; each message is
deserialized once and only its few numbers are kept, converted to arrays at the end.
"""

from __future__ import annotations

import dataclasses
import math
import sqlite3
import struct
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from graphcal.data.bag_layout import decode_fixed
from graphcal.data.geodesy import GeodesyError, geodetic_to_local
from graphcal.data.streams import (
    Field,
    ImuStream,
    PoseStream,
    Provenance,
    Recording,
    StreamError,
    WheelStream,
    unique_samples,
)
from graphcal.data.streams import check_time as _check_time
from graphcal.errors import first_line

NAVSATFIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
#: Message types usable as the pose stream.
POSE_TYPES = (NAVSATFIX, ODOMETRY, POSE_STAMPED, POSE_COVARIANCE)
#: Files of a ROS 2 bag's storage (also readable on their own).
STORAGE_SUFFIXES = (".db3", ".mcap")
#: JointState messages looked at to find the rear wheel joints when they are not named.
JOINT_SCAN_MESSAGES = 200
WheelKind = Literal["angle", "angular_speed"]
#: Decode Imu and JointState messages of one layout with numpy (False: one by one, rosbags).
FAST_DECODING = True

_MISSING_ROSBAGS = 'reading ROS bags needs the rosbags package: pip install -e ".[ros]"'
_NAN2 = (math.nan, math.nan)
#: How to repair a bag whose recording was cut off, by file suffix.
_REPAIR = {
    ".bag": " (a ROS 1 bag cut off while recording needs `rosbag reindex`)",
    ".mcap": " (only ROS 2 MCAP files are read; one cut off while recording needs `mcap recover`)",
}


def _require_rosbags() -> None:
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise StreamError(_MISSING_ROSBAGS) from None


def _reader_errors() -> tuple[type[BaseException], ...]:
    """Exceptions of a corrupt or unsupported bag (rosbags' own and what its parsers raise)."""
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    return (
        AnyReaderError,
        Reader1Error,
        Reader2Error,
        SerdeError,
        TypesysError,
        OSError,
        EOFError,
        KeyError,
        IndexError,
        ValueError,
        AssertionError,
        struct.error,
        sqlite3.Error,
        UnicodeDecodeError,
    )


def is_bag(path: str | Path) -> bool:
    """Whether ``path`` looks like a bag: a ``.bag`` (ROS 1), ``.mcap`` or ``.db3`` file, or a
    directory holding ``metadata.yaml`` (ROS 2) or ``*.db3`` / ``*.mcap`` storage files."""
    path = Path(path)
    if path.is_file():
        return path.suffix in (".bag", *STORAGE_SUFFIXES)
    if path.is_dir():
        return (path / "metadata.yaml").is_file() or bool(_storage_files(path))
    return False


def _storage_files(directory: Path) -> list[Path]:
    return sorted(p for p in directory.iterdir() if p.suffix in STORAGE_SUFFIXES)


def _reader_paths(path: Path) -> list[Path]:
    """What ``AnyReader`` opens for ``path``; :class:`StreamError` if it is no bag."""
    what = "a ROS bag (a .bag or .mcap file, or a ROS 2 bag directory)"
    if not path.exists():
        raise StreamError(f"{path}: no such file or directory; give the path of {what}")
    if not is_bag(path):
        raise StreamError(f"{path}: not {what}; give the path of one")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        # rosbags reads a ROS 2 directory only through its metadata.yaml; without it, its
        # storage files are read one by one (each .mcap/.db3 file is readable on its own).
        return _storage_files(path)
    return [path]


class _Bag:
    """An open ``AnyReader`` of one bag, its errors turned into one-line :class:`StreamError`."""

    def __init__(self, path: Path, source: str):
        _require_rosbags()
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore

        self.path = path
        self.source = source
        self.errors = _reader_errors()
        paths = _reader_paths(path)
        self.ros1 = ros1 = all(p.suffix == ".bag" for p in paths)
        store = Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE
        with self.guard():
            self.reader = AnyReader(paths, default_typestore=get_typestore(store))
            self.reader.open()
            self.topics = {
                name: info.msgtype or ", ".join(sorted({c.msgtype for c in info.connections}))
                for name, info in self.reader.topics.items()
            }
            self.counts = {name: info.msgcount for name, info in self.reader.topics.items()}

    @contextmanager
    def guard(self) -> Iterator[None]:
        """Context turning rosbags' exceptions into a one-line :class:`StreamError`."""
        try:
            yield
        except StreamError:
            raise
        except (FileNotFoundError, PermissionError) as error:
            raise StreamError(
                f"{self.source}: cannot read {self.path}: {first_line(str(error))}; check the "
                "path and its permissions"
            ) from None
        except self.errors as error:
            text = first_line(str(error)) or type(error).__name__
            raise StreamError(
                f"{self.source}: cannot read the bag ({type(error).__name__}: {text}); it is "
                f"corrupt, truncated or of an unsupported format{_REPAIR.get(self.path.suffix, '')}"
            ) from None

    def close(self) -> None:
        """Close the reader (errors on close are ignored)."""
        try:
            self.reader.close()
        except self.errors:
            pass

    def topic_list(self) -> str:
        """``/a (type), /b (type)`` of every topic in the bag."""
        if not self.topics:
            return "the bag has no topics"
        return "topics: " + ", ".join(f"{t} ({self.topics[t]})" for t in sorted(self.topics))

    def raw_messages(self, topics: Iterable[str]) -> Iterable[tuple[str, int, bytes, str]]:
        """``(topic, receive time [ns], raw bytes, message type)`` of every message on
        ``topics``, in one pass."""
        wanted = set(topics)
        connections = [c for c in self.reader.connections if c.topic in wanted]
        for connection, timestamp, raw in self.reader.messages(connections=connections):
            yield connection.topic, timestamp, raw, connection.msgtype

    def raw_topic(
        self,
        extract: Callable[[Any], tuple | None],
        msgtype: str,
        joints: tuple[str, str] | None = None,
    ) -> _Topic:
        """A :class:`_Topic` of a high-rate message type, decoded from raw bytes in chunks."""

        def decode(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
            return decode_fixed(raws, msgtype, self.ros1, joints) if FAST_DECODING else None

        def deserialize(raw: bytes) -> Any:
            return self.reader.deserialize(raw, msgtype)

        return _Topic(extract, decode, deserialize)

    def messages(self, topics: Iterable[str]) -> Iterable[tuple[str, int, Any]]:
        """``(topic, receive time [ns], message)`` of every message on ``topics``, in one pass."""
        wanted = set(topics)
        connections = [c for c in self.reader.connections if c.topic in wanted]
        deserialize = self.reader.deserialize
        for connection, timestamp, raw in self.reader.messages(connections=connections):
            yield connection.topic, timestamp, deserialize(raw, connection.msgtype)


def bag_topics(path: str | Path) -> dict[str, str]:
    """Topics of a bag and their message types, e.g. ``{"/fix": "sensor_msgs/msg/NavSatFix"}``.

    Raises:
        StreamError: ``path`` missing, not a bag, or unreadable.
    """
    path = Path(path)
    bag = _Bag(path, str(path))
    try:
        return dict(sorted(bag.topics.items()))
    finally:
        bag.close()


# --- topic and joint selection ----------------------------------------------------------------


def _short(msgtype: str) -> str:
    return msgtype.rsplit("/", 1)[-1]


def _pick_topic(
    bag: _Bag, topic: str | None, types: tuple[str, ...], role: str, flag: str, required: bool
) -> tuple[str | None, str | None]:
    """The topic of ``role`` and a note if it was picked automatically."""
    wanted = " or ".join(_short(t) for t in types)
    if topic is not None:
        if topic not in bag.topics:
            raise StreamError(
                f"{bag.source}: {role} topic {topic} is not in the bag; pass {flag} with one of "
                f"the {bag.topic_list()}"
            )
        if bag.topics[topic] not in types:
            raise StreamError(
                f"{bag.source}: {role} topic {topic} is {bag.topics[topic]}, not {wanted}; pass "
                f"{flag} with a topic of that type ({bag.topic_list()})"
            )
        return topic, None
    candidates = sorted(t for t, msgtype in bag.topics.items() if msgtype in types)
    if len(candidates) == 1:
        picked = candidates[0]
        return picked, f"{role} topic {picked} ({_short(bag.topics[picked])}) picked automatically"
    if not candidates:
        if not required:
            return None, None
        raise StreamError(
            f"{bag.source}: no {role} topic ({wanted}) in the bag; {bag.topic_list()}; record "
            f"one, or pass {flag} if it has another type"
        )
    listed = ", ".join(f"{t} ({_short(bag.topics[t])})" for t in candidates)
    raise StreamError(
        f"{bag.source}: {len(candidates)} {role} topics ({listed}); pass {flag} with the one to use"
    )


def pick_joints(names: Iterable[str]) -> tuple[str, str] | None:
    """The rear-left and rear-right joint among ``names``, or ``None`` if ambiguous.

    The names containing ``left`` / ``right`` (case-insensitive); when there are several, only
    those also containing ``rear``. Exactly one of each must remain.
    """
    names = sorted(set(names))

    def side(word: str) -> list[str]:
        found = [n for n in names if word in n.lower()]
        if len(found) > 1:
            found = [n for n in found if "rear" in n.lower()]
        return found

    left, right = side("left"), side("right")
    if len(left) == 1 and len(right) == 1 and left[0] != right[0]:
        return left[0], right[0]
    return None


def _joint_names(bag: _Bag, topic: str) -> list[str]:
    """Every joint name in the first :data:`JOINT_SCAN_MESSAGES` messages of ``topic``."""
    names: set[str] = set()
    with bag.guard():
        for count, (_, _, msg) in enumerate(bag.messages([topic]), start=1):
            names.update(msg.name)
            if count >= JOINT_SCAN_MESSAGES:
                break
    return sorted(names)


# --- collecting the messages ------------------------------------------------------------------


#: Raw messages of a high-rate topic decoded together (:mod:`graphcal.data.bag_layout`).
RAW_CHUNK = 65536


@dataclass
class _Topic:
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
        stamp = msg.header.stamp
        self.stamps.append((stamp.sec, stamp.nanosec, timestamp))
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
            notes.append(f"{source}: header stamps all zero, used the bag's receive times")
        return sec.astype(float) + 1e-9 * nanosec.astype(float)


def _navsatfix(msg: Any) -> tuple:
    return msg.latitude, msg.longitude, msg.status.status


def _pose_of(get: Callable[[Any], Any]) -> Callable[[Any], tuple]:
    def extract(msg: Any) -> tuple:
        pose = get(msg)
        p, q = pose.position, pose.orientation
        return p.x, p.y, q.x, q.y, q.z, q.w

    return extract


def _odometry(msg: Any) -> tuple:
    p, q, v = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear
    return p.x, p.y, q.x, q.y, q.z, q.w, v.x, v.y


#: Forward body-frame speed [m/s] above which an Odometry twist's direction gives the
#: sideslip.
SIDESLIP_MIN_SPEED = 0.5

_EXTRACT = {
    NAVSATFIX: _navsatfix,
    ODOMETRY: _odometry,
    POSE_COVARIANCE: _pose_of(lambda m: m.pose.pose),
    POSE_STAMPED: _pose_of(lambda m: m.pose),
}


def _imu(msg: Any) -> tuple:
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


def _joint_extractor(left: str, right: str) -> tuple[Callable[[Any], tuple | None], set[str]]:
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


# --- post-processing --------------------------------------------------------------------------


#: The message fields behind the columns of each message type's rows (:data:`_EXTRACT`,
#: :func:`_imu`, :func:`_joint_extractor`), as the user would look them up.
_POSE_FIELDS = {
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
_IMU_FIELDS = (
    "linear_acceleration.y",
    "angular_velocity.z",
    "linear_acceleration_covariance[0]",
    "angular_velocity_covariance[0]",
    "orientation_covariance[0]",
    *(f"orientation.{a}" for a in "xyzw"),
)


def _unique(
    source: str,
    names: tuple[str, ...],
    values: np.ndarray,
    t: np.ndarray,
    numbers: np.ndarray,
    fields: dict[str, Field],
    notes: list[str],
) -> tuple[np.ndarray, np.ndarray, Provenance]:
    """The topic's rows sorted by stamp, a stamp written twice dropped when the messages
    agree and refused when they differ (the rule of CSV streams too:
    :func:`graphcal.data.streams.unique_samples`); returns ``values``, ``t`` and the
    :class:`Provenance` of the kept rows."""
    provenance = Provenance(source, {**{n: Field(n) for n in names}, **fields}, numbers, "message")
    columns = {name: values[:, j] for j, name in enumerate(names)}
    keep = unique_samples(t, columns, provenance, notes, sort=True)
    return values[keep], t[keep], provenance.take(keep)


def _yaw(q: np.ndarray) -> np.ndarray:
    """Yaw [rad] (ENU, about z) of quaternions ``(x, y, z, w)``, ``(M, 4)``."""
    x, y, z, w = q.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _no_messages(bag: _Bag, topic: str, role: str, flag: str) -> StreamError:
    return StreamError(
        f"{bag.source}: {role} topic {topic} has no messages; pass {flag} with a recorded "
        f"topic ({bag.topic_list()})"
    )


def _pose_stream(bag: _Bag, topic: str, rows: _Topic, notes: list[str]) -> PoseStream:
    source = f"{bag.source}:{topic}"
    msgtype = bag.topics[topic]
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    names = _POSE_FIELDS[msgtype]
    if msgtype == NAVSATFIX:
        fields = {"latitude": Field("latitude", None, "degrees")}
        fields["longitude"] = Field("longitude", None, "degrees")
    else:
        fields = {"x": Field(names[0], None, "m"), "y": Field(names[1], None, "m")}
        fields["heading"] = Field(names[2].rsplit(".", 1)[0], None, "yaw of the quaternion")
    if msgtype == NAVSATFIX:
        fixed = (values[:, 2] >= 0) & np.isfinite(values[:, :2]).all(axis=1)
        if not fixed.any():
            raise StreamError(
                f"{source}: none of the {len(t)} NavSatFix messages has a fix (status >= 0 and "
                "finite latitude/longitude); record the receiver with a fix or pass --pose-topic"
            )
        if not fixed.all():
            notes.append(f"{source}: skipped {int((~fixed).sum())} NavSatFix without a fix")
        values, t, numbers = values[fixed], t[fixed], numbers[fixed]
    values, t, provenance = _unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    if msgtype == NAVSATFIX:
        try:
            x, y, origin = geodetic_to_local(
                values[:, 0], values[:, 1], source, provenance=provenance
            )
        except GeodesyError as error:
            raise StreamError(str(error)) from None
        return PoseStream(t, x, y, None, None, source, origin, provenance)
    quaternion = values[:, 2:6]
    if not np.linalg.norm(quaternion, axis=1).any():
        notes.append(f"{source}: orientation all zero (not logged); the course is used")
        heading = None
    else:
        heading = _yaw(quaternion)
    sideslip = None
    if msgtype == ODOMETRY:  # body-frame twist (child frame): its direction is the sideslip
        vx, vy = values[:, 6], values[:, 7]
        forward = vx >= SIDESLIP_MIN_SPEED  # reversing (masked by the wheels) and standstill: 0
        if forward.any() and np.abs(vy).any():
            sideslip = np.where(forward, np.arctan2(vy, np.where(forward, vx, 1.0)), 0.0)
            notes.append(f"{source}: sideslip from the direction of the body-frame twist")
            provenance.fields["sideslip"] = Field("twist.twist.linear", None, "its direction")
    x, y = values[:, 0].copy(), values[:, 1].copy()
    return PoseStream(t, x, y, heading, sideslip, source, provenance=provenance)


def _wheel_stream(
    bag: _Bag,
    topic: str,
    rows: _Topic,
    joints: tuple[str, str],
    seen: set[str],
    wheel_kind: WheelKind | None,
    notes: list[str],
) -> WheelStream:
    source = f"{bag.source}:{topic}"
    names = ", ".join(sorted(seen)) or "none"
    if not len(rows):
        raise StreamError(
            f"{source}: no JointState message has both joints {joints[0]} and {joints[1]} "
            f"(joint names: {names}); pass --rear-left/--rear-right with two of them"
        )
    if rows.skipped:
        notes.append(
            f"{source}: skipped {rows.skipped} JointState message(s) without both {joints[0]} "
            f"and {joints[1]}"
        )
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    has_position = np.isfinite(values[:, :2]).all(axis=1)
    has_velocity = np.isfinite(values[:, 2:]).all(axis=1)
    if wheel_kind is None:
        wheel_kind = "angle" if has_position.all() or not has_velocity.any() else "angular_speed"
    angle = wheel_kind == "angle"
    present = has_position if angle else has_velocity
    field_name, other = ("position", "angular_speed") if angle else ("velocity", "angle")
    if not present.any():
        raise StreamError(
            f"{source}: the JointState messages carry no {field_name} of {joints[0]} and "
            f"{joints[1]}; pass --wheel-kind {other} or record the {field_name}"
        )
    if not present.all():
        notes.append(
            f"{source}: skipped {int((~present).sum())} JointState message(s) without a "
            f"{field_name}"
        )
    values, t, numbers = values[present], t[present], numbers[present]
    names = tuple(f"{kind}[{joint}]" for kind in ("position", "velocity") for joint in joints)
    unit = "rad, cumulative" if angle else "rad/s"
    used = names[:2] if angle else names[2:]
    fields = {"rear_left": Field(used[0], None, unit), "rear_right": Field(used[1], None, unit)}
    values, t, provenance = _unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    columns = values[:, :2] if angle else values[:, 2:]
    revolutions = columns / (2.0 * np.pi)
    return WheelStream(
        t,
        revolutions[:, 0].copy(),
        revolutions[:, 1].copy(),
        cumulative=angle,
        source=source,
        provenance=provenance,
    )


def _imu_stream(bag: _Bag, topic: str, rows: _Topic, notes: list[str]) -> ImuStream:
    source = f"{bag.source}:{topic}"
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    fields = {
        "lateral_acceleration": Field(_IMU_FIELDS[0], None, "m/s², REP 103: y to the left"),
        "yaw_rate": Field(_IMU_FIELDS[1], None, "rad/s, REP 103: z up"),
    }
    values, t, provenance = _unique(source, _IMU_FIELDS, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    signals = []
    for column, covariance, what in ((0, 2, "linear acceleration"), (1, 3, "angular velocity")):
        # REP 145: a covariance whose first element is -1 means "this field is not provided".
        if (values[:, covariance] == -1).all():
            notes.append(f"{source}: {what} not provided (covariance -1)")
            signals.append(None)
        else:
            signals.append(values[:, column].copy())
    return ImuStream(t, signals[0], signals[1], source, provenance)


def _imu_heading(rows: _Topic, imu: ImuStream, pose: PoseStream, notes: list[str]) -> PoseStream:
    """``pose`` with the heading of the IMU's orientation (an INS's), if it gives one.

    A NavSatFix has no heading; an INS publishes its orientation in the Imu messages. The
    yaw is unwrapped and interpolated at the fix times.
    """
    values = rows.values()
    t_raw = rows.times(imu.source, [])
    provided = values[:, 4] != -1
    quaternion = values[:, 5:9]
    if not provided.all() or not np.linalg.norm(quaternion, axis=1).all():
        return pose
    order = np.argsort(t_raw, kind="stable")
    t_sorted, yaw = t_raw[order], np.unwrap(_yaw(quaternion[order]))
    keep = np.concatenate([[True], np.diff(t_sorted) > 0])
    heading = np.interp(pose.t, t_sorted[keep], yaw[keep])
    notes.append(f"heading from the orientation of {imu.source} (an INS), at the fix times")
    return dataclasses.replace(pose, heading=heading)


# --- the reader -------------------------------------------------------------------------------


def read_bag(
    path: str | Path,
    *,
    pose_topic: str | None = None,
    wheel_topic: str | None = None,
    imu_topic: str | None = None,
    rear_left: str | None = None,
    rear_right: str | None = None,
    wheel_kind: WheelKind | None = None,
    source: str | None = None,
) -> Recording:
    """Read the pose, rear-wheel and (optional) IMU streams of a ROS 1/ROS 2 bag or MCAP file.

    Args:
        path: a ``.bag`` file, a ``.mcap`` file or a ROS 2 bag directory.
        pose_topic: NavSatFix, Odometry, PoseStamped or PoseWithCovarianceStamped topic;
            ``None``: the only topic of one of these types.
        wheel_topic: JointState topic; ``None``: the only one.
        imu_topic: Imu topic; ``None``: the only one, or no IMU stream if there is none.
        rear_left, rear_right: joint names of the rear wheels; ``None``: the two joints named
            ``*left*`` / ``*right*`` (preferring ``*rear*``).
        wheel_kind: ``"angle"`` (JointState position [rad], cumulative) or
            ``"angular_speed"`` (velocity [rad/s]); ``None``: positions when every message
            carries them, else velocities.
        source: name of the recording in messages (default: the path).

    Returns:
        The :class:`Recording`: time [s] from the header stamps, positions [m] (east/north
        of the first fix for NavSatFix), heading [rad, ENU], wheels [rev] or [rev/s], lateral
        acceleration [m/s²] and yaw rate [rad/s]; ``notes`` say what was picked or skipped.

    Raises:
        StreamError: a missing or unreadable bag, a topic or joint that is absent, of the
            wrong type, ambiguous or empty; the message is one line.
    """
    path = Path(path)
    source = source or str(path)
    if wheel_kind not in (None, "angle", "angular_speed"):
        raise StreamError(
            f"{source}: wheel kind {wheel_kind!r} is unknown; use 'angle' or 'angular_speed'"
        )
    bag = _Bag(path, source)
    try:
        return _read(bag, pose_topic, wheel_topic, imu_topic, rear_left, rear_right, wheel_kind)
    finally:
        bag.close()


def _read(
    bag: _Bag,
    pose_topic: str | None,
    wheel_topic: str | None,
    imu_topic: str | None,
    rear_left: str | None,
    rear_right: str | None,
    wheel_kind: WheelKind | None,
) -> Recording:
    notes: list[str] = []
    picks = [
        _pick_topic(bag, pose_topic, POSE_TYPES, "pose", "--pose-topic", True),
        _pick_topic(bag, wheel_topic, (JOINT_STATE,), "wheel", "--wheel-topic", True),
        _pick_topic(bag, imu_topic, (IMU,), "IMU", "--imu-topic", False),
    ]
    notes.extend(note for _, note in picks if note)
    (pose, _), (wheel, _), (imu, _) = picks
    assert pose is not None and wheel is not None
    streams = [(pose, "pose", "--pose-topic"), (wheel, "wheel", "--wheel-topic")]
    if imu is not None:
        streams.append((imu, "IMU", "--imu-topic"))
    for topic, role, flag in streams:
        if any(bag.counts.values()) and bag.counts.get(topic, 0) == 0:  # counts are known
            raise _no_messages(bag, topic, role, flag)

    joints = _resolve_joints(bag, wheel, rear_left, rear_right, notes)
    joint_extract, seen = _joint_extractor(*joints)
    collected = {
        pose: _Topic(_EXTRACT[bag.topics[pose]]),
        wheel: bag.raw_topic(joint_extract, JOINT_STATE, joints),
    }
    if imu is not None:
        collected[imu] = bag.raw_topic(_imu, IMU)
    with bag.guard():
        for topic, timestamp, raw, msgtype in bag.raw_messages(collected):
            rows = collected[topic]
            if rows.decode is not None:
                rows.add_raw(timestamp, raw)
            else:
                rows.add(timestamp, bag.reader.deserialize(raw, msgtype))
        for rows in collected.values():
            rows.flush()
    for topic, role, flag in streams:
        if not len(collected[topic]) and not collected[topic].skipped:
            raise _no_messages(bag, topic, role, flag)

    pose_stream = _pose_stream(bag, pose, collected[pose], notes)
    wheels = _wheel_stream(bag, wheel, collected[wheel], joints, seen, wheel_kind, notes)
    imu_stream = _imu_stream(bag, imu, collected[imu], notes) if imu is not None else None
    if pose_stream.heading is None and imu_stream is not None:
        pose_stream = _imu_heading(collected[imu], imu_stream, pose_stream, notes)
    return Recording(pose_stream, wheels, imu_stream, bag.source, tuple(notes))


def _resolve_joints(
    bag: _Bag, topic: str, rear_left: str | None, rear_right: str | None, notes: list[str]
) -> tuple[str, str]:
    """The rear-left and rear-right joint names: given, or picked from the first messages."""
    source = f"{bag.source}:{topic}"
    if rear_left is not None and rear_right is not None:
        if rear_left == rear_right:
            raise StreamError(
                f"{source}: rear-left and rear-right joint are both {rear_left!r}; pass "
                "--rear-left/--rear-right with two different joints"
            )
        return rear_left, rear_right
    names = _joint_names(bag, topic)
    listed = ", ".join(names) or "none"
    if rear_left is None and rear_right is None:
        picked = pick_joints(names)
        if picked is None:
            raise StreamError(
                f"{source}: cannot tell the rear wheel joints from the joint names ({listed}); "
                "pass --rear-left/--rear-right"
            )
        notes.append(f"{source}: rear wheel joints {picked[0]}, {picked[1]} picked automatically")
        return picked
    given, flag = (rear_left, "--rear-right") if rear_right is None else (rear_right, "--rear-left")
    raise StreamError(
        f"{source}: only one rear wheel joint given ({given}); pass {flag} too (joint names: "
        f"{listed})"
    )
