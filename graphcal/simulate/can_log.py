"""A synthetic car's raw CAN log and its DBC, from the streams of ``graphcal simulate
--streams`` (issue 28).

:data:`CAR_DBC` defines the frames :func:`graphcal.simulate.can_bus.can_frames` makes of a
:class:`~graphcal.simulate.streams.SyntheticRecording`: the rear wheels' speeds in
``WHEEL_SPEEDS`` (0xAA), the IMU's yaw rate and lateral acceleration in the multiplexed
``KINEMATICS`` (0x130), unrelated messages (some in the DBC, some not, one with an extended
id) and a few corrupt frames.

:func:`write_can_recording` writes the DBC, the log in candump (``-L``, python-can's
writer), Vector ASC and BLF, and for each format the decoded-CSV twin: the decoded wheel
speeds and IMU signals at the log's timestamps (as python-can reads them back), with a
manifest for each — the reference the CAN import must equal. :func:`write_candump` writes
a candump log with numpy (the same bytes as python-can's writer) for logs of hours.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.files import atomic_write_chunks, atomic_write_csv, atomic_write_text
from graphcal.simulate.can_bus import (
    EXTENDED_FLAG,
    IMU_ID,
    LIGHT_TRAFFIC,
    WHEEL_ID,
    WHEEL_MESSAGE,
    CanFrames,
    Decoded,
    can_frames,
)
from graphcal.simulate.streams import SyntheticRecording, write_streams

#: The DBC of the synthetic car (opendbc's style: Motorola wheel speeds, a multiplexed IMU).
CAR_DBC = """VERSION ""


NS_ :
	CM_
	BA_DEF_
	BA_
	VAL_

BS_:

BU_: ABS IMU ECM XXX


BO_ 170 WHEEL_SPEEDS: 8 ABS
 SG_ WHEEL_SPEED_FL : 7|15@0+ (0.01,-67.67) [-67.67|260] "km/h" XXX
 SG_ WHEEL_SPEED_FR : 8|15@0+ (0.01,-67.67) [-67.67|260] "km/h" XXX
 SG_ WHEEL_SPEED_RL : 25|15@0+ (0.01,-67.67) [-67.67|260] "km/h" XXX
 SG_ WHEEL_SPEED_RR : 42|15@0+ (0.01,-67.67) [-67.67|260] "km/h" XXX
 SG_ COUNTER : 59|4@0+ (1,0) [0|15] "" XXX

BO_ 304 KINEMATICS: 8 IMU
 SG_ MUX M : 0|2@1+ (1,0) [0|3] "" XXX
 SG_ YAW_RATE m0 : 8|16@1- (0.005,0) [-163.84|163.835] "deg/s" XXX
 SG_ ACCEL_Y m0 : 26|13@1- (0.002,0) [-8.192|8.19] "m/s^2" XXX
 SG_ STEER_ANGLE m1 : 8|16@1- (0.1,0) [-3276.8|3276.7] "deg" XXX
 SG_ STEER_RATE m1 : 24|12@1- (1,0) [-2048|2047] "deg/s" XXX

BO_ 452 ENGINE: 8 ECM
 SG_ ENGINE_RPM : 7|16@0+ (0.25,0) [0|16383.75] "rpm" XXX
 SG_ THROTTLE : 23|8@0+ (0.4,0) [0|102] "%" XXX

BO_ 548 BRAKE: 8 ABS
 SG_ BRAKE_PRESSURE : 0|12@1+ (0.1,0) [0|409.5] "bar" XXX
 SG_ BRAKE_PRESSED : 12|1@1+ (1,0) [0|1] "" XXX

BO_ 956 GEAR: 8 ECM
 SG_ GEAR : 0|4@1+ (1,0) [0|15] "" XXX

BO_ 2564485392 DIAGNOSTIC: 8 XXX
 SG_ DIAG_DATA : 0|32@1+ (1,0) [0|4294967295] "" XXX


CM_ SG_ 170 WHEEL_SPEED_RL "Rear-left wheel speed from the ABS";
CM_ SG_ 170 WHEEL_SPEED_RR "Rear-right wheel speed from the ABS";
VAL_ 956 GEAR 0 "P" 1 "R" 2 "N" 3 "D" ;
"""


def car_traffic(total_rate: float = 1850.0, seed: int = 3) -> tuple[tuple[int, float], ...]:
    """Unrelated traffic of a whole car's bus: :data:`LIGHT_TRAFFIC` plus ids (0x100–0x7FF,
    not in the DBC) at 10–100 Hz until the unrelated frames add up to ``total_rate`` [Hz]
    (with the wheels at 50 Hz and KINEMATICS at 110 Hz, 1850 makes a bus of ~2000
    frames/s)."""
    rng = np.random.default_rng(seed)
    traffic = list(LIGHT_TRAFFIC)
    used = {key for key, _ in traffic} | {WHEEL_ID, IMU_ID}
    rate = sum(r for _, r in traffic)
    while rate < total_rate:
        key = int(rng.integers(0x100, 0x800))
        if key in used:
            continue
        hz = float(min(rng.choice([10.0, 20.0, 25.0, 50.0, 100.0]), total_rate - rate))
        traffic.append((key, hz))
        used.add(key)
        rate += hz
    return tuple(traffic)


def write_car_candump(
    sim: SyntheticRecording,
    path: str | os.PathLike[str],
    traffic: tuple[tuple[int, float], ...] | None = None,
    window_s: float = 300.0,
    corrupt: int = 3,
    seed: int = 0,
) -> int:
    """Write the whole bus of a car (:func:`car_traffic`: ~2000 frames/s) for the recording
    as a candump log, ``window_s`` seconds of frames at a time (so a 3-hour log of 21.6 M
    frames never sits in memory); returns the number of frames written."""
    traffic = car_traffic() if traffic is None else traffic
    wheel_t = sim.wheels["t"].to_numpy()
    first = (int(min(wheel_t[0], sim.imu["t"].iloc[0])) - 1) * 1_000_000
    last = round(float(max(wheel_t[-1], sim.imu["t"].iloc[-1])) * 1e6) + 1
    step = round(window_s * 1e6)
    written = 0
    with open(path, "wb") as handle:
        for low in range(first, last, step):
            frames, _ = can_frames(sim, traffic, corrupt, seed, (low, min(low + step, last)))
            handle.write(candump_text(frames))
            written += len(frames)
    return written


def _messages(frames: CanFrames, channel: int = 0):
    """The frames as python-can messages (received on ``channel``)."""
    import can

    for micros, key, data, length in zip(
        frames.micros.tolist(),
        frames.key.tolist(),
        frames.data,
        frames.length.tolist(),
        strict=True,
    ):
        yield can.Message(
            timestamp=micros / 1e6,
            arbitration_id=key & 0x1FFFFFFF,
            is_extended_id=bool(key & EXTENDED_FLAG),
            data=bytes(data[:length]),
            dlc=length,
            channel=channel,
            is_rx=True,
        )


#: Log formats :func:`write_can_log` writes, by suffix.
FORMATS = ("log", "asc", "blf")


def write_can_log(frames: CanFrames, path: str | os.PathLike[str]) -> Path:
    """Write the frames with python-can's writer of the path's suffix (``.log``: candump
    ``-L``, ``.asc``, ``.blf``)."""
    import can

    path = Path(path)
    writers = {".log": can.CanutilsLogWriter, ".asc": can.ASCWriter, ".blf": can.BLFWriter}
    writer = writers[path.suffix.lower()](str(path))
    try:
        for message in _messages(frames):
            writer.on_message_received(message)
    finally:
        writer.stop()
    return path


_HEX_DIGITS = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)
_DECIMAL = np.frombuffer(b"0123456789", dtype=np.uint8)


def candump_text(frames: CanFrames, channel: str = "can0") -> bytes:
    """The frames as candump ``-L`` lines (``(1763856000.600000) can0 0AA#...... R``),
    built with numpy: the bytes python-can's ``CanutilsLogWriter`` writes."""
    n = len(frames)
    seconds, micros = np.divmod(frames.micros, 1_000_000)
    columns: list[tuple[np.ndarray, np.ndarray]] = []

    def const(text: bytes) -> None:
        row = np.frombuffer(text, dtype=np.uint8)
        columns.append((np.broadcast_to(row, (n, len(row))), np.ones((n, len(row)), bool)))

    def digits(values: np.ndarray, width: int, table: np.ndarray, base: int, keep) -> None:
        places = base ** np.arange(width - 1, -1, -1, dtype=np.int64)
        columns.append((table[(values[:, None] // places[None, :]) % base], keep))

    const(b"(")
    sec_digits = np.maximum(1, np.floor(np.log10(np.maximum(seconds, 1))).astype(int) + 1)
    digits(seconds, 12, _DECIMAL, 10, np.arange(12)[None, :] >= 12 - sec_digits[:, None])
    const(b".")
    digits(micros, 6, _DECIMAL, 10, np.ones((n, 6), bool))
    const(b") " + channel.encode() + b" ")
    extended = (frames.key & EXTENDED_FLAG) != 0
    ids = frames.key & 0x1FFFFFFF
    digits(ids, 8, _HEX_DIGITS, 16, np.arange(8)[None, :] >= np.where(extended, 0, 5)[:, None])
    const(b"#")
    hexes = np.empty((n, 16), dtype=np.uint8)
    hexes[:, 0::2] = _HEX_DIGITS[frames.data >> 4]
    hexes[:, 1::2] = _HEX_DIGITS[frames.data & 15]
    columns.append((hexes, np.arange(16)[None, :] < 2 * frames.length[:, None]))
    const(b" R\n")
    text = np.concatenate([c for c, _ in columns], axis=1)
    keep = np.concatenate([k for _, k in columns], axis=1)
    return text[keep].tobytes()


def write_candump(
    frames: CanFrames, path: str | os.PathLike[str], channel: str = "can0", chunk: int = 500_000
) -> Path:
    """Write a candump ``-L`` log with numpy (:func:`candump_text`), ``chunk`` frames at a
    time, atomically: a 3-hour log of a car's bus in seconds."""
    parts = (slice(start, start + chunk) for start in range(0, len(frames), chunk))
    return atomic_write_chunks(
        path,
        (
            candump_text(
                CanFrames(
                    frames.micros[part],
                    frames.key[part],
                    frames.data[part],
                    frames.length[part],
                    frames.corrupt[part],
                ),
                channel,
            )
            for part in parts
        ),
    )


def read_back_times(path: str | os.PathLike[str], frames: CanFrames, key: int) -> np.ndarray:
    """The timestamps [s] python-can reads from a written log for the frames of ``key`` that
    decode (the ``corrupt`` ones left out), in order: the times the import must give them.
    (ASC stores times after its header's date, BLF after its start time, each with its own
    rounding; a candump log's are the µs of :attr:`CanFrames.t`.)"""
    import can

    path = Path(path)
    reader = (
        can.ASCReader(str(path), relative_timestamp=False)
        if path.suffix.lower() == ".asc"
        else can.LogReader(str(path))
    )
    times = []
    with reader:
        for message in reader:
            if message.arbitration_id | (EXTENDED_FLAG if message.is_extended_id else 0) == key:
                times.append(message.timestamp)
    mine = frames.key == key
    good = ~frames.corrupt[mine]
    times = np.asarray(times)
    if len(times) != mine.sum():
        raise RuntimeError(f"{path}: {len(times)} frames of 0x{key:X} read, {mine.sum()} written")
    return times[good]


def manifest_text(
    log: str | None, dbc: str | None, circumference: float, wheels_csv: str = "", imu_csv: str = ""
) -> str:
    """A manifest of the GNSS CSV with the wheels and the IMU from the CAN log ``log`` and
    ``dbc`` (units from the DBC), or from decoded CSVs (``wheels_csv``, ``imu_csv``)."""
    pose = (
        "[gnss]\n"
        'file = "gnss.csv"\ntime = "t"\nlatitude = "lat"\nlongitude = "lon"\n'
        'heading = "heading"\nheading_unit = "deg"\nheading_convention = "compass"\n'
        'sideslip = "beta"\nsideslip_unit = "rad"\n'
    )
    if log is not None:
        wheels, imu = can_sections(log, dbc or "", circumference)
    else:
        wheels = (
            f'[wheels]\nfile = "{wheels_csv}"\ntime = "t"\nrear_left = "rl"\n'
            'rear_right = "rr"\nkind = "speed"\nspeed_unit = "km/h"\n'
            f"circumference = {circumference!r}\n"
        )
        imu = (
            f'[imu]\nfile = "{imu_csv}"\ntime = "t"\nlateral_acceleration = "ay"\n'
            'yaw_rate = "wz"\nyaw_rate_unit = "deg/s"\n'
        )
    return (
        "# A synthetic car's CAN log (graphcal.simulate.can_log).\n"
        'rate = 40.0\ntruth = "truth.json"\n\n' + pose + "\n" + wheels + "\n" + imu
    )


def can_sections(log: str, dbc: str, circumference: float) -> tuple[str, str]:
    """The ``[wheels]`` and ``[imu]`` sections of a manifest reading the rear wheel speeds
    (km/h, the DBC's unit; ``circumference`` [m] the ECU's) and the IMU's lateral
    acceleration and yaw rate from the CAN log ``log`` with the DBC ``dbc`` (paths relative to
    the manifest), each ending in a newline."""
    wheels = (
        f'[wheels]\ncan = "{log}"\ndbc = "{dbc}"\nmessage = "{WHEEL_MESSAGE}"\n'
        'rear_left = "WHEEL_SPEED_RL"\nrear_right = "WHEEL_SPEED_RR"\nkind = "speed"\n'
        f"circumference = {circumference!r}  # m, the ECU's; speed_unit: the DBC's km/h\n"
    )
    imu = (
        f"[imu]  # the same log and DBC as [wheels]\nmessage = 0x{IMU_ID:X}\n"
        'lateral_acceleration = "ACCEL_Y"\nyaw_rate = "YAW_RATE"\n'
    )
    return wheels, imu


@dataclass(frozen=True)
class CanRecording:
    """The files of :func:`write_can_recording`, by format (``"log"``, ``"asc"``, ``"blf"``).

    Attributes:
        directory: where they are.
        dbc: the DBC.
        logs: the CAN log of each format.
        can_manifests: the manifest reading each log with the DBC.
        csv_manifests: the manifest of the same streams decoded into CSVs (the reference).
        frames: the frames written; decoded: their decoded wheel and IMU values.
    """

    directory: Path
    dbc: Path
    logs: dict[str, Path]
    can_manifests: dict[str, Path]
    csv_manifests: dict[str, Path]
    frames: CanFrames
    decoded: Decoded


def write_can_recording(
    sim: SyntheticRecording,
    directory: str | os.PathLike[str],
    formats: tuple[str, ...] = FORMATS,
    traffic: tuple[tuple[int, float], ...] = LIGHT_TRAFFIC,
    corrupt: int = 3,
    seed: int = 0,
) -> CanRecording:
    """Write the recording's streams (:func:`~graphcal.simulate.streams.write_streams`), the
    DBC ``car.dbc``, the CAN log ``drive.<format>`` of each format, and for each the decoded
    CSVs ``wheels_<format>.csv`` (km/h) and ``imu_<format>.csv`` (m/s², deg/s) at the times
    python-can reads from that log, with the manifests ``can_<format>.toml`` and
    ``decoded_<format>.toml``."""
    directory = Path(directory)
    write_streams(sim, directory)
    dbc = directory / "car.dbc"
    atomic_write_text(dbc, CAR_DBC)
    frames, decoded = can_frames(sim, traffic, corrupt, seed)
    logs, can_manifests, csv_manifests = {}, {}, {}
    circumference = float(sim.settings.circumference)
    for fmt in formats:
        log = write_can_log(frames, directory / f"drive.{fmt}")
        wheels = decoded.wheels.assign(t=read_back_times(log, frames, WHEEL_ID))
        imu = decoded.imu.assign(t=_imu_times(log, frames))
        atomic_write_csv(wheels, directory / f"wheels_{fmt}.csv")
        atomic_write_csv(imu, directory / f"imu_{fmt}.csv")
        can_manifests[fmt] = atomic_write_text(
            directory / f"can_{fmt}.toml", manifest_text(log.name, dbc.name, circumference)
        )
        csv_manifests[fmt] = atomic_write_text(
            directory / f"decoded_{fmt}.toml",
            manifest_text(None, None, circumference, f"wheels_{fmt}.csv", f"imu_{fmt}.csv"),
        )
        logs[fmt] = log
    return CanRecording(directory, dbc, logs, can_manifests, csv_manifests, frames, decoded)


def _imu_times(log: Path, frames: CanFrames) -> np.ndarray:
    """The read-back times of the KINEMATICS frames of page 0 that decode."""
    mine = frames.key == IMU_ID
    page0 = (frames.data[mine, 0] & 3) == 0
    return read_back_times(log, frames, IMU_ID)[page0[~frames.corrupt[mine]]]
