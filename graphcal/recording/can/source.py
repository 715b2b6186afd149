"""A manifest section read from a CAN log (:class:`CanSource`): its keys checked, its log and
DBC found, its message and signals looked up in the DBC. ``[imu]`` without a ``can`` of its
own reads the wheels' log and DBC (and their ``bus`` and ``time_offset``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from graphcal.recording.can.dbc import (
    find_message,
    find_signal,
    listing,
    load_dbc,
    parse_message_spec,
)
from graphcal.recording.can.frames import frame_key, id_text
from graphcal.recording.section import Section
from graphcal.recording.streams import StreamError
from graphcal.recording.vocabulary import MOUNTED_KEYS

#: Manifest keys of a section read from a CAN log.
CAN_KEYS = ("can", "dbc", "message", "bus")
#: Keys of a CSV section that a CAN log's section does not use (its frames carry the time).
CSV_ONLY_KEYS = ("file", "topic", "time", "time_unit")


@dataclass
class CanSource:
    """One manifest section read from a CAN log: its files, message and signals.

    Attributes:
        section: ``"wheels"`` or ``"imu"``.
        table: the section's keys.
        log, dbc: the files; ``log_key``, ``dbc_key`` the keys that named them
            (``"[wheels] can"``; ``"[wheels] can, as [imu] has none"`` when inherited).
        message: the cantools message.
        signals: by role (``rear_left``, ``yaw_rate``), the cantools signal.
        bus: the bus filter as written, or ``None``; ``bus_key`` the key that gave it.
        inherits: ``[wheels]``' keys when ``[imu]`` reads the wheels' log (no ``can`` of its
            own): its ``bus`` and ``time_offset`` apply unless ``[imu]`` gives them.
    """

    section: str
    table: Section
    log: Path
    log_key: str
    dbc: Path
    dbc_key: str
    database: Any
    message: Any
    signals: dict[str, Any]
    bus: int | str | None
    bus_key: str
    inherits: Section | None = None

    @property
    def key(self) -> int:
        """The message's :func:`frame_key`."""
        return frame_key(self.message.frame_id, self.message.is_extended_frame)

    def message_text(self) -> str:
        """``message WHEEL_SPEEDS (0x0AA) of car.dbc``."""
        return f"message {self.message.name} ({id_text(self.key)}) of {self.dbc}"

    def field_name(self, role: str) -> str:
        """A signal as the messages name it: ``WHEEL_SPEEDS.WHEEL_SPEED_RL``."""
        return f"{self.message.name}.{self.signals[role].name}"


def _path_key(table: Section, key: str, fallback: Section | None, what: str) -> tuple[Path, str]:
    """The file a key names (``can``, ``dbc``), the key that named it, checked present."""
    section = table.name
    value, where = table.get(key), f"[{section}] {key}"
    if value is None and fallback is not None and key in fallback:
        value, where = fallback[key], f"[wheels] {key}, as [{section}] has none"
    if value is None:
        raise table.error(
            f"[{section}] needs {key} ({what}, relative to the manifest)"
            + (" or [wheels] can and dbc to share" if section == "imu" else "")
        )
    if not isinstance(value, str) or not value:
        raise table.error(f"{where} must be a path (text), got {value!r}")
    path = table.resolve(value)
    if not path.is_file():
        raise StreamError(f"{path}: no such file (named in {table.source} {where}); check the path")
    return path, where


def can_source(table: Section, wheels: Section, databases: dict) -> CanSource:
    """Check one section's CAN keys (``[wheels]`` or ``[imu]``; ``[imu]`` may share the
    ``wheels`` section's log) and find its message and signals in the DBC."""
    section = table.name
    fallback = wheels if section == "imu" and "can" in wheels else None
    _check_unused_keys(table)
    log, log_key = _path_key(table, "can", fallback, "the CAN log")
    dbc, dbc_key = _path_key(table, "dbc", fallback, "the DBC that decodes it")
    database = load_dbc(dbc, dbc_key, table.source, databases)
    if "message" not in table:
        raise table.error(
            f"[{section}] needs message (the DBC message's name or frame id, e.g. 0xAA) with "
            f"can; {dbc} has {listing([m.name for m in database.messages])}"
        )
    spec = parse_message_spec(table["message"])
    if spec is None:
        raise table.error(
            f"[{section}] message must be a message name or frame id (0xAA, 170), got "
            f"{table['message']!r}"
        )
    message = find_message(database, spec, dbc, f"[{section}] message", table.source)
    signals = _signals(table, message, dbc)
    inherits = fallback if fallback is not None and "can" not in table else None
    bus, bus_key = table.get("bus"), f"[{section}] bus"
    if bus is None and inherits is not None:
        bus, bus_key = inherits.get("bus"), f"[wheels] bus, as [{section}] has none"
    if bus is not None and (isinstance(bus, bool) or not isinstance(bus, int | str)):
        raise table.error(f"[{section}] bus must be a channel name or number, got {bus!r}")
    return CanSource(
        section,
        table,
        log,
        log_key,
        dbc,
        dbc_key,
        database,
        message,
        signals,
        bus,
        bus_key,
        inherits,
    )


def _check_unused_keys(table: Section) -> None:
    """One line for a key of another source (a CSV file or bag topic, a mounted IMU's
    columns, a CSV's time) in a section read from a CAN log."""
    section = table.name
    both = [k for k in ("file", "topic") if k in table]
    if both:
        raise table.error(
            f"[{section}] {both[0]} and can/message: name one source for the stream (a CSV "
            "file or a CAN log)"
        )
    mounted = [k for k in MOUNTED_KEYS if k in table]
    if mounted:
        raise table.error(
            f"[{section}] {', '.join(mounted)}: not read from a CAN log; name the vehicle "
            "frame's lateral_acceleration and yaw_rate signals"
        )
    unused = [k for k in CSV_ONLY_KEYS if k in table]
    if unused:
        raise table.error(
            f"[{section}] {', '.join(unused)}: not used with a CAN log, whose frames carry "
            "their time in seconds (use time_offset)"
        )


def _signals(table: Section, message: Any, dbc: Path) -> dict[str, Any]:
    """The section's signals of ``message`` by role (``rear_left``, ``yaw_rate``), checked:
    both wheels, two different signals; for ``[imu]`` at least one."""
    section = table.name
    roles = (
        ("rear_left", "rear_right")
        if section == "wheels"
        else (
            "lateral_acceleration",
            "yaw_rate",
        )
    )
    signals = {}
    for role in roles:
        if role not in table:
            continue
        signals[role] = find_signal(
            message, table[role], dbc, f"[{section}] {role} in {table.source}"
        )
    if section == "wheels":
        for role in roles:
            if role not in signals:
                raise table.error(
                    f"[wheels] needs {role} (a signal of {message.name}: "
                    f"{listing([s.name for s in message.signals])})"
                )
        if signals["rear_left"].name == signals["rear_right"].name:
            raise table.error(
                f"[wheels] rear_left and rear_right are both {signals['rear_left'].name!r}; "
                "name the two wheels' signals"
            )
    elif not signals:
        raise table.error(
            f"[imu] needs lateral_acceleration or yaw_rate (a signal of {message.name}: "
            f"{listing([s.name for s in message.signals])})"
        )
    return signals
