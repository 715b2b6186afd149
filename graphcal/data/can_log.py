"""Wheel and IMU streams from a raw CAN log decoded with a DBC (the manifest keys ``can``,
``dbc``, ``message``, ``bus`` of ``[wheels]`` and ``[imu]``; issue 28).

The log's frames are read once for all its sections (:mod:`graphcal.data.can_reader`), the
DBC with cantools (:mod:`graphcal.data.can_dbc`), each section's signals decoded vectorized
(:mod:`graphcal.data.can_decode`) into its stream (:mod:`graphcal.data.can_streams`). A frame
that does not decode is counted and reported in a note, not fatal.

Errors name the manifest key, the file, the message and the signal the user wrote, and how to
fix them (one line, :class:`~graphcal.data.streams.StreamError`).
"""

from __future__ import annotations

import weakref
from pathlib import Path
from typing import TYPE_CHECKING, Any

from graphcal.data.can_reader import read_frames
from graphcal.data.can_source import CAN_KEYS, can_source
from graphcal.data.can_streams import imu_stream, wheel_stream
from graphcal.data.imu_mounting import MOUNTED_KEYS  # a 3-axis IMU's keys, not read from CAN
from graphcal.data.streams import ImuStream, StreamError, WheelStream

if TYPE_CHECKING:
    from graphcal.data.manifest import Manifest


def _need_packages(what: str) -> None:
    """One line if cantools or python-can is missing."""
    import importlib.util

    missing = [name for name in ("cantools", "can") if importlib.util.find_spec(name) is None]
    if missing:
        names = " and ".join("python-can" if n == "can" else n for n in missing)
        raise StreamError(f'{what} needs {names}: pip install -e ".[can]" (the can extra)')


def reads_can(manifest: Manifest, section: str) -> bool:
    """Whether ``[section]`` (``"wheels"`` or ``"imu"``) is read from a CAN log: it has any
    of ``can``, ``dbc``, ``message``, ``bus``; or, for ``[imu]``, ``[wheels]`` is read from
    one and ``[imu]`` names no file of its own (nor a mounted IMU's keys)."""
    table = manifest.wheels if section == "wheels" else manifest.imu
    if table is None:
        return False
    if any(key in table for key in CAN_KEYS):
        return True
    if section == "imu" and reads_can(manifest, "wheels"):
        return not any(key in table for key in ("file", "topic", *MOUNTED_KEYS))
    return False


def can_sections(manifest: Manifest) -> list[str]:
    """The sections of a manifest read from a CAN log (:func:`reads_can`)."""
    return [name for name in ("wheels", "imu") if reads_can(manifest, name)]


#: Streams read with another section's (one log read once), by manifest, until asked for.
_PENDING: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def read_can_section(manifest: Manifest, section: str, notes: list[str]) -> WheelStream | ImuStream:
    """The stream of ``[section]`` (``"wheels"`` or ``"imu"``) from its CAN log; the first call
    reads every CAN section of the manifest (each log once) and keeps the others' streams for
    their calls."""
    pending = _PENDING.get(manifest)
    if not pending or section not in pending:
        pending = read_can_sections(manifest, notes)
        _PENDING[manifest] = pending
    return pending.pop(section)


def read_can_sections(manifest: Manifest, notes: list[str]) -> dict[str, WheelStream | ImuStream]:
    """The ``[wheels]`` and ``[imu]`` streams of a manifest that come from CAN logs (empty
    if none does); each log is read once for the messages of all its sections."""
    sections = can_sections(manifest)
    if not sections:
        return {}
    _need_packages(f"{manifest.source}: [{sections[0]}] can (a CAN log)")
    databases: dict[Path, Any] = {}
    sources = [can_source(manifest, name, databases) for name in sections]
    streams: dict[str, WheelStream | ImuStream] = {}
    for log in dict.fromkeys(s.log for s in sources):
        users = [s for s in sources if s.log == log]
        frames = read_frames(log, {s.key for s in users})
        bad, first_bad = frames.malformed
        if frames.total == 0:
            raise StreamError(
                f"{log}: no CAN frames in it (named in {manifest.source} {users[0].log_key}); "
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
                streams["wheels"] = wheel_stream(manifest, source, frames, notes)
            else:
                streams["imu"] = imu_stream(manifest, source, frames, notes)
    return streams
