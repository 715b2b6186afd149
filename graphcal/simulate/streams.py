"""A synthetic drive as raw sensor streams, each at its own rate and on its own sample clock.

The drive of :func:`graphcal.simulate.drive.simulate_drive` is simulated noise-free on a fine
grid, then sampled as a real car records it: GNSS fixes at 10 Hz in latitude/longitude
around ``origin`` with a compass heading in degrees and the sideslip an INS would give, rear
wheel speeds from the CAN bus at 100 Hz in m/s (converted by the "ECU" with its own
circumference) or cumulative tick counts, and an IMU at 100 Hz — each stream starting and
sampling at its own instants, with timestamp jitter on the CAN bus. :func:`write_streams`
writes them as CSV files with a streams manifest (:mod:`graphcal.recording.manifest.manifest`) and a
``truth.json`` with ``theta_true``.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.files import atomic_write_csv, atomic_write_text
from graphcal.log.drive_log import DriveLog
from graphcal.model import PARAMETER_NAMES, lever_offset
from graphcal.recording.geodesy import local_to_geodetic
from graphcal.recording.streams import ImuStream, PoseStream, Recording, WheelStream
from graphcal.simulate.drive import (
    THETA_TRUE_DEFAULT,
    NoiseLevels,
    SyntheticDrive,
    VehicleMotion,
    simulate_drive,
)

#: Time of the first sample [s]: a Unix time (2025-11-23), as loggers write.
EPOCH = 1_763_856_000.0
#: Fine grid [s] of the noise-free simulation that the streams sample.
FINE_DT = 0.005


@dataclass(frozen=True)
class StreamSettings:
    """Rates, noise and formats of the simulated streams (SI unless named otherwise).

    Attributes:
        gnss_rate, wheel_rate, imu_rate: [Hz].
        position_noise: [m] per fix, east and north; heading_noise [rad] per fix.
        wheel_speed_noise: [m/s] per wheel-speed sample (0.06 m/s at 100 Hz is about the
            paper's 0.0005 rev per 40 Hz interval once integrated).
        lateral_acceleration_noise [m/s²], yaw_rate_noise [rad/s], sideslip_noise [rad].
        wheel_kind: ``"speed"`` (m/s, the ECU's ``circumference``) or ``"ticks"``.
        circumference: [m] the ECU used to turn rotations into speed.
        ticks_per_revolution: resolution of the tick counters.
        clock_jitter: [s] uniform ± jitter of the wheel and IMU timestamps.
        antenna_arm: ``(ahead, left)`` [m] of the GNSS antenna from the centre of gravity, a
            point of the rigid body (its fixes are ``p + R(psi) · arm``).
        origin: ``(latitude, longitude)`` [deg] of the drive's start.
    """

    gnss_rate: float = 10.0
    wheel_rate: float = 100.0
    imu_rate: float = 100.0
    position_noise: float = 0.2
    heading_noise: float = float(np.deg2rad(1.5))
    wheel_speed_noise: float = 0.06
    lateral_acceleration_noise: float = 0.0
    yaw_rate_noise: float = 0.0
    sideslip_noise: float = 0.0
    wheel_kind: str = "speed"
    circumference: float = 2.0
    ticks_per_revolution: int = 96
    clock_jitter: float = 0.0005
    antenna_arm: tuple[float, float] = (0.0, 0.0)
    origin: tuple[float, float] = (47.4979, 19.0402)

    def __post_init__(self) -> None:
        if self.wheel_kind not in ("speed", "ticks"):
            raise ValueError(f"wheel_kind must be 'speed' or 'ticks', got {self.wheel_kind!r}")
        for name in ("gnss_rate", "wheel_rate", "imu_rate", "circumference"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        if not 0 <= self.clock_jitter < 0.25 / max(self.wheel_rate, self.imu_rate):
            raise ValueError("clock_jitter must be >= 0 and well below the sample interval")


@dataclass(frozen=True)
class SyntheticRecording:
    """Simulated streams with the noise-free drive they sample and ``theta_true``."""

    recording: Recording
    drive: SyntheticDrive
    settings: StreamSettings
    gnss: pd.DataFrame
    wheels: pd.DataFrame
    imu: pd.DataFrame | None

    def manifest(self) -> str:
        """The streams manifest of :func:`write_streams`' files: a local x/y pose (``pose.csv``)
        when ``gnss`` has ``x`` and ``y`` columns, no ``[imu]`` without an IMU stream."""
        return manifest_text(
            self.settings, local_pose="x" in self.gnss.columns, imu=self.imu is not None
        )

    def metadata(self) -> dict:
        """What ``truth.json`` says besides the drive, theta_true and the stream settings."""
        return {}


def _times(start: float, end: float, rate: float, phase: float, jitter: float, rng) -> np.ndarray:
    t = start + phase + np.arange(0.0, end - start - phase, 1.0 / rate)
    if jitter > 0:
        t = t + rng.uniform(-jitter, jitter, len(t))
    return t


def simulate_streams(
    length_km: float = 24.0,
    seed: int = 0,
    theta_true: np.ndarray = THETA_TRUE_DEFAULT,
    settings: StreamSettings | None = None,
    motion: VehicleMotion | None = None,
    route: str = "city",
) -> SyntheticRecording:
    """Simulate a drive and sample it as GNSS, CAN wheel and IMU streams (module docstring).

    Args:
        length_km: route length [km].
        seed: seed of every random choice; the route is the one
            :func:`~graphcal.simulate.drive.simulate_drive` drives with the same seed.
        theta_true: true parameters (SI).
        settings: rates, noise and formats of the streams.
        motion: driving-style constants.
        route: ``"city"`` or ``"straight"``.
    """
    settings = settings or StreamSettings()
    quiet = NoiseLevels(0.0, 0.0, 0.0, 0.0, 0.0)
    drive = simulate_drive(length_km, seed, theta_true, quiet, FINE_DT, motion, route)
    rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
    gnss = _gnss_frame(drive.truth, settings, rng)
    wheels = _wheel_frame(drive.truth, settings, rng)
    imu = _imu_frame(drive.truth, settings, rng)
    recording = _recording(gnss, wheels, imu, settings)
    return SyntheticRecording(recording, drive, settings, gnss, wheels, imu)


def _gnss_frame(
    truth: DriveLog, settings: StreamSettings, rng: np.random.Generator
) -> pd.DataFrame:
    """GNSS/INS fixes ``t, lat, lon, heading, beta``: the antenna's position, compass
    heading [deg], sideslip [rad]; they start 0.5 s late."""
    t_fine = EPOCH + truth.t
    start, end = float(t_fine[0]), float(t_fine[-1])
    t_gnss = _times(start + 0.5, end - 0.3, settings.gnss_rate, 0.037, 0.0, rng)
    true_heading = np.interp(t_gnss, t_fine, truth.psi)
    antenna = lever_offset(true_heading, np.asarray(settings.antenna_arm, float))
    east = np.interp(t_gnss, t_fine, truth.px) + antenna[:, 0]
    east = east + settings.position_noise * rng.standard_normal(len(t_gnss))
    north = np.interp(t_gnss, t_fine, truth.py) + antenna[:, 1]
    north = north + settings.position_noise * rng.standard_normal(len(t_gnss))
    heading = true_heading + settings.heading_noise * rng.standard_normal(len(t_gnss))
    sideslip = np.interp(t_gnss, t_fine, truth.beta)
    sideslip = sideslip + settings.sideslip_noise * rng.standard_normal(len(t_gnss))
    latitude, longitude = local_to_geodetic(east, north, settings.origin)
    compass = np.mod(90.0 - np.degrees(heading), 360.0)
    return pd.DataFrame(
        {"t": t_gnss, "lat": latitude, "lon": longitude, "heading": compass, "beta": sideslip}
    )


def _wheel_frame(
    truth: DriveLog, settings: StreamSettings, rng: np.random.Generator
) -> pd.DataFrame:
    """Rear wheels on the CAN bus, ``t, rl, rr``: speeds [m/s] or cumulative tick counts of
    the fine simulation's rotation."""
    t_fine = EPOCH + truth.t
    start, end = float(t_fine[0]), float(t_fine[-1])
    cumulative = {
        side: np.concatenate([[0.0], np.cumsum(n[:-1])])
        for side, n in (("rl", truth.n_rl), ("rr", truth.n_rr))
    }
    # Wheels (the CAN logger) start last, 0.6 s late: the drive log's grid starts at their
    # first sample, and the GNSS epochs fall between its rows (12 ms before one), as they do
    # in a real recording.
    t_wheels = _times(start + 0.6, end, settings.wheel_rate, 0.0, settings.clock_jitter, rng)
    wheels = pd.DataFrame({"t": t_wheels})
    rate_t = 0.5 * (t_fine[1:] + t_fine[:-1])  # rotation rates hold between fine samples
    for side, cum in cumulative.items():
        if settings.wheel_kind == "ticks":
            offset = rng.uniform(0.0, 1.0)  # counters start anywhere within a tick
            counts = np.interp(t_wheels, t_fine, cum) * settings.ticks_per_revolution + offset
            wheels[side] = np.floor(counts).astype(np.int64)
        else:
            rev_per_s = np.interp(t_wheels, rate_t, np.diff(cum) / np.diff(t_fine))
            speed = rev_per_s * settings.circumference
            noise = settings.wheel_speed_noise * rng.standard_normal(len(t_wheels))
            wheels[side] = np.maximum(speed + noise, 0.0)
    return wheels


def _imu_frame(truth: DriveLog, settings: StreamSettings, rng: np.random.Generator) -> pd.DataFrame:
    """IMU samples ``t, ay, wz``: lateral acceleration [m/s²] and yaw rate [rad/s]; they
    start 0.2 s late."""
    t_fine = EPOCH + truth.t
    start, end = float(t_fine[0]), float(t_fine[-1])
    rate_t = 0.5 * (t_fine[1:] + t_fine[:-1])  # rates hold between fine samples
    t_imu = _times(start + 0.2, end, settings.imu_rate, 0.0051, settings.clock_jitter, rng)
    yaw_rate = np.diff(truth.psi) / np.diff(truth.t)
    return pd.DataFrame(
        {
            "t": t_imu,
            "ay": np.interp(t_imu, t_fine, truth.ay)
            + settings.lateral_acceleration_noise * rng.standard_normal(len(t_imu)),
            "wz": np.interp(t_imu, rate_t, yaw_rate)
            + settings.yaw_rate_noise * rng.standard_normal(len(t_imu)),
        }
    )


def _recording(
    gnss: pd.DataFrame, wheels: pd.DataFrame, imu: pd.DataFrame, settings: StreamSettings
) -> Recording:
    """The streams as the manifest reader would return them (SI, local frame)."""
    from graphcal.recording.geodesy import geodetic_to_local

    x, y, origin = geodetic_to_local(gnss["lat"].to_numpy(), gnss["lon"].to_numpy(), "gnss")
    pose = PoseStream(
        t=gnss["t"].to_numpy(),
        x=x,
        y=y,
        heading=np.radians(90.0 - gnss["heading"].to_numpy()),
        sideslip=gnss["beta"].to_numpy(),
        source="<synthetic gnss>",
        origin=origin,
    )
    if settings.wheel_kind == "ticks":
        scale, cumulative = 1.0 / settings.ticks_per_revolution, True
    else:
        scale, cumulative = 1.0 / settings.circumference, False
    wheel = WheelStream(
        t=wheels["t"].to_numpy(),
        left=wheels["rl"].to_numpy(dtype=float) * scale,
        right=wheels["rr"].to_numpy(dtype=float) * scale,
        cumulative=cumulative,
        source="<synthetic wheels>",
        resolution=scale if settings.wheel_kind == "ticks" else None,
    )
    imu_stream = ImuStream(
        t=imu["t"].to_numpy(),
        lateral_acceleration=imu["ay"].to_numpy(),
        yaw_rate=imu["wz"].to_numpy(),
        source="<synthetic imu>",
    )
    return Recording(pose=pose, wheels=wheel, imu=imu_stream, source="<synthetic streams>")


def manifest_text(
    settings: StreamSettings, rate: float = 40.0, *, local_pose: bool = False, imu: bool = True
) -> str:
    """The streams manifest of :func:`write_streams`' files.

    ``local_pose``: a ``[pose]`` of ``pose.csv`` with x, y [m] and an ENU heading [rad] (motion
    capture) instead of GNSS latitude/longitude; ``imu``: with the ``[imu]`` section.
    """
    if settings.wheel_kind == "ticks":
        wheel_keys = f'kind = "ticks"\nticks_per_revolution = {settings.ticks_per_revolution}\n'
    else:
        wheel_keys = (
            'kind = "speed"\nspeed_unit = "m/s"\n'
            f"circumference = {settings.circumference!r}  # m, the ECU's\n"
        )
    if local_pose:
        pose = (
            "\n[pose]\n"
            'file = "pose.csv"\ntime = "t"\nx = "x"\ny = "y"\n'
            'heading = "heading"\nheading_unit = "rad"\nheading_convention = "enu"\n'
        )
    else:
        pose = (
            "\n[gnss]\n"
            'file = "gnss.csv"\ntime = "t"\nlatitude = "lat"\nlongitude = "lon"\n'
            'heading = "heading"\nheading_unit = "deg"\nheading_convention = "compass"\n'
            'sideslip = "beta"\nsideslip_unit = "rad"\n'
        )
    imu_keys = (
        '\n[imu]\nfile = "imu.csv"\ntime = "t"\nlateral_acceleration = "ay"\nyaw_rate = "wz"\n'
    )
    return (
        "# Synthetic recording written by `graphcal simulate --streams`.\n"
        f"rate = {rate!r}\n"
        'truth = "truth.json"  # synthetic only: theta_true, compared with after calibration\n'
        f"{pose}"
        "\n[wheels]\n"
        'file = "wheels.csv"\ntime = "t"\nrear_left = "rl"\nrear_right = "rr"\n'
        f"{wheel_keys}"
        f"{imu_keys if imu else ''}"
    )


def replace_section(manifest: str, name: str, section: str) -> str:
    """The manifest text with its ``[name]`` section (from its header to the blank line before
    the next section, or to the end) replaced by ``section``: its header and lines, each
    ending in a newline."""
    pattern = rf"^\[{name}\][^\n]*\n.*?(?=\n\[|\Z)"
    text, count = re.subn(pattern, lambda _m: section, manifest, count=1, flags=re.S | re.M)
    if count != 1:
        raise ValueError(f"the manifest has no [{name}] section to replace")
    return text


def write_streams(sim: SyntheticRecording, directory: str | os.PathLike[str]) -> list[Path]:
    """Write ``gnss.csv``, ``wheels.csv``, ``imu.csv``, ``manifest.toml`` and ``truth.json``
    (``pose.csv`` instead of ``gnss.csv`` for a local x/y pose, no ``imu.csv`` without an IMU:
    :meth:`SyntheticRecording.manifest`)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    pose_file = "pose.csv" if "x" in sim.gnss.columns else "gnss.csv"
    written = [
        atomic_write_csv(sim.gnss, directory / pose_file),
        atomic_write_csv(sim.wheels, directory / "wheels.csv"),
    ]
    if sim.imu is not None:
        written.append(atomic_write_csv(sim.imu, directory / "imu.csv"))
    written.append(write_truth(sim, directory))
    written.append(atomic_write_text(directory / "manifest.toml", sim.manifest()))
    return written


def write_truth(sim: SyntheticRecording, directory: str | os.PathLike[str]) -> Path:
    """Write ``truth.json``: the drive's seed, length and route, ``theta_true`` and the
    stream settings, for ``calibrate`` to compare with."""
    from graphcal import __version__

    truth = {
        "generator": f"graphcal {__version__} simulate --streams",
        "seed": sim.drive.seed,
        "length_km": sim.drive.length_km,
        "route": sim.drive.route,
        "theta_true": dict(zip(PARAMETER_NAMES, map(float, sim.drive.theta_true), strict=True)),
        "theta_units": {"c_e": "m", "c_d": "m", "t_r": "m", "d": "s^2 (m per m/s^2)"},
        "streams": {
            key: list(value) if isinstance(value, tuple) else value
            for key, value in asdict(sim.settings).items()
        },
        "epoch_s": EPOCH,
        **sim.metadata(),
    }
    return atomic_write_text(Path(directory) / "truth.json", json.dumps(truth, indent=2) + "\n")
