"""The wanted frames of a candump log (``candump -l`` or ``-L`` text, ``.log`` or ``.log.gz``),
parsed with numpy in blocks of :data:`BLOCK_BYTES`: each line's frame id is read for all lines
at once, and only the lines of the wanted ids are parsed further (time, channel, payload) — a
3-hour log of a car (21.6 M frames) is read in seconds without holding it in memory. The time
is the text's value, correctly rounded [s].
"""

from __future__ import annotations

import gzip
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.recording.can.frames import EXTENDED_FLAG, Frames
from graphcal.recording.streams import StreamError

#: Bytes of a candump log parsed at once (a block ends at a line end).
BLOCK_BYTES = 1 << 24
#: candump's flag of an error frame in an 8-digit id (not a frame of any message).
CAN_ERR_FLAG = 0x20000000

_HEX = np.full(256, 255, dtype=np.uint8)
for _value, _char in enumerate(b"0123456789ABCDEF"):
    _HEX[_char] = _value
for _value, _char in enumerate(b"abcdef"):
    _HEX[_char] = 10 + _value


@dataclass
class _Block:
    """The wanted frames of one block of a candump log."""

    t: np.ndarray
    key: np.ndarray
    channel_text: np.ndarray
    length: np.ndarray
    data: np.ndarray
    number: np.ndarray


def _gather_text(buf: np.ndarray, start: np.ndarray, stop: np.ndarray, width: int) -> np.ndarray:
    """The bytes ``buf[start:stop]`` of each row as a fixed-width bytes array (``S{width}``)."""
    index = start[:, None] + np.arange(width)[None, :]
    inside = index < stop[:, None]
    chars = np.where(inside, buf[np.minimum(index, len(buf) - 1)], 0).astype(np.uint8)
    return np.ascontiguousarray(chars).view(f"S{width}").ravel()


def _parse_candump_block(
    block: bytes, first_line: int, wanted: np.ndarray, counts: Counter, std_counts: np.ndarray
) -> tuple[_Block, int, int, int | None]:
    """Parse one block of whole candump lines. Returns the wanted frames, the block's lines,
    its malformed lines and the first one's line number (1-based in the log); counts every
    frame's key into ``counts`` (extended) and ``std_counts`` (11-bit ids)."""
    buf = np.frombuffer(block, dtype=np.uint8)
    ends = np.flatnonzero(buf == 10)
    starts = np.empty_like(ends)
    starts[:1] = 0
    starts[1:] = ends[:-1] + 1
    stop = ends - (buf[np.maximum(ends - 1, 0)] == 13)  # without a trailing '\r'
    blank = stop <= starts
    hashes = np.flatnonzero(buf == 35)  # '#'
    spaces = np.flatnonzero(buf == 32)
    if len(hashes) == 0 or len(spaces) == 0:
        bad = np.flatnonzero(~blank)
        return _empty_block(), len(ends), len(bad), _first(bad, first_line)
    ok, h, before, keys, extended, frames = _frame_keys(buf, starts, stop, blank, hashes, spaces)
    _count_keys(keys, frames, extended, counts, std_counts)
    bad = np.flatnonzero(~ok & ~blank)
    chosen = np.flatnonzero(frames & np.isin(keys, wanted))
    if not len(chosen):
        return _empty_block(), len(ends), len(bad), _first(bad, first_line)
    t, channel_text, length, data, good, remote = _wanted_lines(
        buf, spaces, starts[chosen], stop[chosen], h[chosen], before[chosen]
    )
    lost = np.flatnonzero(~good & ~remote)
    if len(lost):  # frames of a wanted id whose line does not parse: malformed lines
        bad = np.union1d(bad, chosen[lost])
    chosen_good = np.flatnonzero(good)
    block_frames = _Block(
        t=t[chosen_good],
        key=keys[chosen][chosen_good],
        channel_text=channel_text[chosen_good],
        length=length[chosen_good],
        data=data[chosen_good],
        number=first_line + chosen[chosen_good],
    )
    return block_frames, len(ends), len(bad), _first(bad, first_line)


def _frame_keys(
    buf: np.ndarray,
    starts: np.ndarray,
    stop: np.ndarray,
    blank: np.ndarray,
    hashes: np.ndarray,
    spaces: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each line's frame id, read between the space before it and the ``#`` after it: which
    lines look like frames (``(time) channel id#...``), where their ``#`` and the space
    before the id are, each one's :func:`~graphcal.recording.can.frames.frame_key`, which ids
    are extended, and which lines are frames of a message (not error frames)."""
    k = np.searchsorted(hashes, starts)
    h = hashes[np.minimum(k, len(hashes) - 1)]
    ok = ~blank & (k < len(hashes)) & (h < stop) & (buf[starts] == 40)  # '(' ... '#'
    j = np.searchsorted(spaces, h) - 1
    before = spaces[np.maximum(j, 0)]  # the space before the id
    ok &= (j >= 0) & (before > starts)
    id_len = h - before - 1
    ok &= (id_len >= 1) & (id_len <= 8)
    ids = np.zeros(len(starts), dtype=np.uint32)
    for digit_place in range(8):
        position = h - 1 - digit_place
        inside = ok & (digit_place < id_len)
        digit = _HEX[buf[np.where(inside, position, 0)]]
        ok &= ~(inside & (digit == 255))
        ids |= np.where(inside, digit, 0).astype(np.uint32) << np.uint32(4 * digit_place)
    extended = id_len > 3
    error_frame = ok & extended & ((ids & CAN_ERR_FLAG) != 0)
    keys = (ids & np.uint32(0x1FFFFFFF)) | np.where(extended, EXTENDED_FLAG, 0).astype(np.uint32)
    frames = ok & ~error_frame
    return ok, h, before, keys, extended, frames


def _count_keys(
    keys: np.ndarray,
    frames: np.ndarray,
    extended: np.ndarray,
    counts: Counter,
    std_counts: np.ndarray,
) -> None:
    """Count the frames' keys: 11-bit ids into ``std_counts``, extended ones into ``counts``."""
    standard = frames & ~extended
    std_counts += np.bincount(keys[standard], minlength=2048)[:2048]
    if (frames & extended).any():
        found, many = np.unique(keys[frames & extended], return_counts=True)
        counts.update(dict(zip(found.tolist(), many.tolist(), strict=True)))


def _wanted_lines(
    buf: np.ndarray,
    spaces: np.ndarray,
    line_start: np.ndarray,
    line_stop: np.ndarray,
    hash_at: np.ndarray,
    channel_end: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The time [s], channel text, payload length [bytes] and payload of the wanted lines,
    which of them parse, and which are remote frames (no payload)."""
    first_space = spaces[np.searchsorted(spaces, line_start)]
    # time between '(' and ')', the channel between the first space and the id
    closed = buf[np.maximum(first_space - 1, 0)] == 41  # ')'
    stamp = _gather_text(buf, line_start + 1, first_space - 1, 24)
    channel_text = _gather_text(buf, first_space + 1, channel_end, 16)
    data_start = hash_at + 1
    fd = buf[np.minimum(data_start, len(buf) - 1)] == 35  # '##' + flags: CAN FD
    data_start = np.where(fd, hash_at + 3, data_start)
    following = np.searchsorted(spaces, hash_at)
    next_space = spaces[np.minimum(following, len(spaces) - 1)]
    spaced = (following < len(spaces)) & (next_space < line_stop)  # ' R' / ' T' after the data
    data_stop = np.where(spaced, next_space, line_stop)
    remote = np.isin(buf[np.minimum(data_start, len(buf) - 1)], (82, 114)) & (
        data_start < data_stop
    )  # 'R': a remote frame, no payload
    n_hex = np.maximum(data_stop - data_start, 0)
    good = closed & (first_space < channel_end) & (n_hex % 2 == 0) & (n_hex <= 128)
    length = (n_hex // 2).astype(np.int64)
    width = max(8, int(length[good].max(initial=0)))
    data = np.zeros((len(line_start), width), dtype=np.uint8)
    for byte in range(width):
        inside = good & (byte < length)
        at = np.where(inside, data_start + 2 * byte, 0)
        high, low = _HEX[buf[at]], _HEX[buf[at + 1]]
        good &= ~(inside & ((high == 255) | (low == 255)))
        data[:, byte] = np.where(inside, (high << 4) | (low & 15), 0)
    try:
        t = stamp.astype(np.float64)
    except ValueError:
        t = np.array([_float_or_nan(s) for s in stamp])
    good &= np.isfinite(t) & ~remote
    return t, channel_text, length, data, good, remote


def _float_or_nan(text: bytes) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")


def _first(bad: np.ndarray, first_line: int) -> int | None:
    return int(first_line + bad[0]) if len(bad) else None


def _empty_block() -> _Block:
    return _Block(
        np.zeros(0),
        np.zeros(0, dtype=np.uint32),
        np.zeros(0, dtype="S16"),
        np.zeros(0, dtype=np.int64),
        np.zeros((0, 8), dtype=np.uint8),
        np.zeros(0, dtype=np.int64),
    )


def _open_log(path: Path):
    return gzip.open(path, "rb") if path.suffix.lower() == ".gz" else open(path, "rb")


def read_candump(path: Path, wanted: set[int]) -> Frames:
    """The wanted frames of a candump log, parsed with numpy block by block."""
    wanted_keys = np.array(sorted(wanted), dtype=np.uint32)
    counts: Counter = Counter()
    std_counts = np.zeros(2048, dtype=np.int64)
    blocks: list[_Block] = []
    line, malformed, first_bad = 1, 0, None
    try:
        with _open_log(path) as handle:
            tail = b""
            while True:
                chunk = handle.read(BLOCK_BYTES)
                if not chunk:
                    block, tail = (tail + b"\n" if tail.strip() else b""), b""
                else:
                    chunk = tail + chunk
                    cut = chunk.rfind(b"\n") + 1
                    block, tail = chunk[:cut], chunk[cut:]
                if block:
                    found, lines, bad, first = _parse_candump_block(
                        block, line, wanted_keys, counts, std_counts
                    )
                    blocks.append(found)
                    line += lines
                    malformed += bad
                    if first_bad is None:
                        first_bad = first
                if not chunk:
                    break
    except (OSError, EOFError) as exc:
        raise StreamError(f"{path}: cannot read ({getattr(exc, 'strerror', None) or exc})") from exc
    for key in np.flatnonzero(std_counts):
        counts[int(key)] = int(std_counts[key])
    texts = np.concatenate([b.channel_text for b in blocks]) if blocks else np.zeros(0, "S16")
    names, channel = np.unique(texts, return_inverse=True)
    width = max((b.data.shape[1] for b in blocks), default=8)
    data = np.concatenate(
        [np.pad(b.data, ((0, 0), (0, width - b.data.shape[1]))) for b in blocks]
        or [np.zeros((0, width), dtype=np.uint8)]
    )
    return Frames(
        t=np.concatenate([b.t for b in blocks] or [np.zeros(0)]),
        key=np.concatenate([b.key for b in blocks] or [np.zeros(0, dtype=np.uint32)]),
        channel=channel.ravel(),
        length=np.concatenate([b.length for b in blocks] or [np.zeros(0, dtype=np.int64)]),
        data=data,
        number=np.concatenate([b.number for b in blocks] or [np.zeros(0, dtype=np.int64)]),
        channels=tuple(n.decode("utf-8", "replace") for n in names),
        counts=counts,
        total=sum(counts.values()),
        unit="line",
        path=path,
        malformed=(malformed, first_bad),
    )
