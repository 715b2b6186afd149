"""The frames of a CAN log as numpy arrays (:class:`Frames`), and a frame's id and format as
one integer key (:func:`frame_key`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The flag of an extended (29-bit) frame id in a frame's key (:func:`frame_key`).
EXTENDED_FLAG = 1 << 31


def frame_key(frame_id: int, extended: bool) -> int:
    """A frame's id and format as one integer: ``id | EXTENDED_FLAG`` for a 29-bit id."""
    return int(frame_id) | (EXTENDED_FLAG if extended else 0)


def id_text(key: int) -> str:
    """``0x0AA`` (11-bit) or ``0x18FEF100 (extended)`` for a frame key."""
    if key & EXTENDED_FLAG:
        return f"0x{key & 0x1FFFFFFF:08X} (extended)"
    return f"0x{key:03X}"


@dataclass
class Frames:
    """The frames of the wanted ids of a CAN log, in the log's order.

    Attributes:
        t: timestamp [s] of each frame, ``(n,)``.
        key: :func:`frame_key` of each frame, ``(n,)`` uint32.
        channel: index into :attr:`channels` of each frame's bus, ``(n,)``.
        length: payload bytes of each frame (its DLC in bytes), ``(n,)``.
        data: payloads, zero-padded, ``(n, width)`` uint8.
        number: each frame's place in the log (1-based): its line in a candump log, else the
            frame's number among the log's frames.
        channels: the buses as the log names them (``"can0"``; ASC/BLF: ``"1"``, ``"2"``).
        counts: frames per key of the whole log (all ids, all buses).
        total: frames in the log.
        unit: ``"line"`` (candump) or ``"frame"``.
        malformed: lines that are not frames (candump), and the first one's number.
        path: the log.
    """

    t: np.ndarray
    key: np.ndarray
    channel: np.ndarray
    length: np.ndarray
    data: np.ndarray
    number: np.ndarray
    channels: tuple[str, ...]
    counts: Counter
    total: int
    unit: str
    path: Path
    malformed: tuple[int, int | None] = (0, None)

    def take(self, keep: np.ndarray) -> Frames:
        """The frames ``keep`` (indices or mask)."""
        return Frames(
            self.t[keep],
            self.key[keep],
            self.channel[keep],
            self.length[keep],
            self.data[keep],
            self.number[keep],
            self.channels,
            self.counts,
            self.total,
            self.unit,
            self.path,
            self.malformed,
        )


def reason(exc: BaseException) -> str:
    """An exception's message on one line."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text
