"""A DBC read with cantools (``strict=False``: real DBCs overlap signals or name things twice),
and its messages and signals found by the names or frame ids a manifest gives, each miss one
line listing a few of the DBC's names (those like the one given first).
"""

from __future__ import annotations

import difflib
import re
from pathlib import Path
from typing import Any

from graphcal.recording.can.frames import reason
from graphcal.recording.streams import StreamError

#: How many names an error lists (messages of a DBC, signals, ids of a log).
LISTED = 8


def load_dbc(path: Path, where: str, manifest_source: str, cache: dict | None = None):
    """A DBC read with cantools (``strict=False``); one line with cantools' reason if it does
    not parse."""
    if cache is not None and path in cache:
        return cache[path]
    import cantools

    try:
        database = cantools.database.load_file(str(path), strict=False)
    except Exception as exc:
        why = reason(exc)
        dbc = re.search(r'DBC: "(.*)"$', why)
        if dbc:
            why = dbc.group(1)
        raise StreamError(
            f"{path}: not a DBC cantools reads ({why}) (named in {manifest_source} {where}); "
            "fix the file or name another"
        ) from None
    if not isinstance(database, cantools.database.can.Database):
        raise StreamError(
            f"{path}: not a CAN database (named in {manifest_source} {where}); give a DBC"
        )
    if cache is not None:
        cache[path] = database
    return database


def listing(names: list[str], wanted: str | None = None) -> str:
    """A few of ``names``, those like ``wanted`` first: ``A, B, C, … (40 in all)``."""
    close = difflib.get_close_matches(wanted, names, n=3, cutoff=0.5) if wanted else []
    shown = close + [n for n in names if n not in close]
    text = ", ".join(shown[:LISTED])
    return text + (f", … ({len(names)} in all)" if len(names) > LISTED else "")


def parse_message_spec(value: Any) -> int | str | None:
    """A ``message`` key: a frame id (an integer, or text ``0xAA`` / ``170``) or a name."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int):
        return value if value >= 0 else None
    if not isinstance(value, str) or not value.strip():
        return None
    text = value.strip()
    if re.fullmatch(r"0[xX][0-9a-fA-F]+", text):
        return int(text, 16)
    if text.isdigit():
        return int(text)
    return text


def find_message(database, spec: int | str, dbc: Path, key: str, named_in: str = ""):
    """The DBC's message named (or with the frame id) ``spec``; one line listing a few of the
    DBC's messages if it has none (``key``: the manifest key that named it, in the manifest
    ``named_in``)."""
    where = f"{key} in {named_in}" if named_in else key
    messages = list(database.messages)
    names = [m.name for m in messages]
    if isinstance(spec, int):
        found = [m for m in messages if m.frame_id == spec]
        if found:
            return found[0]
        listed = listing([f"{m.name} (0x{m.frame_id:X})" for m in messages])
        raise StreamError(
            f"{dbc}: no message with frame id 0x{spec:X} ({spec}) ({where}); the DBC has "
            f"{listed or 'no messages'}; check {key} and dbc"
        )
    for message in messages:
        if message.name == spec:
            return message
    folded = [m for m in messages if m.name.lower() == spec.lower()]
    hint = f" (did you mean {folded[0].name}?)" if folded else ""
    raise StreamError(
        f"{dbc}: no message {spec!r}{hint} ({where}); the DBC has "
        f"{listing(names, spec) or 'no messages'}; check {key} and dbc"
    )


def find_signal(message, name: Any, dbc: Path, where: str):
    """The message's signal ``name``; one line listing the message's signals if it has
    none."""
    if not isinstance(name, str) or not name:
        raise StreamError(f"{where} must be a signal name (text) of {message.name}, got {name!r}")
    for signal in message.signals:
        if signal.name == name:
            return signal
    names = [s.name for s in message.signals]
    raise StreamError(
        f"{dbc}: message {message.name} has no signal {name!r} ({where}); its signals: "
        f"{listing(names, name) or 'none'}"
    )
