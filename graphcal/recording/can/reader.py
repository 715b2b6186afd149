"""The frames of the wanted ids of a CAN log, whatever its format: a candump log with numpy
(:mod:`graphcal.recording.can.candump`), every other format python-can reads (Vector ``.asc`` and
``.blf``, python-can's ``.csv``, ``.trc``) through ``can.LogReader``, one frame at a time,
keeping only the wanted ids.

**Time** is each frame's timestamp in the log [s] (candump: the text's value, correctly
rounded; ASC: the header's date, read in the local time zone as python-can reads it, plus
the frame's offset; BLF: the file's start plus the frame's offset).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.recording.can.candump import read_candump
from graphcal.recording.can.frames import EXTENDED_FLAG, Frames, reason
from graphcal.recording.streams import StreamError


def is_candump(path: Path) -> bool:
    """A candump text log: ``.log`` (or ``.log.gz``)."""
    suffixes = [s.lower() for s in path.suffixes[-2:]]
    return suffixes[-1:] == [".log"] or suffixes == [".log", ".gz"]


def read_frames(path: Path, wanted: set[int]) -> Frames:
    """The frames of the keys ``wanted`` (:func:`frame_key`) of a CAN log, with every id's
    frame count; a candump log with numpy, any other format with python-can."""
    if is_candump(path):
        return read_candump(path, wanted)
    return _read_python_can(path, wanted)


def _read_python_can(path: Path, wanted: set[int]) -> Frames:
    """The wanted frames of a log python-can reads (ASC, BLF, CSV, TRC), one at a time."""
    import can

    try:
        if path.suffix.lower() == ".asc":  # absolute times: the header's date + the offsets
            reader = can.ASCReader(str(path), relative_timestamp=False)
        else:
            reader = can.LogReader(str(path))
    except ValueError as exc:
        raise StreamError(
            f"{path}: not a CAN log format python-can reads ({exc}); graphcal reads candump "
            "-l logs (.log), Vector .asc and .blf, and python-can's .csv"
        ) from None
    except Exception as exc:
        raise StreamError(f"{path}: cannot read as a CAN log ({reason(exc)})") from None
    counts: Counter = Counter()
    rows: list[tuple[float, int, Any, int, bytes]] = []
    number = 0
    one_based = path.suffix.lower() in (".asc", ".blf")  # python-can counts their buses from 0
    try:
        with reader:
            for number, message in enumerate(reader, start=1):
                if message.is_error_frame:
                    continue
                key = message.arbitration_id | (EXTENDED_FLAG if message.is_extended_id else 0)
                counts[key] += 1
                if key in wanted and not message.is_remote_frame:
                    rows.append(
                        (message.timestamp, key, message.channel, number, bytes(message.data))
                    )
    except Exception as exc:
        where = f" after frame {number}" if number else ""
        raise StreamError(f"{path}: cannot read as a CAN log{where} ({reason(exc)})") from None
    n = len(rows)
    width = max(8, max((len(r[4]) for r in rows), default=0))
    data = np.zeros((n, width), dtype=np.uint8)
    length = np.zeros(n, dtype=np.int64)
    for i, row in enumerate(rows):
        payload = row[4]
        data[i, : len(payload)] = np.frombuffer(payload, dtype=np.uint8)
        length[i] = len(payload)

    def bus_name(channel: Any) -> str:
        if channel is None:
            return ""
        if isinstance(channel, int) and one_based:
            return str(channel + 1)
        return str(channel)

    names = [bus_name(r[2]) for r in rows]
    channels, channel = np.unique(np.array(names, dtype=object).astype(str), return_inverse=True)
    return Frames(
        t=np.array([r[0] for r in rows], dtype=np.float64),
        key=np.array([r[1] for r in rows], dtype=np.uint32),
        channel=channel.ravel(),
        length=length,
        data=data,
        number=np.array([r[3] for r in rows], dtype=np.int64),
        channels=tuple(str(c) for c in channels),
        counts=counts,
        total=sum(counts.values()),
        unit="frame",
        path=path,
    )
