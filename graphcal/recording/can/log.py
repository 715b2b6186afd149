"""Wheel and IMU streams from a raw CAN log decoded with a DBC (the manifest keys ``can``,
``dbc``, ``message``, ``bus`` of ``[wheels]`` and ``[imu]``; issue 28).

The log's frames are read once for all its sections (:mod:`.reader`), the DBC with cantools
(:mod:`.dbc`), each section's signals decoded vectorized (:mod:`.decode`) into its stream
(:mod:`.streams`). A frame that does not decode is counted and reported in a note, not fatal.

Errors name the manifest key, the file, the message and the signal the user wrote, and how to
fix them (one line, :class:`~graphcal.recording.streams.StreamError`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from graphcal.recording.can.reader import read_frames
from graphcal.recording.can.source import CAN_KEYS, can_source
from graphcal.recording.can.streams import imu_stream, wheel_stream
from graphcal.recording.section import Section
from graphcal.recording.streams import ImuStream, StreamError, WheelStream
from graphcal.recording.vocabulary import MOUNTED_KEYS


def _need_packages(what: str) -> None:
    """One line if cantools or python-can is missing."""
    import importlib.util

    missing = [name for name in ("cantools", "can") if importlib.util.find_spec(name) is None]
    if missing:
        names = " and ".join("python-can" if n == "can" else n for n in missing)
        raise StreamError(f'{what} needs {names}: pip install -e ".[can]" (the can extra)')


def reads_can(table: Section | None, wheels: Section) -> bool:
    """Whether a section (``[wheels]`` or ``[imu]``; ``None``: absent) is read from a CAN log:
    it has any of ``can``, ``dbc``, ``message``, ``bus``; or, for ``[imu]``, ``wheels`` is read
    from one and ``[imu]`` names no file of its own (nor a mounted IMU's keys)."""
    if table is None:
        return False
    if table.has_any(CAN_KEYS):
        return True
    if table.name == "imu" and reads_can(wheels, wheels):
        return not table.has_any(("file", "topic", *MOUNTED_KEYS))
    return False


def read_can_sections(
    wheels: Section, imu: Section | None, notes: list[str]
) -> dict[str, WheelStream | ImuStream]:
    """The ``wheels`` and ``imu`` streams that come from CAN logs (:func:`reads_can`; empty
    if none does), by section name; each log is read once for the messages of all its
    sections."""
    sections = [table for table in (wheels, imu) if reads_can(table, wheels)]
    if not sections:
        return {}
    _need_packages(f"{wheels.source}: [{sections[0].name}] can (a CAN log)")
    databases: dict[Path, Any] = {}
    sources = [can_source(table, wheels, databases) for table in sections]
    streams: dict[str, WheelStream | ImuStream] = {}
    for log in dict.fromkeys(s.log for s in sources):
        users = [s for s in sources if s.log == log]
        frames = read_frames(log, {s.key for s in users})
        bad, first_bad = frames.malformed
        if frames.total == 0:
            raise StreamError(
                f"{log}: no CAN frames in it (named in {wheels.source} {users[0].log_key}); "
                "a candump log has lines like '(1763856000.000000) can0 0AA#1122334455667788', "
                "else give a Vector .asc or .blf or python-can's .csv"
            )
        if bad:
            notes.append(
                f"{log}: {bad} line(s) are not CAN frames and were skipped (first: line "
                f"{first_bad})"
            )
        for source in users:
            if source.section == "wheels":
                streams["wheels"] = wheel_stream(source, frames, notes)
            else:
                streams["imu"] = imu_stream(source, frames, notes)
    return streams
