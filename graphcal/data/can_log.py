"""Wheel and IMU streams from a raw CAN log decoded with a DBC (the manifest keys ``can``,
``dbc``, ``message``, ``bus`` of ``[wheels]`` and ``[imu]``; issue 28).

**Reading.** A candump log (``candump -l`` or ``-L`` text, ``.log`` or ``.log.gz``) is parsed
with numpy in blocks of :data:`BLOCK_BYTES`: each line's frame id is read for all lines at
once, and only the lines of the wanted ids are parsed further (time, channel, payload) — a
3-hour log of a car (21.6 M frames) is read in seconds without holding it in memory. Every
other format python-can reads (Vector ``.asc`` and ``.blf``, python-can's ``.csv``,
``.trc``) goes through ``can.LogReader``, one frame at a time, keeping only the wanted ids.

**Decoding.** The DBC is read with cantools (``strict=False``: real DBCs overlap signals or
name things twice). The frames of one message are decoded together: each signal's raw bits
are taken from the payloads as one ``uint64`` array with numpy bit operations derived from
the signal's definition (start bit, length, byte order, signed, IEEE float), scaled as
cantools scales (``raw * scale + offset``, so the values are cantools' to the bit), and a
multiplexed signal is present in the frames whose multiplexer (chain) selects it. A signal
spanning more than 8 bytes (a 64-bit signal off a byte boundary) is decoded frame by frame
with cantools. A frame cantools would refuse — shorter than the DBC's length (a wrong DLC),
a multiplexer value the DBC does not define, a float that is not finite — is counted and
reported in a note, not fatal.

**Time** is each frame's timestamp in the log [s] (candump: the text's value, correctly
rounded; ASC: the header's date, read in the local time zone as python-can reads it, plus
the frame's offset; BLF: the file's start plus the frame's offset), plus the section's
``time_offset``.

Errors name the manifest key, the file, the message and the signal the user wrote, and how to
fix them (one line, :class:`~graphcal.data.streams.StreamError`).
"""

from __future__ import annotations

import difflib
import gzip
import re
import weakref
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from graphcal.data.imu_mounting import MOUNTED_KEYS  # a 3-axis IMU's keys, not read from CAN
from graphcal.data.streams import (
    Field,
    ImuStream,
    Provenance,
    StreamError,
    WheelStream,
    check_time,
    unique_samples,
)

if TYPE_CHECKING:
    from graphcal.data.manifest import Manifest

#: Bytes of a candump log parsed at once (a block ends at a line end).
BLOCK_BYTES = 1 << 24
#: The flag of an extended (29-bit) frame id in a frame's key (:func:`frame_key`).
EXTENDED_FLAG = 1 << 31
#: candump's flag of an error frame in an 8-digit id (not a frame of any message).
CAN_ERR_FLAG = 0x20000000
#: Manifest keys of a section read from a CAN log.
CAN_KEYS = ("can", "dbc", "message", "bus")
#: Keys of a CSV section that a CAN log's section does not use (its frames carry the time).
CSV_ONLY_KEYS = ("file", "topic", "time", "time_unit")
#: How DBCs spell the units graphcal knows, by the manifest's unit name.
SPEED_UNIT_SPELLINGS = {
    "km/h": ("km/h", "kph", "kmh", "km/hr", "kmph", "kilometers per hour"),
    "m/s": ("m/s", "mps", "m/sec"),
    "mph": ("mph", "mi/h", "miles per hour"),
}
RPM_SPELLINGS = ("rpm", "1/min", "u/min", "rev/min", "r/min")
YAW_RATE_UNIT_SPELLINGS = {
    "deg/s": ("deg/s", "°/s", "dps", "deg/sec", "degree/s", "degrees/s", "grad/s"),
    "rad/s": ("rad/s", "rad/sec", "radians/s"),
}
#: How many names an error lists (messages of a DBC, signals, ids of a log).
LISTED = 8

_HEX = np.full(256, 255, dtype=np.uint8)
for _value, _char in enumerate(b"0123456789ABCDEF"):
    _HEX[_char] = _value
for _value, _char in enumerate(b"abcdef"):
    _HEX[_char] = 10 + _value


def frame_key(frame_id: int, extended: bool) -> int:
    """A frame's id and format as one integer: ``id | EXTENDED_FLAG`` for a 29-bit id."""
    return int(frame_id) | (EXTENDED_FLAG if extended else 0)


def id_text(key: int) -> str:
    """``0x0AA`` (11-bit) or ``0x18FEF100 (extended)`` for a frame key."""
    if key & EXTENDED_FLAG:
        return f"0x{key & 0x1FFFFFFF:08X} (extended)"
    return f"0x{key:03X}"


def _need_packages(what: str) -> None:
    """One line if cantools or python-can is missing."""
    import importlib.util

    missing = [name for name in ("cantools", "can") if importlib.util.find_spec(name) is None]
    if missing:
        names = " and ".join("python-can" if n == "can" else n for n in missing)
        raise StreamError(f'{what} needs {names}: pip install -e ".[can]" (the can extra)')


# ----------------------------------------------------------------------------------- reading


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


def is_candump(path: Path) -> bool:
    """A candump text log: ``.log`` (or ``.log.gz``)."""
    suffixes = [s.lower() for s in path.suffixes[-2:]]
    return suffixes[-1:] == [".log"] or suffixes == [".log", ".gz"]


def read_frames(path: Path, wanted: set[int]) -> Frames:
    """The frames of the keys ``wanted`` (:func:`frame_key`) of a CAN log, with every id's
    frame count; a candump log with numpy, any other format with python-can."""
    if is_candump(path):
        return _read_candump(path, wanted)
    return _read_python_can(path, wanted)


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
    standard = frames & ~extended
    std_counts += np.bincount(keys[standard], minlength=2048)[:2048]
    if (frames & extended).any():
        found, many = np.unique(keys[frames & extended], return_counts=True)
        counts.update(dict(zip(found.tolist(), many.tolist(), strict=True)))
    bad = np.flatnonzero(~ok & ~blank)
    chosen = np.flatnonzero(frames & np.isin(keys, wanted))
    if not len(chosen):
        return _empty_block(), len(ends), len(bad), _first(bad, first_line)

    line_start, line_stop, hash_at = starts[chosen], stop[chosen], h[chosen]
    first_space = spaces[np.searchsorted(spaces, line_start)]
    channel_end = before[chosen]
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
    data = np.zeros((len(chosen), width), dtype=np.uint8)
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


def _read_candump(path: Path, wanted: set[int]) -> Frames:
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
        raise StreamError(f"{path}: cannot read as a CAN log ({_reason(exc)})") from None
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
        raise StreamError(f"{path}: cannot read as a CAN log{where} ({_reason(exc)})") from None
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


def _reason(exc: BaseException) -> str:
    """An exception's message on one line."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text


# ---------------------------------------------------------------------------------- decoding


@dataclass(frozen=True)
class _Layout:
    """Where a signal's raw bits are in a payload: ``nbytes`` bytes from ``first``, read as
    one big- or little-endian integer, shifted right by ``shift`` and masked to ``length``."""

    first: int
    nbytes: int
    shift: int
    length: int
    big: bool


def signal_layout(signal) -> _Layout | None:
    """The :class:`_Layout` of a cantools signal, or ``None`` if it spans more than 8 bytes
    (then it is decoded frame by frame with cantools)."""
    length = int(signal.length)
    if signal.byte_order == "little_endian":
        lsb = int(signal.start)
        first, last = lsb // 8, (lsb + length - 1) // 8
        nbytes = last - first + 1
        shift = lsb - 8 * first
    else:  # Motorola: the DBC's start bit is the most significant bit, bytes in order
        msb = 8 * (int(signal.start) // 8) + 7 - int(signal.start) % 8
        first, last = msb // 8, (msb + length - 1) // 8
        nbytes = last - first + 1
        shift = 8 * nbytes - (msb - 8 * first) - length
    if nbytes > 8 or length > 64:
        return None
    return _Layout(first, nbytes, shift, length, signal.byte_order != "little_endian")


def raw_bits(data: np.ndarray, layout: _Layout) -> np.ndarray:
    """A signal's raw bits in each payload of ``data`` ``(n, width)``, as ``uint64``."""
    word = np.zeros(len(data), dtype=np.uint64)
    for i in range(layout.nbytes):
        place = 8 * (layout.nbytes - 1 - i) if layout.big else 8 * i
        column = layout.first + i
        byte = data[:, column] if column < data.shape[1] else np.zeros(len(data), np.uint8)
        word |= byte.astype(np.uint64) << np.uint64(place)
    word >>= np.uint64(layout.shift)
    if layout.length < 64:
        word &= np.uint64((1 << layout.length) - 1)
    return word


def physical(signal, raw: np.ndarray) -> np.ndarray:
    """The values cantools decodes from raw bits ``raw`` (``uint64``): signed or IEEE float
    as the signal says, then ``raw * scale + offset`` (float64, as cantools computes it: in
    integers when the DBC's scale and offset are integers and the product may pass 2^53)."""
    length = int(signal.length)
    scale, offset = signal.scale, signal.offset
    if signal.is_float:
        if length == 32:
            with np.errstate(invalid="ignore"):  # a NaN's payload: it fails as not finite
                value = raw.astype(np.uint32).view(np.float32).astype(np.float64)
        else:
            value = raw.view(np.float64).copy()
    elif signal.is_signed:
        negative = (raw >> np.uint64(length - 1)) & np.uint64(1)
        signed = raw.view(np.int64) if length == 64 else raw.astype(np.int64)
        if length < 64:
            signed = signed - (negative.astype(np.int64) << np.int64(length))
        value = signed
    else:
        value = raw
    integral = isinstance(scale, int) and isinstance(offset, int) and not signal.is_float
    if integral and length + abs(scale).bit_length() + 1 > 53:  # Python's exact integers
        return np.array([float(int(v) * scale + offset) for v in value.tolist()], dtype=float)
    value = value.astype(np.float64)
    if scale == 1 and offset == 0:
        return value
    return value * scale + offset


@dataclass
class Decoded:
    """The values of some signals of one message's frames.

    Attributes:
        present: by signal name, the frames that carry it (a multiplexed signal only those
            of its page), ``(n,)``.
        values: by signal name, the decoded value in each frame (NaN where absent).
        failed: frames that do not decode (cantools would refuse them), ``(n,)``.
        reasons: why, for the first failed frame.
    """

    present: dict[str, np.ndarray]
    values: dict[str, np.ndarray]
    failed: np.ndarray
    reasons: dict[int, str] = field(default_factory=dict)


def decode_signals(message, names: list[str], data: np.ndarray, length: np.ndarray) -> Decoded:
    """Decode the signals ``names`` of a cantools ``message`` from its frames' payloads
    ``data`` ``(n, width)`` of ``length`` bytes, vectorized over the frames (module
    docstring); frames shorter than the message, or whose multiplexer value the DBC does not
    define, fail."""
    n = len(data)
    failed = length < int(message.length)
    reasons: dict[int, str] = {}
    if failed.any():
        k = int(np.flatnonzero(failed)[0])
        reasons[k] = f"{int(length[k])} bytes where the DBC has {int(message.length)}"
    cache: dict[str, np.ndarray] = {}
    odd = [s for s in message.signals if signal_layout(s) is None]
    slow = _decode_slowly(message, data, length) if odd else None

    def value_of(name: str) -> np.ndarray:
        if name not in cache:
            signal = message.get_signal_by_name(name)
            layout = signal_layout(signal)
            if layout is None:
                cache[name] = slow[name]
            else:
                cache[name] = physical(signal, raw_bits(data, layout))
        return cache[name]

    present, values = {}, {}
    for name in names:
        signal = message.get_signal_by_name(name)
        selected = np.ones(n, dtype=bool)
        current = signal
        while current.multiplexer_signal is not None:
            mux = message.get_signal_by_name(current.multiplexer_signal)
            page = value_of(mux.name)
            defined = sorted(
                {
                    i
                    for s in message.signals
                    if s.multiplexer_signal == mux.name
                    for i in (s.multiplexer_ids or [])
                }
            )
            undefined = ~np.isin(page, defined) & ~failed
            if undefined.any():
                k = int(np.flatnonzero(undefined)[0])
                reasons.setdefault(
                    k, f"multiplexer {mux.name} = {page[k]:g}, a value the DBC does not define"
                )
                failed = failed | undefined
            selected &= np.isin(page, current.multiplexer_ids or [])
            current = mux
        value = value_of(name)
        finite = np.isfinite(value)
        broken = selected & ~finite & ~failed
        if broken.any():
            k = int(np.flatnonzero(broken)[0])
            reasons.setdefault(k, f"signal {name} = {value[k]} (not a finite number)")
            failed = failed | broken
        present[name] = selected
        values[name] = value
    for name in names:
        present[name] = present[name] & ~failed
        values[name] = np.where(present[name], values[name], np.nan)
    if slow is not None:
        failed = failed | slow["__failed__"].astype(bool)
        for name in names:
            present[name] &= ~failed
    return Decoded(present, values, failed, reasons)


def _decode_slowly(message, data: np.ndarray, length: np.ndarray) -> dict[str, np.ndarray]:
    """Every signal of ``message`` decoded frame by frame with cantools (for signals that
    span more than 8 bytes); ``"__failed__"`` marks the frames cantools refuses."""
    n = len(data)
    out = {s.name: np.full(n, np.nan) for s in message.signals}
    failed = np.zeros(n)
    for i in range(n):
        try:
            decoded = message.decode(
                bytes(data[i, : length[i]]), decode_choices=False, allow_truncated=False
            )
        except Exception:
            failed[i] = 1
            continue
        for name, value in decoded.items():
            out[name][i] = float(value)
    out["__failed__"] = failed
    return out


# ------------------------------------------------------------------------- the manifest side


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
    table: dict
    log: Path
    log_key: str
    dbc: Path
    dbc_key: str
    database: Any
    message: Any
    signals: dict[str, Any]
    bus: int | str | None
    bus_key: str
    inherits: dict | None = None

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
    sources = [_source(manifest, name, databases) for name in sections]
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
                streams["wheels"] = _wheel_stream(manifest, source, frames, notes)
            else:
                streams["imu"] = _imu_stream(manifest, source, frames, notes)
    return streams


def _path_key(
    manifest: Manifest, table: dict, key: str, fallback: dict | None, what: str
) -> tuple[Path, str]:
    """The file a key names (``can``, ``dbc``), the key that named it, checked present."""
    section = "wheels" if table is manifest.wheels else "imu"
    value, where = table.get(key), f"[{section}] {key}"
    if value is None and fallback is not None and key in fallback:
        value, where = fallback[key], f"[wheels] {key}, as [{section}] has none"
    if value is None:
        raise manifest.error(
            f"[{section}] needs {key} ({what}, relative to the manifest)"
            + (" or [wheels] can and dbc to share" if section == "imu" else "")
        )
    if not isinstance(value, str) or not value:
        raise manifest.error(f"{where} must be a path (text), got {value!r}")
    path = manifest.resolve(value)
    if not path.is_file():
        raise StreamError(
            f"{path}: no such file (named in {manifest.source} {where}); check the path"
        )
    return path, where


def load_dbc(path: Path, where: str, manifest_source: str, cache: dict | None = None):
    """A DBC read with cantools (``strict=False``); one line with cantools' reason if it does
    not parse."""
    if cache is not None and path in cache:
        return cache[path]
    import cantools

    try:
        database = cantools.database.load_file(str(path), strict=False)
    except Exception as exc:
        reason = _reason(exc)
        dbc = re.search(r'DBC: "(.*)"$', reason)
        if dbc:
            reason = dbc.group(1)
        raise StreamError(
            f"{path}: not a DBC cantools reads ({reason}) (named in {manifest_source} {where}); "
            "fix the file or name another"
        ) from None
    if not isinstance(database, cantools.database.can.Database):
        raise StreamError(
            f"{path}: not a CAN database (named in {manifest_source} {where}); give a DBC"
        )
    if cache is not None:
        cache[path] = database
    return database


def _listing(names: list[str], wanted: str | None = None) -> str:
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
        listed = _listing([f"{m.name} (0x{m.frame_id:X})" for m in messages])
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
        f"{_listing(names, spec) or 'no messages'}; check {key} and dbc"
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
        f"{_listing(names, name) or 'none'}"
    )


def _source(manifest: Manifest, section: str, databases: dict) -> CanSource:
    """Check one section's CAN keys and find its message and signals in the DBC."""
    table = manifest.wheels if section == "wheels" else manifest.imu
    fallback = manifest.wheels if section == "imu" and "can" in manifest.wheels else None
    both = [k for k in ("file", "topic") if k in table]
    if both:
        raise manifest.error(
            f"[{section}] {both[0]} and can/message: name one source for the stream (a CSV "
            "file or a CAN log)"
        )
    mounted = [k for k in MOUNTED_KEYS if k in table]
    if mounted:
        raise manifest.error(
            f"[{section}] {', '.join(mounted)}: not read from a CAN log; name the vehicle "
            "frame's lateral_acceleration and yaw_rate signals"
        )
    unused = [k for k in CSV_ONLY_KEYS if k in table]
    if unused:
        raise manifest.error(
            f"[{section}] {', '.join(unused)}: not used with a CAN log, whose frames carry "
            "their time in seconds (use time_offset)"
        )
    log, log_key = _path_key(manifest, table, "can", fallback, "the CAN log")
    dbc, dbc_key = _path_key(manifest, table, "dbc", fallback, "the DBC that decodes it")
    database = load_dbc(dbc, dbc_key, manifest.source, databases)
    if "message" not in table:
        raise manifest.error(
            f"[{section}] needs message (the DBC message's name or frame id, e.g. 0xAA) with "
            f"can; {dbc} has {_listing([m.name for m in database.messages])}"
        )
    spec = parse_message_spec(table["message"])
    if spec is None:
        raise manifest.error(
            f"[{section}] message must be a message name or frame id (0xAA, 170), got "
            f"{table['message']!r}"
        )
    message = find_message(database, spec, dbc, f"[{section}] message", manifest.source)
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
            message, table[role], dbc, f"[{section}] {role} in {manifest.source}"
        )
    if section == "wheels":
        for role in roles:
            if role not in signals:
                raise manifest.error(
                    f"[wheels] needs {role} (a signal of {message.name}: "
                    f"{_listing([s.name for s in message.signals])})"
                )
        if signals["rear_left"].name == signals["rear_right"].name:
            raise manifest.error(
                f"[wheels] rear_left and rear_right are both {signals['rear_left'].name!r}; "
                "name the two wheels' signals"
            )
    elif not signals:
        raise manifest.error(
            f"[imu] needs lateral_acceleration or yaw_rate (a signal of {message.name}: "
            f"{_listing([s.name for s in message.signals])})"
        )
    inherits = fallback if fallback is not None and "can" not in table else None
    bus, bus_key = table.get("bus"), f"[{section}] bus"
    if bus is None and inherits is not None:
        bus, bus_key = inherits.get("bus"), f"[wheels] bus, as [{section}] has none"
    if bus is not None and (isinstance(bus, bool) or not isinstance(bus, int | str)):
        raise manifest.error(f"[{section}] bus must be a channel name or number, got {bus!r}")
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


def _bus_matches(name: str, bus: int | str) -> bool:
    """A log's bus name (``"can0"``, ``"1"``) is the manifest's ``bus`` (``"can0"``; or a
    number: ``0`` is ``"0"``, ``"can0"``, ``"vcan0"``)."""
    if isinstance(bus, str):
        return name == bus or (bus.isdigit() and _bus_matches(name, int(bus)))
    digits = re.search(r"(\d+)$", name)
    return digits is not None and int(digits.group(1)) == bus


def _message_frames(source: CanSource, frames: Frames) -> Frames:
    """The frames of the source's message (on its bus); one line if the log has none."""
    mine = frames.key == source.key
    if not mine.any():
        ids = sorted(frames.counts, key=lambda k: -frames.counts[k])
        known = {
            frame_key(m.frame_id, m.is_extended_frame): m.name for m in source.database.messages
        }
        named = [k for k in ids if k in known] + [k for k in ids if k not in known]
        listed = [f"{id_text(k)}" + (f" {known[k]}" if k in known else "") for k in named]
        other = ""
        flipped = source.key ^ EXTENDED_FLAG
        if flipped in frames.counts:
            other = (
                f" (it has {id_text(flipped)}: the DBC's message is "
                f"{'extended' if source.key & EXTENDED_FLAG else 'an 11-bit id'})"
            )
        raise StreamError(
            f"{frames.path}: no frame of {source.message_text()} ([{source.section}] "
            f"message){other} among its {frames.total} frames; the "
            f"log has {len(ids)} id(s): {_listing(listed)}; check [{source.section}] message, "
            "dbc and can"
        )
    if source.bus is not None:
        buses = [i for i, name in enumerate(frames.channels) if _bus_matches(name, source.bus)]
        on_bus = mine & np.isin(frames.channel, buses)
        if not on_bus.any():
            found = sorted({frames.channels[c] for c in np.unique(frames.channel[mine])})
            raise StreamError(
                f"{frames.path}: no frame of {source.message_text()} on bus {source.bus!r} "
                f"({source.bus_key}); its frames are on {', '.join(found) or 'an unnamed bus'}; "
                "set bus to one of those or leave it out"
            )
        mine = on_bus
    return frames.take(mine)


def _decoded_samples(
    manifest: Manifest, source: CanSource, frames: Frames, notes: list[str], wraps: dict[str, float]
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The time [s], the value of each role's signal and the frame numbers of a section's
    samples: the frames of its message that carry all its signals (a signal of another
    multiplexer page is interpolated at those frames' times, said in a note); counters that
    wrap (``wraps``, by role) are unwrapped first."""
    from graphcal.data.manifest import _unwrap_counter

    mine = _message_frames(source, frames)
    names = {role: signal.name for role, signal in source.signals.items()}
    decoded = decode_signals(
        source.message, list(dict.fromkeys(names.values())), mine.data, mine.length
    )
    failed = int(decoded.failed.sum())
    roles = list(names)
    if failed:
        k = int(np.flatnonzero(decoded.failed)[0])
        reason = decoded.reasons.get(k, "")
        what = (
            f"{failed} of the {len(mine.t)} frames of {source.message_text()} "
            f"([{source.section}] message) do not decode (first: {mine.unit} "
            f"{int(mine.number[k])}{': ' + reason if reason else ''})"
        )
        if failed == len(mine.t):
            raise StreamError(f"{frames.path}: {what}; check [{source.section}] dbc and message")
        notes.append(f"{frames.path}: {what}; left out")
    present = {role: decoded.present[names[role]] for role in roles}
    lead = roles[0]
    for role in roles:
        if not present[role].any():
            raise StreamError(
                f"{frames.path}: no frame of {source.message_text()} carries signal "
                f"{names[role]} ([{source.section}] {role}; multiplexed: its page never "
                "comes); check the signal"
            )
    keep = np.flatnonzero(present[lead])
    t = mine.t[keep]
    values = {}
    for role in roles:
        own = present[role]
        value = decoded.values[names[role]]
        if np.array_equal(own, present[lead]):
            values[role] = value[keep]
            if role in wraps:
                values[role] = _unwrap_counter(values[role], wraps[role])
            continue
        order = np.argsort(mine.t[own], kind="stable")
        own_t, own_v = mine.t[own][order], value[own][order]
        if role in wraps:
            own_v = _unwrap_counter(own_v, wraps[role])
        values[role] = np.interp(t, own_t, own_v)
        inside = (t >= own_t[0]) & (t <= own_t[-1])
        t, keep = t[inside], keep[inside]
        values = {r: v[inside] for r, v in values.items()}
        notes.append(
            f"{frames.path}: signals {names[lead]} and {names[role]} of "
            f"{source.message.name} come in different frames (multiplexer pages): "
            f"{names[role]} interpolated at the times of {names[lead]}"
        )
    return t, values, mine.number[keep]


def _unit_of(signal) -> str:
    return (signal.unit or "").strip()


def _known_unit(unit: str, spellings: dict[str, tuple[str, ...]]) -> str | None:
    folded = unit.lower().replace(" ", "")
    for name, options in spellings.items():
        if folded in options:
            return name
    return None


def _dbc_unit(source: CanSource, roles: tuple[str, ...], spellings) -> tuple[str | None, str]:
    """The unit the DBC gives the roles' signals, if one graphcal knows and all agree, and the
    DBC's text of it."""
    units = {_unit_of(source.signals[r]) for r in roles if r in source.signals}
    known = {_known_unit(u, spellings) for u in units}
    if len(known) == 1 and None not in known:
        return known.pop(), ", ".join(sorted(units))
    return None, ", ".join(repr(u) for u in sorted(units)) or "none"


def _wheel_stream(
    manifest: Manifest, source: CanSource, frames: Frames, notes: list[str]
) -> WheelStream:
    """The wheel stream of ``[wheels]`` from its CAN message (units as ``_read_wheels``)."""
    from graphcal.data.manifest import SPEED_UNITS, WHEEL_KINDS, wheel_scale

    table = source.table
    signals = source.signals
    dbc_unit, dbc_text = _dbc_unit(source, ("rear_left", "rear_right"), SPEED_UNIT_SPELLINGS)
    rpm = all(_unit_of(s).lower() in RPM_SPELLINGS for s in signals.values())
    if "kind" not in table:
        suggestion = (
            ' (the DBC\'s unit says kind = "speed")'
            if dbc_unit
            else (' (the DBC\'s unit says kind = "rpm")' if rpm else "")
        )
        raise manifest.error(f"[wheels] needs kind (one of {', '.join(WHEEL_KINDS)}){suggestion}")
    kind = manifest.choice(table, "kind", WHEEL_KINDS, "wheels", None)
    cumulative, wraps = kind in ("ticks", "angle"), {}
    declared = [f'kind = "{kind}"']
    keys: dict[str, str] = {"kind": kind}

    def speed_unit() -> str:
        if "speed_unit" in table:
            unit = manifest.choice(table, "speed_unit", SPEED_UNITS, "wheels", None)
            declared.append(f'speed_unit = "{unit}"')
            if dbc_unit is not None and dbc_unit != unit:
                notes.append(
                    f"{source.dbc}: {source.message.name}'s wheel signals are in {dbc_text}; "
                    f'[wheels] speed_unit = "{unit}" overrides it'
                )
            return unit
        if dbc_unit is not None:
            declared.append(f'speed_unit = "{dbc_unit}" from the DBC ({dbc_text})')
            return dbc_unit
        hint = ' (the signals are in rpm: set kind = "rpm")' if rpm else ""
        raise manifest.error(
            f"[wheels] needs speed_unit ({', '.join(SPEED_UNITS)}): {source.dbc} gives "
            f"signals {signals['rear_left'].name}, {signals['rear_right'].name} the unit "
            f"{dbc_text}{hint}"
        )

    scaling = wheel_scale(manifest, kind, speed_unit)
    scale, resolution, wrap = scaling.scale, scaling.resolution, scaling.wrap
    if kind == "speed":
        declared.append(f"circumference = {scaling.circumference:g} m")
        keys.update(speed_unit=str(scaling.speed_unit), circumference=repr(scaling.circumference))
    elif kind == "ticks":
        declared.append(f"ticks_per_revolution = {scaling.ticks:g}")
        keys["ticks_per_revolution"] = repr(scaling.ticks)
        for role, signal in signals.items():
            counter_wrap = wrap if wrap is not None else _counter_range(signal)
            if counter_wrap is not None:
                wraps[role] = counter_wrap
    units = ", ".join(declared)
    t, values, numbers = _decoded_samples(manifest, source, frames, notes, wraps)
    fields = {
        "time": Field("timestamp", source.log_key.split(" in ")[0], "s (the log's)"),
        **{
            role: Field(source.field_name(role), f"[wheels] {role}", units, tuple(keys.items()))
            for role in ("rear_left", "rear_right")
        },
    }
    t, values, provenance = _checked(manifest, source, frames, t, values, numbers, fields, notes)
    return WheelStream(
        t=t,
        left=values["rear_left"] * scale,
        right=values["rear_right"] * scale,
        cumulative=cumulative,
        source=str(frames.path),
        resolution=resolution,
        provenance=provenance,
    )


def _counter_range(signal) -> float | None:
    """Where an unsigned integer counter signal wraps: its raw range × scale (offset 0)."""
    if signal.is_signed or signal.is_float or signal.offset != 0 or signal.scale <= 0:
        return None
    return float(2 ** int(signal.length)) * float(signal.scale)


def _imu_stream(
    manifest: Manifest, source: CanSource, frames: Frames, notes: list[str]
) -> ImuStream:
    """The IMU stream of ``[imu]`` from its CAN message."""
    from graphcal.data.manifest import YAW_RATE_UNITS

    table = source.table
    declared: dict[str, dict[str, str]] = {}
    units = {"lateral_acceleration": "m/s², positive to the left"}
    factor = 1.0
    if "yaw_rate" in source.signals:
        dbc_unit, dbc_text = _dbc_unit(source, ("yaw_rate",), YAW_RATE_UNIT_SPELLINGS)
        if "yaw_rate_unit" in table:
            unit = manifest.choice(table, "yaw_rate_unit", YAW_RATE_UNITS, "imu", None)
            units["yaw_rate"] = f'yaw_rate_unit = "{unit}"'
        elif dbc_unit is not None:
            unit = dbc_unit
            units["yaw_rate"] = f'yaw_rate_unit = "{unit}" from the DBC ({dbc_text})'
        else:
            raise manifest.error(
                f"[imu] needs yaw_rate_unit ({', '.join(YAW_RATE_UNITS)}): {source.dbc} gives "
                f"signal {source.signals['yaw_rate'].name} the unit {dbc_text}"
            )
        declared["yaw_rate"] = {"yaw_rate_unit": unit}
        factor = YAW_RATE_UNITS[unit]
    t, values, numbers = _decoded_samples(manifest, source, frames, notes, {})
    fields = {
        "time": Field("timestamp", source.log_key.split(" in ")[0], "s (the log's)"),
        **{
            role: Field(
                source.field_name(role),
                f"[imu] {role}",
                units.get(role),
                tuple(declared.get(role, {}).items()),
            )
            for role in source.signals
        },
    }
    t, values, provenance = _checked(manifest, source, frames, t, values, numbers, fields, notes)
    yaw_rate = values.get("yaw_rate")
    return ImuStream(
        t=t,
        lateral_acceleration=values.get("lateral_acceleration"),
        yaw_rate=None if yaw_rate is None else yaw_rate * factor,
        source=str(frames.path),
        provenance=provenance,
    )


def _checked(
    manifest: Manifest,
    source: CanSource,
    frames: Frames,
    t: np.ndarray,
    values: dict[str, np.ndarray],
    numbers: np.ndarray,
    fields: dict[str, Field],
    notes: list[str],
) -> tuple[np.ndarray, dict[str, np.ndarray], Provenance]:
    """Sort the samples by time, drop repeats (:func:`unique_samples`), check the time and
    add the section's ``time_offset``."""
    provenance = Provenance(str(frames.path), fields, numbers, frames.unit, quantity="signal")
    keep = unique_samples(t, values, provenance, notes, sort=True)
    if len(keep) < len(t) or not np.array_equal(keep, np.arange(len(t))):
        t, provenance = t[keep], provenance.take(keep)
        values = {role: v[keep] for role, v in values.items()}
    check_time(t, str(frames.path), provenance)
    table, section = source.table, source.section
    if "time_offset" not in table and source.inherits:  # the wheels' log: the same clock
        table, section = source.inherits, "wheels"
    offset = manifest.number(table, "time_offset", 0.0, section)
    return t + offset, values, provenance
