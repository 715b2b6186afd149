"""The frames a synthetic car's CAN bus carries, encoded as the DBC of
:mod:`graphcal.simulate.can_log` defines them (issue 28).

:func:`can_frames` turns a :class:`~graphcal.simulate.streams.SyntheticRecording` into the
frames of the bus: the rear wheels' speeds in ``WHEEL_SPEEDS`` (0xAA) as the ABS sends them —
km/h, big-endian 15-bit signals with scale 0.01 and offset −67.67, at the recording's wheel
rate —, the IMU's yaw rate [deg/s] and lateral acceleration [m/s²] in page 0 of the
multiplexed, little-endian, signed ``KINEMATICS`` (0x130) at the IMU's rate, page 1 at
:data:`STEERING_RATE`, unrelated traffic, and a few corrupt frames (a wrong DLC, an undefined
multiplexer value). Every frame's time is a whole microsecond and every signal is quantized
exactly as the DBC encodes it (``raw = round((value − offset) / scale)``, decoded
``raw · scale + offset``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from graphcal.simulate.streams import SyntheticRecording

WHEEL_MESSAGE, WHEEL_ID = "WHEEL_SPEEDS", 0xAA
IMU_MESSAGE, IMU_ID = "KINEMATICS", 0x130
EXTENDED_FLAG = 1 << 31
#: Unrelated traffic of a light log (tests): ``(frame key, rate [Hz])``; ENGINE, BRAKE,
#: GEAR and DIAGNOSTIC (extended) are in the DBC, 0x2E4 and 0x3D3 are not.
LIGHT_TRAFFIC = (
    (0x1C4, 50.0),
    (0x224, 50.0),
    (0x3BC, 10.0),
    (0x18DAF110 | EXTENDED_FLAG, 1.0),
    (0x2E4, 20.0),
    (0x3D3, 20.0),
)
#: Rate [Hz] of KINEMATICS' page 1 (steering).
STEERING_RATE = 10.0


@dataclass(frozen=True)
class CanFrames:
    """Frames of a CAN log, sorted by time.

    Attributes:
        micros: time of each frame [µs since the Unix epoch], int64 ``(n,)``.
        key: frame id, ``| EXTENDED_FLAG`` for a 29-bit id, ``(n,)``.
        data: payloads ``(n, 8)`` uint8; length: bytes of each (its DLC), ``(n,)``.
        corrupt: frames that do not decode (wrong DLC, undefined multiplexer value).
    """

    micros: np.ndarray
    key: np.ndarray
    data: np.ndarray
    length: np.ndarray
    corrupt: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Time [s] of each frame (the float a log's text ``%.6f`` reads back as)."""
        return self.micros / 1e6

    def __len__(self) -> int:
        return len(self.micros)


@dataclass(frozen=True)
class Decoded:
    """What the DBC decodes from the frames of the wheel and IMU messages (the reference).

    Attributes:
        wheels: ``t`` [s] and ``rl``, ``rr`` [km/h] of each good WHEEL_SPEEDS frame.
        imu: ``t`` [s], ``ay`` [m/s²] and ``wz`` [deg/s] of each good KINEMATICS page-0 frame.
    """

    wheels: pd.DataFrame
    imu: pd.DataFrame


def _quantize(value: np.ndarray, scale: float, offset: float, bits: int, signed: bool):
    """Raw integers and decoded values of ``value`` as the DBC encodes it (cantools:
    ``round((value - offset) / scale)``, clipped to the signal's range)."""
    raw = np.round((np.asarray(value, dtype=float) - offset) / scale)
    low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
    raw = np.clip(raw, low, high).astype(np.int64)
    return raw, raw.astype(np.float64) * scale + offset


def _pack(data: np.ndarray, raw: np.ndarray, start: int, bits: int, big: bool) -> None:
    """Write raw integers (two's complement if negative) into payloads ``data`` at a DBC
    signal's place: Motorola (``big``) with ``start`` its most significant bit, Intel with
    ``start`` its least significant bit."""
    value = raw.astype(np.int64) & ((1 << bits) - 1)
    for k in range(bits):  # bit k of the value, counted from its least significant bit
        bit = (value >> k) & 1
        if big:
            msb = 8 * (start // 8) + 7 - start % 8  # position 0 = MSB of byte 0
            position = msb + bits - 1 - k
            byte, shift = position // 8, 7 - position % 8
        else:
            position = start + k
            byte, shift = position // 8, position % 8
        data[:, byte] |= (bit << shift).astype(np.uint8)


def can_frames(
    sim: SyntheticRecording,
    traffic: tuple[tuple[int, float], ...] = LIGHT_TRAFFIC,
    corrupt: int = 3,
    seed: int = 0,
    window: tuple[int, int] | None = None,
) -> tuple[CanFrames, Decoded]:
    """The frames of a synthetic car's bus for the recording ``sim`` (module docstring) and
    what the DBC decodes from them; ``corrupt`` WHEEL_SPEEDS frames with 5 bytes and as many
    KINEMATICS frames with multiplexer value 3 are added. ``window``: only the frames in
    ``[start, end)`` [µs] (consecutive windows make up the whole log, for logs of hours)."""
    if sim.settings.wheel_kind != "speed":
        raise ValueError("can_frames needs a recording with wheel speeds (wheel_kind 'speed')")
    wheel_all = np.round(sim.wheels["t"].to_numpy() * 1e6).astype(np.int64)
    imu_all = np.round(sim.imu["t"].to_numpy() * 1e6).astype(np.int64)
    start_us = int(min(wheel_all[0], imu_all[0]))
    end_us = int(max(wheel_all[-1], imu_all[-1]))
    # unrelated traffic from a whole second before the first sample (the log's first frame
    # is at a whole millisecond, as an ASC header's date has it)
    first_us = (start_us // 1_000_000 - 1) * 1_000_000
    low, high = window if window is not None else (first_us, end_us + 1)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 28, max(low, 0)]))
    wheel_part, wheels = _wheel_frames(sim, wheel_all, (low, high), rng)
    imu_part, imu = _imu_frames(sim, imu_all, (low, high))
    parts = [wheel_part, imu_part, _steering_frames(start_us, end_us, (low, high), rng)]
    for number, (key, rate) in enumerate(traffic):
        period = round(1e6 / rate)
        phase = 0 if number == 0 else int(np.random.default_rng([seed, key]).integers(1, period))
        micros = _periodic(first_us + phase, end_us, period, low, high)
        parts.append(_part(micros, key, rng.integers(0, 256, (len(micros), 8), dtype=np.uint8)))
    if corrupt:
        parts += _corrupt_frames(wheel_all, imu_all, corrupt, (low, high), rng)
    return _sorted(parts), Decoded(wheels, imu)


#: Frames of one message, unsorted: ``(micros, key, data, length, corrupt)`` as in
#: :class:`CanFrames`.
_Part = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _part(micros, key: int, data: np.ndarray, length=None, bad=None) -> _Part:
    """Frames of ``key`` at ``micros`` with payloads ``data`` (8 bytes and good unless
    ``length`` and ``bad`` say otherwise)."""
    n = len(micros)
    return (
        np.asarray(micros, dtype=np.int64),
        np.full(n, key, dtype=np.int64),
        data,
        np.full(n, 8, dtype=np.int64) if length is None else length,
        np.zeros(n, dtype=bool) if bad is None else bad,
    )


def _inside(micros: np.ndarray, window: tuple[int, int]) -> np.ndarray:
    """Which of the times ``micros`` [µs] lie in ``window``'s ``[low, high)``."""
    low, high = window
    return (micros >= low) & (micros < high)


def _wheel_frames(
    sim: SyntheticRecording,
    wheel_all: np.ndarray,
    window: tuple[int, int],
    rng: np.random.Generator,
) -> tuple[_Part, pd.DataFrame]:
    """WHEEL_SPEEDS frames in ``window`` (km/h, big-endian 15-bit, scale 0.01, offset
    -67.67; the front wheels the rear ones' mean with noise) and the decoded rear speeds."""
    rows = np.flatnonzero(_inside(wheel_all, window))
    wheel_us = wheel_all[rows]
    kmh = {side: sim.wheels[side].to_numpy()[rows] * 3.6 for side in ("rl", "rr")}
    raw_rl, rl = _quantize(kmh["rl"], 0.01, -67.67, 15, False)
    raw_rr, rr = _quantize(kmh["rr"], 0.01, -67.67, 15, False)
    front = 0.5 * (kmh["rl"] + kmh["rr"]) + 0.05 * rng.standard_normal(len(wheel_us))
    raw_front, _ = _quantize(front, 0.01, -67.67, 15, False)
    data = np.zeros((len(wheel_us), 8), dtype=np.uint8)
    for raw, start in ((raw_front, 7), (raw_front, 8), (raw_rl, 25), (raw_rr, 42)):
        _pack(data, raw, start, 15, True)
    _pack(data, rows % 16, 59, 4, True)
    return _part(wheel_us, WHEEL_ID, data), pd.DataFrame({"t": wheel_us / 1e6, "rl": rl, "rr": rr})


def _imu_frames(
    sim: SyntheticRecording, imu_all: np.ndarray, window: tuple[int, int]
) -> tuple[_Part, pd.DataFrame]:
    """KINEMATICS page-0 frames in ``window`` (little-endian signed: yaw rate [deg/s],
    lateral acceleration [m/s²]) and their decoded values."""
    rows = np.flatnonzero(_inside(imu_all, window))
    imu_us = imu_all[rows]
    raw_wz, wz = _quantize(np.degrees(sim.imu["wz"].to_numpy()[rows]), 0.005, 0.0, 16, True)
    raw_ay, ay = _quantize(sim.imu["ay"].to_numpy()[rows], 0.002, 0.0, 13, True)
    data = np.zeros((len(imu_us), 8), dtype=np.uint8)
    _pack(data, raw_wz, 8, 16, False)
    _pack(data, raw_ay, 26, 13, False)
    return _part(imu_us, IMU_ID, data), pd.DataFrame({"t": imu_us / 1e6, "ay": ay, "wz": wz})


def _steering_frames(
    start_us: int, end_us: int, window: tuple[int, int], rng: np.random.Generator
) -> _Part:
    """KINEMATICS page-1 frames (random steering) at :data:`STEERING_RATE` in ``window``."""
    steer_us = _periodic(start_us + 3_000, end_us, round(1e6 / STEERING_RATE), *window)
    data = np.zeros((len(steer_us), 8), dtype=np.uint8)
    _pack(data, np.ones(len(steer_us), dtype=np.int64), 0, 2, False)
    _pack(data, rng.integers(-900, 900, len(steer_us)), 8, 16, False)
    return _part(steer_us, IMU_ID, data)


def _corrupt_frames(
    wheel_all: np.ndarray,
    imu_all: np.ndarray,
    corrupt: int,
    window: tuple[int, int],
    rng: np.random.Generator,
) -> list[_Part]:
    """``corrupt`` WHEEL_SPEEDS frames with 5 bytes and as many KINEMATICS frames with
    multiplexer value 3, spread over the drive (those in ``window``)."""
    at = np.linspace(0.2, 0.8, corrupt)
    wheel_bad = wheel_all[(at * len(wheel_all)).astype(int)] + 7_000
    imu_bad = imu_all[(at * len(imu_all)).astype(int)] + 4_000
    wheel_bad, imu_bad = wheel_bad[_inside(wheel_bad, window)], imu_bad[_inside(imu_bad, window)]
    data = np.zeros((len(wheel_bad), 8), dtype=np.uint8)
    data[:, :5] = rng.integers(0, 256, (len(wheel_bad), 5), dtype=np.uint8)
    bad = np.ones(len(wheel_bad), dtype=bool)
    wheel_part = _part(wheel_bad, WHEEL_ID, data, np.full(len(wheel_bad), 5), bad)
    data = rng.integers(0, 256, (len(imu_bad), 8), dtype=np.uint8)
    data[:, 0] = (data[:, 0] & 0xFC) | 3
    return [wheel_part, _part(imu_bad, IMU_ID, data, None, np.ones(len(imu_bad), dtype=bool))]


def _sorted(parts: list[_Part]) -> CanFrames:
    """The frames of all parts, sorted by time (stable: ties keep the parts' order)."""
    micros = np.concatenate([p[0] for p in parts])
    order = np.argsort(micros, kind="stable")
    return CanFrames(
        micros=micros[order],
        key=np.concatenate([p[1] for p in parts])[order],
        data=np.concatenate([p[2] for p in parts])[order],
        length=np.concatenate([p[3] for p in parts])[order],
        corrupt=np.concatenate([p[4] for p in parts])[order],
    )


def _periodic(first: int, end: int, period: int, low: int, high: int) -> np.ndarray:
    """The times ``first + k · period`` [µs] up to ``end`` that lie in ``[low, high)``."""
    k0 = max(0, -(-(low - first) // period))
    stop = min(end, high - 1)
    k1 = (stop - first) // period + 1 if stop >= first else 0
    return first + period * np.arange(k0, max(k0, k1), dtype=np.int64)
