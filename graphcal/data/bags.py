"""ROS 1 bags, ROS 2 bags (sqlite3 or mcap storage) and bare MCAP files, read with ``rosbags``.

``rosbags`` is pure Python (no ROS installation); it is the optional extra ``graphcal[ros]``
and is imported only inside the functions. :func:`read_bag` turns the bag's topics into the
streams of :mod:`graphcal.data.streams`:

* pose: ``sensor_msgs/NavSatFix`` (latitude/longitude → east/north [m] from the first fix,
  no heading), ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``geometry_msgs/PoseWithCovarianceStamped`` (x, y [m]; heading = yaw of the orientation);
* wheels: ``sensor_msgs/JointState`` of the two rear wheel joints, ``position`` [rad,
  cumulative] → revolutions, or ``velocity`` [rad/s] → revolutions per second; or a vendor
  wheel-speed message recognised by its type (:data:`VENDOR_WHEELS`: Dataspeed
  ``dbw_mkz_msgs/WheelSpeedReport``, PACMod ``WheelSpeedRpt``, rad/s);
* IMU (optional): ``sensor_msgs/Imu``, ``linear_acceleration.y`` [m/s²] and
  ``angular_velocity.z`` [rad/s] in the vehicle frame (x forward, y left; REP 103).

Any numeric field of any topic can stand for a wheel, the heading or an IMU signal, named
``TOPIC:FIELD`` (:class:`FieldRef`: ``/car/wheels:wheels[2].speed``), checked against and read
through the message definitions the bag carries (rosbags' typestore of the bag); a wheel
field's kind and unit convert it as ``[wheels] kind`` does a CSV column.

Time is each message's ``header.stamp``; when every stamp of a topic is zero, or its messages
have no header, the time the bag recorded the message. Every topic is read in one pass over
the bag; each message is deserialized once (or its numbers gathered from the raw bytes of a
topic of one layout, :mod:`graphcal.data.bag_layout`) and only its few numbers are kept,
converted to arrays at the end.
"""

from __future__ import annotations

import dataclasses
import math
import re
import sqlite3
import struct
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from graphcal.data.bag_layout import (
    ARRAY,
    BASE,
    NAME,
    PRIMITIVES,
    SEQUENCE,
    Steps,
    decode_fields,
    decode_fixed,
)
from graphcal.data.geodesy import GeodesyError, geodetic_to_local
from graphcal.data.manifest import (
    ANGLE_UNITS,
    HEADING_CONVENTIONS,
    SPEED_UNITS,
    WHEEL_KINDS,
    YAW_RATE_UNITS,
)
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
HEADER = "std_msgs/msg/Header"
#: Message types usable as the pose stream.
POSE_TYPES = (NAVSATFIX, ODOMETRY, POSE_STAMPED, POSE_COVARIANCE)
#: Files of a ROS 2 bag's storage (also readable on their own).
STORAGE_SUFFIXES = (".db3", ".mcap")
#: JointState messages looked at to find the rear wheel joints when they are not named.
JOINT_SCAN_MESSAGES = 200
WheelKind = Literal["speed", "angular_speed", "rpm", "ticks", "angle"]
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


# --- field paths: any numeric field of any message --------------------------------------------

#: Vendor wheel-speed messages read without flags: type → (what it is, the rear-left and
#: rear-right fields, their kind). Both report each wheel's angular speed [rad/s].
VENDOR_WHEELS = {
    "dbw_mkz_msgs/msg/WheelSpeedReport": (
        "Dataspeed wheel speeds, rad/s",
        "rear_left",
        "rear_right",
    ),
    "pacmod_msgs/msg/WheelSpeedRpt": (
        "PACMod wheel speeds, rad/s",
        "rear_left_wheel_speed",
        "rear_right_wheel_speed",
    ),
    "pacmod3_msgs/msg/WheelSpeedRpt": (
        "PACMod wheel speeds, rad/s",
        "rear_left_wheel_speed",
        "rear_right_wheel_speed",
    ),
}
#: Messages with the vehicle's speed but not each wheel's: refused as wheels, saying so.
SPEED_ONLY = (
    "autoware_auto_vehicle_msgs/msg/VelocityReport",
    "autoware_vehicle_msgs/msg/VelocityReport",
)
#: Their definitions, registered when a bag carries none (a ROS 2 bag recorded before Iron).
VENDOR_DEFINITIONS = {
    "dbw_mkz_msgs/msg/WheelSpeedReport": (
        "std_msgs/Header header\nfloat32 front_left\nfloat32 front_right\nfloat32 rear_left\n"
        "float32 rear_right\n"
    ),
    **dict.fromkeys(
        ("pacmod_msgs/msg/WheelSpeedRpt", "pacmod3_msgs/msg/WheelSpeedRpt"),
        "std_msgs/Header header\nfloat64 front_left_wheel_speed\nfloat64 front_right_wheel_speed\n"
        "float64 rear_left_wheel_speed\nfloat64 rear_right_wheel_speed\n",
    ),
}
#: Kinds of a wheel field and what each needs, for messages.
WHEEL_FIELD_KINDS = (
    "speed [with --speed-unit and --circumference], angular_speed [rad/s], rpm, "
    "ticks [cumulative, with --ticks-per-revolution], angle [rad, cumulative]"
)
_PATH = re.compile(r"[A-Za-z_]\w*(\[\d+\])*(\.[A-Za-z_]\w*(\[\d+\])*)*")
_STEP = re.compile(r"([A-Za-z_]\w*)|\[(\d+)\]")
#: Numeric fields listed at most in a message about a field that is not a number.
LISTED_FIELDS = 24


@dataclass(frozen=True)
class FieldRef:
    """One numeric field of a topic's messages, as the user named it.

    Attributes:
        topic: the topic (``/vehicle/wheel_speeds``).
        path: the field path, dotted into nested fields, with array indices
            (``wheels[2].speed``).
        steps: the path's field names and indices (``("wheels", 2, "speed")``).
        flag: the option that named it (``--rear-left``), or ``None`` when picked by type.
    """

    topic: str
    path: str
    steps: Steps
    flag: str | None = None

    @property
    def written(self) -> str:
        """``/vehicle/wheel_speeds:rear_left``, as on the command line."""
        return f"{self.topic}:{self.path}"

    def get(self, msg: Any) -> float | None:
        """The field's value in a deserialized message; ``None`` if an index is beyond a
        sequence's end."""
        value = msg
        try:
            for step in self.steps:
                value = value[step] if isinstance(step, int) else getattr(value, step)
        except IndexError:
            return None
        return float(value)


def parse_steps(path: str) -> Steps:
    """``"wheels[2].speed"`` → ``("wheels", 2, "speed")``; :class:`ValueError` if malformed."""
    if not _PATH.fullmatch(path):
        raise ValueError(path)
    return tuple(name or int(index) for name, index in _STEP.findall(path))


def is_field_ref(text: str | None, bag_topics: dict[str, str]) -> bool:
    """Whether an option's value is ``TOPIC:FIELD`` (a topic — absolute, or one in the bag —
    then a colon), not a joint name."""
    if text is None or ":" not in text:
        return False
    topic = text.split(":", 1)[0]
    return topic.startswith("/") or topic in bag_topics


def _describe(nodetype: int, desc: Any) -> str:
    """``float32``, ``std_msgs/msg/Header``, ``float64[9]``, ``Wheel[]`` of a definition node."""
    if nodetype == BASE:
        return desc[0]
    if nodetype == NAME:
        return desc
    (subtype, subdesc), bound = desc
    inner = _describe(subtype, subdesc)
    return f"{inner}[{bound}]" if nodetype == ARRAY else f"{inner}[]"


def _listing(fielddefs: dict, msgtype: str) -> str:
    """``header (std_msgs/msg/Header), front_left (float32), ...``: a message's fields."""
    fields = fielddefs[msgtype][1]
    return ", ".join(f"{name} ({_describe(*node)})" for name, node in fields) or "none"


def _numeric_paths(fielddefs: dict, msgtype: str, prefix: str = "", depth: int = 0) -> list[str]:
    """The message's numeric field paths (arrays as ``name[i]``), nested up to 4 levels."""
    found: list[str] = []
    for name, (nodetype, desc) in fielddefs[msgtype][1]:
        path = f"{prefix}{name}"
        while nodetype in (ARRAY, SEQUENCE):
            (nodetype, desc), _ = desc
            path += "[i]"
        if nodetype == BASE and desc[0] in PRIMITIVES:
            found.append(path)
        elif nodetype == NAME and depth < 4 and desc in fielddefs:
            found.extend(_numeric_paths(fielddefs, desc, f"{path}.", depth + 1))
    return found


def resolve_field(bag: _Bag, ref: FieldRef) -> str:
    """The primitive type (``float32``) of ``ref``, checked against the topic's message
    definition; :class:`StreamError` naming the option, topic, type and path and listing what
    exists (the bag's topics, the fields at the level where the path fails)."""
    flag = f"{ref.flag} {ref.written}" if ref.flag else ref.written
    where = f"{bag.source}: {flag}"
    if ref.topic not in bag.topics:
        raise StreamError(f"{where}: no topic {ref.topic} in the bag; {bag.topic_list()}")
    msgtype = bag.topics[ref.topic]
    fielddefs = bag.reader.typestore.fielddefs
    if msgtype not in fielddefs:
        raise StreamError(
            f"{where}: the bag carries no definition of {msgtype} (a ROS 2 bag recorded before "
            "Iron stores none), so its fields cannot be read; record with a newer ROS 2"
        )
    nodetype, desc = NAME, msgtype
    walked = ""
    for step in ref.steps:
        what = f"{walked} ({_describe(nodetype, desc)})" if walked else msgtype
        if isinstance(step, str):
            if nodetype != NAME:
                hint = f"; index it: {walked}[0]" if nodetype in (ARRAY, SEQUENCE) else ""
                raise StreamError(f"{where}: {what} has no fields{hint}")
            fields = dict(fielddefs[desc][1])
            if step not in fields:
                raise StreamError(
                    f"{where}: {what} has no field {step!r}; its fields: "
                    f"{_listing(fielddefs, desc)}"
                )
            nodetype, desc = fields[step]
            walked = f"{walked}.{step}" if walked else step
            continue
        if nodetype not in (ARRAY, SEQUENCE):
            raise StreamError(f"{where}: {what} is not an array; drop the index [{step}]")
        (subtype, subdesc), bound = desc
        if nodetype == ARRAY and step >= bound:
            raise StreamError(
                f"{where}: {what} has {bound} elements; index 0 to {bound - 1}, not {step}"
            )
        nodetype, desc = subtype, subdesc
        walked += f"[{step}]"
    if nodetype == BASE and desc[0] in PRIMITIVES:
        return desc[0]
    what = f"{walked} ({_describe(nodetype, desc)})"
    if nodetype == NAME:
        exists = f"its fields: {_listing(fielddefs, desc)}"
    elif nodetype in (ARRAY, SEQUENCE):
        exists = f"index it: {walked}[0]"
    else:
        numeric = _numeric_paths(fielddefs, msgtype)
        shown = ", ".join(numeric[:LISTED_FIELDS]) + (
            ", ..." if len(numeric) > LISTED_FIELDS else ""
        )
        exists = f"the numeric fields of {msgtype}: {shown or 'none'}"
    raise StreamError(f"{where}: {what} is not a number; {exists}")


def _field_ref(bag: _Bag, flag: str, text: str, topic: str | None = None) -> FieldRef:
    """``TOPIC:FIELD`` (or a bare field path on ``topic``) as a checked :class:`FieldRef`."""
    if topic is None:
        topic, path = text.split(":", 1)
    else:
        path = text
    try:
        steps = parse_steps(path)
    except ValueError:
        raise StreamError(
            f"{bag.source}: {flag} {text}: {path!r} is not a field path; write TOPIC:FIELD, "
            "the field dotted into nested fields with array indices (/vehicle/wheels:"
            "wheels[2].speed)"
        ) from None
    ref = FieldRef(topic, path, steps, flag)
    resolve_field(bag, ref)
    return ref


def _field_rows(bag: _Bag, msgtype: str, refs: list[FieldRef]) -> _Topic:
    """A :class:`_Topic` of the numbers at ``refs`` (one topic of type ``msgtype``): decoded
    from raw bytes in chunks when the messages share a layout, else one by one."""
    fielddefs = bag.reader.typestore.fielddefs
    first = fielddefs[msgtype][1][:1]
    stamped = bool(first) and first[0][0] == "header" and first[0][1] == (NAME, HEADER)
    paths = [ref.steps for ref in refs]

    def decode(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
        if not FAST_DECODING:
            return None
        return decode_fields(raws, msgtype, fielddefs, paths, bag.ros1, stamped)

    def extract(msg: Any) -> tuple | None:
        values = tuple(ref.get(msg) for ref in refs)
        return None if None in values else values

    def deserialize(raw: bytes) -> Any:
        return bag.reader.deserialize(raw, msgtype)

    return _Topic(extract, decode, deserialize, stamped=stamped)


def _field_values(
    source: str, rows: _Topic, refs: list[FieldRef], notes: list[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(values, t, numbers)`` of a field topic's messages whose fields are all finite."""
    paths = " and ".join(ref.path for ref in refs)
    if not len(rows):
        raise StreamError(
            f"{source}: no message has {paths} (an index beyond the end of every message's "
            "array); name fields that the messages carry"
        )
    if rows.skipped:
        notes.append(f"{source}: skipped {rows.skipped} message(s) without {paths}")
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        raise StreamError(f"{source}: {paths} is not finite in any message; name another field")
    if not finite.all():
        notes.append(f"{source}: skipped {int((~finite).sum())} message(s) where {paths} is NaN")
        values, t, numbers = values[finite], t[finite], numbers[finite]
    return values, t, numbers


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


# --- what to read: the options, and the wheels, IMU and heading named as fields ---------------


@dataclass(frozen=True)
class BagRequest:
    """What :func:`read_bag` was asked to read (its keyword arguments; ``None``: detect)."""

    pose_topic: str | None = None
    wheel_topic: str | None = None
    imu_topic: str | None = None
    rear_left: str | None = None
    rear_right: str | None = None
    wheel_kind: str | None = None
    speed_unit: str | None = None
    circumference: float | None = None
    ticks_per_revolution: float | None = None
    heading: str | None = None
    heading_unit: str | None = None
    heading_convention: str | None = None
    yaw_rate: str | None = None
    yaw_rate_unit: str | None = None
    lateral_acceleration: str | None = None


@dataclass(frozen=True)
class _WheelFields:
    """The rear wheels as two numeric fields of one topic, and what they hold."""

    topic: str
    left: FieldRef
    right: FieldRef
    kind: str
    vendor: str | None = None


def _check_request(source: str, r: BagRequest) -> None:
    """One line for an option's value that is unknown or out of range."""
    choices = (
        ("--wheel-kind", r.wheel_kind, WHEEL_KINDS),
        ("--speed-unit", r.speed_unit, tuple(SPEED_UNITS)),
        ("--heading-unit", r.heading_unit, tuple(ANGLE_UNITS)),
        ("--heading-convention", r.heading_convention, HEADING_CONVENTIONS),
        ("--yaw-rate-unit", r.yaw_rate_unit, tuple(YAW_RATE_UNITS)),
    )
    for flag, value, options in choices:
        if value is not None and value not in options:
            raise StreamError(f"{source}: {flag} {value!r} is unknown; use {', '.join(options)}")
    for flag, value in (
        ("--circumference", r.circumference),
        ("--ticks-per-revolution", r.ticks_per_revolution),
    ):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise StreamError(f"{source}: {flag} {value} must be a positive number")


def _register_vendor_types(bag: _Bag, notes: list[str]) -> None:
    """Register the known vendor definitions the bag does not carry (older ROS 2 bags)."""
    from rosbags.typesys import get_types_from_msg

    store = bag.reader.typestore
    for msgtype in sorted(set(bag.topics.values()) & set(VENDOR_DEFINITIONS)):
        if msgtype not in store.fielddefs:
            with bag.guard():
                store.register(get_types_from_msg(VENDOR_DEFINITIONS[msgtype], msgtype))
            notes.append(
                f"{bag.source}: the bag carries no definition of {msgtype}; read with the "
                "vendor's published one"
            )


def _wheel_fields(bag: _Bag, r: BagRequest, notes: list[str]) -> _WheelFields | None:
    """The wheels as fields of a topic — named (``--rear-left TOPIC:FIELD``, or fields of a
    ``--wheel-topic`` that is no JointState) or a vendor wheel-speed message picked by its
    type — or ``None`` to read the joints of a JointState."""
    left_ref, right_ref = (
        is_field_ref(r.rear_left, bag.topics),
        is_field_ref(r.rear_right, bag.topics),
    )
    topic_type = bag.topics.get(r.wheel_topic or "")
    on_topic = topic_type is not None and topic_type != JOINT_STATE
    if left_ref or right_ref or (on_topic and (r.rear_left or r.rear_right)):
        if r.rear_left is None or r.rear_right is None:
            given, other = (
                ("--rear-left", "--rear-right")
                if r.rear_right is None
                else ("--rear-right", "--rear-left")
            )
            raise StreamError(
                f"{bag.source}: {given} {r.rear_left or r.rear_right} names a field; pass {other} "
                "too (TOPIC:FIELD, or a field of the same topic)"
            )
        # A bare field is on the other option's topic, else on --wheel-topic.
        written = r.rear_left if left_ref else r.rear_right if right_ref else None
        anchor = written.split(":", 1)[0] if written is not None else r.wheel_topic
        refs = {}
        for flag, text, is_ref in sorted(
            (("--rear-left", r.rear_left, left_ref), ("--rear-right", r.rear_right, right_ref)),
            key=lambda option: not option[2],  # the TOPIC:FIELD ones first
        ):
            refs[flag] = _field_ref(bag, flag, text, None if is_ref else anchor)
        left, right = refs["--rear-left"], refs["--rear-right"]
        if left.topic != right.topic:
            raise StreamError(
                f"{bag.source}: --rear-left {left.written} and --rear-right {right.written} are "
                "on different topics; name two fields of one topic"
            )
        if r.wheel_topic is not None and r.wheel_topic != left.topic:
            raise StreamError(
                f"{bag.source}: --wheel-topic {r.wheel_topic} but --rear-left {left.written}; "
                "leave --wheel-topic out or name fields of it"
            )
        if left.steps == right.steps:
            raise StreamError(
                f"{bag.source}: --rear-left and --rear-right are both {left.written}; name the "
                "two wheels' fields"
            )
        vendor = VENDOR_WHEELS.get(bag.topics[left.topic])
        kind = r.wheel_kind or ("angular_speed" if vendor else None)
        if kind is None:
            raise StreamError(
                f"{bag.source}: --rear-left {left.written}: pass --wheel-kind, what the fields "
                f"hold: {WHEEL_FIELD_KINDS}"
            )
        label = vendor[0] if vendor and r.wheel_kind is None else None
        return _WheelFields(left.topic, left, right, kind, label)
    speed_only = [t for t, msgtype in sorted(bag.topics.items()) if msgtype in SPEED_ONLY]
    nothing_else = (r.wheel_topic, r.rear_left, r.rear_right) == (None, None, None) and not any(
        msgtype == JOINT_STATE or msgtype in VENDOR_WHEELS for msgtype in bag.topics.values()
    )
    if speed_only and (topic_type in SPEED_ONLY or nothing_else):
        topic = r.wheel_topic if topic_type in SPEED_ONLY else speed_only[0]
        raise StreamError(
            f"{bag.source}: {topic} ({_short(bag.topics[topic])}) has the vehicle's "
            "longitudinal speed only, not each rear wheel's that the calibration needs; record "
            "the wheel speeds (a JointState, the vehicle's wheel-speed report) and name them"
        )
    if on_topic:
        assert r.wheel_topic is not None and topic_type is not None
        if topic_type not in VENDOR_WHEELS:
            raise StreamError(
                f"{bag.source}: wheel topic {r.wheel_topic} is {topic_type}, neither JointState "
                "nor a known wheel-speed message; name its fields with --rear-left FIELD "
                f"--rear-right FIELD and --wheel-kind (its fields: "
                f"{_listing(bag.reader.typestore.fielddefs, topic_type)})"
                if topic_type in bag.reader.typestore.fielddefs
                else f"{bag.source}: wheel topic {r.wheel_topic} is {topic_type}, of which the "
                "bag carries no definition; pass --wheel-topic with a JointState topic"
            )
        return _vendor_fields(bag, r.wheel_topic, r.wheel_kind)
    if r.rear_left is not None or r.rear_right is not None or r.wheel_topic is not None:
        return None  # joints of a JointState
    vendors = sorted(t for t, msgtype in bag.topics.items() if msgtype in VENDOR_WHEELS)
    if len(vendors) > 1:
        listed = ", ".join(f"{t} ({_short(bag.topics[t])})" for t in vendors)
        raise StreamError(
            f"{bag.source}: {len(vendors)} wheel-speed topics ({listed}); pass --wheel-topic "
            "with the one to use"
        )
    if not vendors:
        return None
    picked = _vendor_fields(bag, vendors[0], r.wheel_kind)
    joint_states = sorted(t for t, msgtype in bag.topics.items() if msgtype == JOINT_STATE)
    rather = (
        f", rather than the JointState {', '.join(joint_states)} (pass --wheel-topic to use it)"
        if joint_states
        else ""
    )
    vendor = VENDOR_WHEELS[bag.topics[picked.topic]][0]
    notes.append(
        f"wheel topic {picked.topic} ({_short(bag.topics[picked.topic])}: {vendor}) "
        f"picked automatically{rather}"
    )
    return picked


def _vendor_fields(bag: _Bag, topic: str, wheel_kind: str | None) -> _WheelFields:
    """The rear wheels of a vendor wheel-speed message (:data:`VENDOR_WHEELS`)."""
    vendor, left, right = VENDOR_WHEELS[bag.topics[topic]]
    refs = [FieldRef(topic, path, (path,)) for path in (left, right)]
    for ref in refs:
        resolve_field(bag, ref)  # the bag's own definition of the type must have them
    label = vendor if wheel_kind is None else None  # the vendor's unit, unless overridden
    return _WheelFields(topic, refs[0], refs[1], wheel_kind or "angular_speed", label)


def _wheel_conversion(
    source: str, fields: _WheelFields | None, r: BagRequest
) -> tuple[float, bool, float | None, str, tuple[tuple[str, str], ...]]:
    """``(scale to revolutions [per second], cumulative, resolution [rev], unit text, declared
    units)`` of the wheel fields' kind, as ``[wheels] kind`` converts a CSV's columns."""
    given = {
        "--speed-unit": r.speed_unit,
        "--circumference": r.circumference,
        "--ticks-per-revolution": r.ticks_per_revolution,
    }
    kind = fields.kind if fields is not None else r.wheel_kind
    needs = {"speed": ("--speed-unit", "--circumference"), "ticks": ("--ticks-per-revolution",)}
    for flag, value in given.items():
        if value is not None and (fields is None or flag not in needs.get(kind or "", ())):
            applies = "speed" if flag != "--ticks-per-revolution" else "ticks"
            raise StreamError(
                f"{source}: {flag} applies to wheels read from fields (--rear-left TOPIC:FIELD) "
                f"with --wheel-kind {applies}; leave it out"
            )
    if fields is None:
        return 1.0, True, None, "", ()
    if kind == "speed":
        if r.circumference is None:
            raise StreamError(
                f"{source}: --wheel-kind speed needs --circumference: the wheel circumference [m] "
                "the ECU used to turn rotations into speed (from its documentation; often 2.0)"
            )
        unit = r.speed_unit or "m/s"
        by_default = "" if r.speed_unit else " by default"
        text = (
            f"--wheel-kind speed, --speed-unit {unit}{by_default}, "
            f"--circumference {r.circumference:g} m"
        )
        declared = (("kind", kind), ("speed_unit", unit), ("circumference", repr(r.circumference)))
        return SPEED_UNITS[unit] / r.circumference, False, None, text, declared
    if kind == "ticks":
        if r.ticks_per_revolution is None:
            raise StreamError(f"{source}: --wheel-kind ticks needs --ticks-per-revolution")
        ticks = r.ticks_per_revolution
        text = f"--wheel-kind ticks, --ticks-per-revolution {ticks:g}"
        declared = (("kind", kind), ("ticks_per_revolution", repr(ticks)))
        return 1.0 / ticks, True, 1.0 / ticks, text, declared
    scale = 1.0 / 60.0 if kind == "rpm" else 1.0 / (2.0 * np.pi)
    text = fields.vendor or f"--wheel-kind {kind}"
    return scale, kind == "angle", None, text, (("kind", kind),)


def _field_wheel_stream(
    bag: _Bag, fields: _WheelFields, rows: _Topic, r: BagRequest, notes: list[str]
) -> WheelStream:
    """The wheel stream of two fields, converted to revolutions [per second] by their kind."""
    source = f"{bag.source}:{fields.topic}"
    scale, cumulative, resolution, unit, declared = _wheel_conversion(source, fields, r)
    refs = [fields.left, fields.right]
    values, t, numbers = _field_values(source, rows, refs, notes)
    roles = ("rear_left", "rear_right")
    provenance_fields = {
        role: Field(ref.path, ref.flag, unit, declared)
        for role, ref in zip(roles, refs, strict=True)
    }
    names = (fields.left.path, fields.right.path)
    values, t, provenance = _unique(source, names, values, t, numbers, provenance_fields, notes)
    _check_time(t, source, provenance)
    return WheelStream(
        t,
        values[:, 0] * scale,
        values[:, 1] * scale,
        cumulative=cumulative,
        source=source,
        resolution=resolution,
        provenance=provenance,
    )


def _imu_fields(bag: _Bag, r: BagRequest) -> list[FieldRef]:
    """``--lateral-acceleration`` / ``--yaw-rate`` as fields of one topic (or none given)."""
    refs = []
    for text, flag in (
        (r.lateral_acceleration, "--lateral-acceleration"),
        (r.yaw_rate, "--yaw-rate"),
    ):
        if text is None:
            continue
        if is_field_ref(text, bag.topics):
            refs.append(_field_ref(bag, flag, text))
        elif r.imu_topic is not None:
            refs.append(_field_ref(bag, flag, text, r.imu_topic))
        else:
            raise StreamError(
                f"{bag.source}: {flag} {text}: name its topic too ({flag} TOPIC:{text}) or pass "
                "--imu-topic"
            )
    topics = sorted({ref.topic for ref in refs})
    if len(topics) > 1:
        raise StreamError(
            f"{bag.source}: --lateral-acceleration and --yaw-rate are on different topics "
            f"({', '.join(topics)}); name two fields of one topic"
        )
    if refs and r.imu_topic is not None and r.imu_topic != topics[0]:
        raise StreamError(
            f"{bag.source}: --imu-topic {r.imu_topic} but {refs[0].flag} {refs[0].written}; "
            "leave --imu-topic out or name fields of it"
        )
    if r.yaw_rate_unit is not None and r.yaw_rate is None:
        raise StreamError(f"{bag.source}: --yaw-rate-unit applies to --yaw-rate TOPIC:FIELD")
    return refs


def _field_imu_stream(
    bag: _Bag, refs: list[FieldRef], rows: _Topic, r: BagRequest, notes: list[str]
) -> ImuStream:
    """The IMU stream of ``--lateral-acceleration`` and/or ``--yaw-rate`` fields."""
    source = f"{bag.source}:{refs[0].topic}"
    values, t, numbers = _field_values(source, rows, refs, notes)
    unit = r.yaw_rate_unit or "rad/s"
    fields = {}
    for ref in refs:
        if ref.flag == "--yaw-rate":
            by_default = "" if r.yaw_rate_unit else " by default"
            fields["yaw_rate"] = Field(
                ref.path,
                ref.flag,
                f"--yaw-rate-unit {unit}{by_default}",
                (("yaw_rate_unit", unit),),
            )
        else:
            fields["lateral_acceleration"] = Field(ref.path, ref.flag, "m/s², positive to the left")
    names = tuple(ref.path for ref in refs)
    values, t, provenance = _unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    signals: dict[str, np.ndarray | None] = {"lateral_acceleration": None, "yaw_rate": None}
    for column, role in enumerate(fields):
        scale = YAW_RATE_UNITS[unit] if role == "yaw_rate" else 1.0
        signals[role] = values[:, column] * scale
    return ImuStream(t, signals["lateral_acceleration"], signals["yaw_rate"], source, provenance)


def _heading_field(bag: _Bag, r: BagRequest) -> FieldRef | None:
    """``--heading TOPIC:FIELD``, checked (or ``None``)."""
    if r.heading is None:
        for flag, value in (
            ("--heading-unit", r.heading_unit),
            ("--heading-convention", r.heading_convention),
        ):
            if value is not None:
                raise StreamError(f"{bag.source}: {flag} applies to --heading TOPIC:FIELD")
        return None
    if not is_field_ref(r.heading, bag.topics):
        raise StreamError(
            f"{bag.source}: --heading {r.heading}: write TOPIC:FIELD (a topic of the bag, a "
            f"colon, the field); {bag.topic_list()}"
        )
    return _field_ref(bag, "--heading", r.heading)


def _field_heading(
    bag: _Bag, ref: FieldRef, rows: _Topic, pose: PoseStream, r: BagRequest, notes: list[str]
) -> PoseStream:
    """``pose`` with the heading of a field (``--heading``), unwrapped and interpolated at the
    pose's times; ``--heading-unit`` (default rad) and ``--heading-convention`` (default enu,
    REP 103) as ``[gnss] heading_unit`` / ``heading_convention`` for a CSV."""
    source = f"{bag.source}:{ref.topic}"
    values, t, _ = _field_values(source, rows, [ref], notes)
    unit, convention = r.heading_unit or "rad", r.heading_convention or "enu"
    angle = values[:, 0] * ANGLE_UNITS[unit]
    if convention == "compass":
        angle = 0.5 * np.pi - angle
    order = np.argsort(t, kind="stable")
    t_sorted, yaw = t[order], np.unwrap(angle[order])
    keep = np.concatenate([[True], np.diff(t_sorted) > 0])
    heading = np.interp(pose.t, t_sorted[keep], yaw[keep])
    replaced = ", replacing the pose's orientation" if pose.heading is not None else ""
    notes.append(f"heading from {ref.written} ({unit}, {convention}) at the pose times{replaced}")
    field = Field(
        ref.written,
        "--heading",
        f"--heading-unit {unit}, --heading-convention {convention}",
        (("heading_unit", unit), ("heading_convention", convention)),
    )
    provenance = pose.provenance
    if provenance is not None:
        provenance = dataclasses.replace(provenance, fields={**provenance.fields, "heading": field})
    return dataclasses.replace(pose, heading=heading, provenance=provenance)


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
    speed_unit: str | None = None,
    circumference: float | None = None,
    ticks_per_revolution: float | None = None,
    heading: str | None = None,
    heading_unit: str | None = None,
    heading_convention: str | None = None,
    yaw_rate: str | None = None,
    yaw_rate_unit: str | None = None,
    lateral_acceleration: str | None = None,
    source: str | None = None,
) -> Recording:
    """Read the pose, rear-wheel and (optional) IMU streams of a ROS 1/ROS 2 bag or MCAP file.

    A wheel, the heading or an IMU signal may be any numeric field of any topic, named
    ``TOPIC:FIELD`` (``/vehicle/wheels:wheels[2].speed``: the field dotted into nested fields,
    with array indices) and read through the bag's own message definitions; a vendor
    wheel-speed message (:data:`VENDOR_WHEELS`) is recognised by its type.

    Args:
        path: a ``.bag`` file, a ``.mcap`` file or a ROS 2 bag directory.
        pose_topic: NavSatFix, Odometry, PoseStamped or PoseWithCovarianceStamped topic;
            ``None``: the only topic of one of these types.
        wheel_topic: JointState topic, a vendor wheel-speed topic, or a topic whose fields
            ``rear_left`` / ``rear_right`` name; ``None``: the only vendor wheel-speed topic,
            else the only JointState topic.
        imu_topic: Imu topic (or the topic of bare ``yaw_rate`` / ``lateral_acceleration``
            fields); ``None``: the only one, or no IMU stream if there is none.
        rear_left, rear_right: joint names of the rear wheels, or fields (``TOPIC:FIELD``,
            or a bare field of the other's topic or of ``wheel_topic``); ``None``: the two
            joints named ``*left*`` / ``*right*`` (preferring ``*rear*``), or a vendor
            message's rear wheels.
        wheel_kind: what the wheels hold. A JointState: ``"angle"`` (position [rad],
            cumulative) or ``"angular_speed"`` (velocity [rad/s]); ``None``: positions when
            every message carries them, else velocities. Fields: also ``"speed"`` (needs
            ``circumference`` and ``speed_unit``), ``"rpm"``, ``"ticks"`` (cumulative; needs
            ``ticks_per_revolution``), as ``[wheels] kind`` of a manifest; a vendor message:
            ``angular_speed`` by default.
        speed_unit: ``"m/s"`` (default), ``"km/h"`` or ``"mph"`` of ``kind = "speed"``.
        circumference: [m] the ECU's wheel circumference of ``kind = "speed"``.
        ticks_per_revolution: counts per wheel revolution of ``kind = "ticks"``.
        heading: ``TOPIC:FIELD`` of the heading (replaces the pose's; interpolated at the pose
            times); ``heading_unit`` ``"rad"`` (default) or ``"deg"``, ``heading_convention``
            ``"enu"`` (default, REP 103) or ``"compass"``.
        yaw_rate, lateral_acceleration: fields of the IMU signals (instead of an Imu topic);
            ``yaw_rate_unit`` ``"rad/s"`` (default) or ``"deg/s"``; lateral acceleration in
            m/s², positive to the left.
        source: name of the recording in messages (default: the path).

    Returns:
        The :class:`Recording`: time [s] from the header stamps (the bag's receive times for
        messages without a header), positions [m] (east/north of the first fix for
        NavSatFix), heading [rad, ENU], wheels [rev] or [rev/s], lateral acceleration [m/s²]
        and yaw rate [rad/s]; ``notes`` say what was picked or skipped.

    Raises:
        StreamError: a missing or unreadable bag, a topic, joint or field that is absent, of
            the wrong type, not a number, ambiguous or empty; the message is one line and
            names the option, topic, message type and field path, and lists what exists.
    """
    path = Path(path)
    source = source or str(path)
    request = BagRequest(
        pose_topic,
        wheel_topic,
        imu_topic,
        rear_left,
        rear_right,
        wheel_kind,
        speed_unit,
        circumference,
        ticks_per_revolution,
        heading,
        heading_unit,
        heading_convention,
        yaw_rate,
        yaw_rate_unit,
        lateral_acceleration,
    )
    _check_request(source, request)
    bag = _Bag(path, source)
    try:
        return _read(bag, request)
    finally:
        bag.close()


def _read(bag: _Bag, r: BagRequest) -> Recording:
    notes: list[str] = []
    _register_vendor_types(bag, notes)
    pose, pose_note = _pick_topic(bag, r.pose_topic, POSE_TYPES, "pose", "--pose-topic", True)
    fields = _wheel_fields(bag, r, notes)
    wheel = wheel_note = None
    if fields is None:
        if r.wheel_kind not in (None, "angle", "angular_speed"):
            raise StreamError(
                f"{bag.source}: --wheel-kind {r.wheel_kind}: a JointState gives angle (position) "
                "or angular_speed (velocity); the other kinds apply to fields (--rear-left "
                "TOPIC:FIELD)"
            )
        wheel, wheel_note = _pick_topic(
            bag, r.wheel_topic, (JOINT_STATE,), "wheel", "--wheel-topic", True
        )
    _wheel_conversion(f"{bag.source}:{fields.topic if fields else wheel}", fields, r)
    imu_refs = _imu_fields(bag, r)
    imu = imu_note = None
    if not imu_refs:
        imu, imu_note = _pick_topic(bag, r.imu_topic, (IMU,), "IMU", "--imu-topic", False)
    heading_ref = _heading_field(bag, r)
    notes[:0] = [note for note in (pose_note, wheel_note, imu_note) if note]
    assert pose is not None
    streams = [(pose, "pose", "--pose-topic")]
    if fields is not None:
        streams.append((fields.topic, "wheel", fields.left.flag or "--wheel-topic"))
    else:
        assert wheel is not None
        streams.append((wheel, "wheel", "--wheel-topic"))
    if imu is not None:
        streams.append((imu, "IMU", "--imu-topic"))
    if imu_refs:
        streams.append((imu_refs[0].topic, "IMU", imu_refs[0].flag or "--imu-topic"))
    if heading_ref is not None:
        streams.append((heading_ref.topic, "heading", "--heading"))
    for topic, role, flag in streams:
        if any(bag.counts.values()) and bag.counts.get(topic, 0) == 0:  # counts are known
            raise _no_messages(bag, topic, role, flag)

    consumers: dict[str, list[_Topic]] = {}

    def consume(topic: str, rows: _Topic) -> _Topic:
        consumers.setdefault(topic, []).append(rows)
        return rows

    pose_rows = consume(pose, _Topic(_EXTRACT[bag.topics[pose]]))
    rows_of = [pose_rows]
    if fields is not None:
        wheel_rows = consume(
            fields.topic, _field_rows(bag, bag.topics[fields.topic], [fields.left, fields.right])
        )
    else:
        assert wheel is not None
        joints = _resolve_joints(bag, wheel, r.rear_left, r.rear_right, notes)
        joint_extract, seen = _joint_extractor(*joints)
        wheel_rows = consume(wheel, bag.raw_topic(joint_extract, JOINT_STATE, joints))
    rows_of.append(wheel_rows)
    imu_rows = heading_rows = None
    if imu is not None:
        imu_rows = consume(imu, bag.raw_topic(_imu, IMU))
    elif imu_refs:
        imu_rows = consume(
            imu_refs[0].topic, _field_rows(bag, bag.topics[imu_refs[0].topic], imu_refs)
        )
    if imu_rows is not None:
        rows_of.append(imu_rows)
    if heading_ref is not None:
        heading_rows = consume(
            heading_ref.topic, _field_rows(bag, bag.topics[heading_ref.topic], [heading_ref])
        )
        rows_of.append(heading_rows)
    with bag.guard():
        for topic, timestamp, raw, msgtype in bag.raw_messages(consumers):
            for rows in consumers[topic]:
                if rows.decode is not None:
                    rows.add_raw(timestamp, raw)
                else:
                    rows.add(timestamp, bag.reader.deserialize(raw, msgtype))
        for rows in rows_of:
            rows.flush()
    for (topic, role, flag), rows in zip(streams, rows_of, strict=True):
        if not len(rows) and not rows.skipped:
            raise _no_messages(bag, topic, role, flag)

    pose_stream = _pose_stream(bag, pose, pose_rows, notes)
    if fields is not None:
        wheels = _field_wheel_stream(bag, fields, wheel_rows, r, notes)
    else:
        assert wheel is not None
        wheels = _wheel_stream(bag, wheel, wheel_rows, joints, seen, r.wheel_kind, notes)
    imu_stream = None
    if imu is not None:
        assert imu_rows is not None
        imu_stream = _imu_stream(bag, imu, imu_rows, notes)
    elif imu_refs:
        assert imu_rows is not None
        imu_stream = _field_imu_stream(bag, imu_refs, imu_rows, r, notes)
    if heading_ref is not None:
        assert heading_rows is not None
        pose_stream = _field_heading(bag, heading_ref, heading_rows, pose_stream, r, notes)
    elif pose_stream.heading is None and imu is not None and imu_stream is not None:
        assert imu_rows is not None
        pose_stream = _imu_heading(imu_rows, imu_stream, pose_stream, notes)
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
