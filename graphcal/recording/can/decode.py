"""Signals of a DBC message decoded from its frames' payloads, vectorized over the frames.

Each signal's raw bits are taken from the payloads as one ``uint64`` array with numpy bit
operations derived from the signal's definition (start bit, length, byte order, signed, IEEE
float), scaled as cantools scales (``raw * scale + offset``, so the values are cantools' to
the bit), and a multiplexed signal is present in the frames whose multiplexer (chain)
selects it. A signal spanning more than 8 bytes (a 64-bit signal off a byte boundary) is
decoded frame by frame with cantools. A frame cantools would refuse — shorter than the DBC's
length (a wrong DLC), a multiplexer value the DBC does not define, a float that is not
finite — is marked failed, with the first one's reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
