"""Reading ROS 1 bags, ROS 2 bags (sqlite3 or mcap storage) and bare MCAP files with ``rosbags``.

``rosbags`` is pure Python (no ROS installation); it is the optional extra ``graphcal[ros]``
and is imported only inside the functions of this module, the only one that imports it.
A :class:`BagReader` opens a bag, says what it holds (:meth:`BagReader.contents`), turns
rosbags' exceptions into one-line :class:`StreamError` and yields its messages: every topic
in one pass, each message deserialized once or its numbers gathered from the raw bytes of a
topic of one layout (:mod:`graphcal.recording.bag.layout`).
"""

from __future__ import annotations

import sqlite3
import struct
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.errors import exception_reason, first_line
from graphcal.recording.bag.fields import FieldRef
from graphcal.recording.bag.layout import NAME, decode_fields, decode_fixed
from graphcal.recording.bag.rows import TopicRows
from graphcal.recording.bag.topics import HEADER, BagContents
from graphcal.recording.bag.vendors import VENDOR_DEFINITIONS
from graphcal.recording.streams import StreamError

#: Files of a ROS 2 bag's storage (also readable on their own).
STORAGE_SUFFIXES = (".db3", ".mcap")
#: JointState messages looked at to find the rear wheel joints when they are not named.
JOINT_SCAN_MESSAGES = 200
#: Decode Imu, JointState and field messages of one layout with numpy (False: one by one,
#: rosbags).
FAST_DECODING = True

_MISSING_ROSBAGS = 'reading ROS bags needs the rosbags package: pip install -e ".[ros]"'
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


class BagReader:
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
            text = exception_reason(error)
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

    def contents(self) -> BagContents:
        """What the bag holds: its topics, their message counts and its message definitions."""
        return BagContents(self.source, self.topics, self.counts, self.reader.typestore.fielddefs)

    def register_vendor_types(self, notes: list[str]) -> None:
        """Register the known vendor definitions the bag does not carry (older ROS 2 bags)."""
        from rosbags.typesys import get_types_from_msg

        store = self.reader.typestore
        for msgtype in sorted(set(self.topics.values()) & set(VENDOR_DEFINITIONS)):
            if msgtype not in store.fielddefs:
                with self.guard():
                    store.register(get_types_from_msg(VENDOR_DEFINITIONS[msgtype], msgtype))
                notes.append(
                    f"{self.source}: the bag carries no definition of {msgtype}; read with the "
                    "vendor's published one"
                )

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
    ) -> TopicRows:
        """A :class:`TopicRows` of a high-rate message type, decoded from raw bytes in chunks."""

        def decode(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
            return decode_fixed(raws, msgtype, self.ros1, joints) if FAST_DECODING else None

        def deserialize(raw: bytes) -> Any:
            return self.reader.deserialize(raw, msgtype)

        return TopicRows(extract, decode, deserialize)

    def field_topic(self, msgtype: str, refs: list[FieldRef]) -> TopicRows:
        """A :class:`TopicRows` of the numbers at ``refs`` (one topic of type ``msgtype``):
        decoded from raw bytes in chunks when the messages share a layout, else one by one."""
        fielddefs = self.reader.typestore.fielddefs
        first = fielddefs[msgtype][1][:1]
        stamped = bool(first) and first[0][0] == "header" and first[0][1] == (NAME, HEADER)
        paths = [ref.steps for ref in refs]

        def decode(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
            if not FAST_DECODING:
                return None
            return decode_fields(raws, msgtype, fielddefs, paths, self.ros1, stamped)

        def extract(msg: Any) -> tuple | None:
            values = tuple(ref.get(msg) for ref in refs)
            return None if None in values else values

        def deserialize(raw: bytes) -> Any:
            return self.reader.deserialize(raw, msgtype)

        return TopicRows(extract, decode, deserialize, stamped=stamped)

    def messages(self, topics: Iterable[str]) -> Iterable[tuple[str, int, Any]]:
        """``(topic, receive time [ns], message)`` of every message on ``topics``, in one pass."""
        wanted = set(topics)
        connections = [c for c in self.reader.connections if c.topic in wanted]
        deserialize = self.reader.deserialize
        for connection, timestamp, raw in self.reader.messages(connections=connections):
            yield connection.topic, timestamp, deserialize(raw, connection.msgtype)

    def joint_names(self, topic: str) -> list[str]:
        """Every joint name in the first :data:`JOINT_SCAN_MESSAGES` messages of ``topic``."""
        names: set[str] = set()
        with self.guard():
            for count, (_, _, msg) in enumerate(self.messages([topic]), start=1):
                names.update(msg.name)
                if count >= JOINT_SCAN_MESSAGES:
                    break
        return sorted(names)


def bag_topics(path: str | Path) -> dict[str, str]:
    """Topics of a bag and their message types, e.g. ``{"/fix": "sensor_msgs/msg/NavSatFix"}``.

    Raises:
        StreamError: ``path`` missing, not a bag, or unreadable.
    """
    path = Path(path)
    bag = BagReader(path, str(path))
    try:
        return dict(sorted(bag.topics.items()))
    finally:
        bag.close()
