"""How the simulated robot drives and what its sensors record: :class:`RobotSettings`, and
the fine grid :data:`FINE_DT` its noise-free motion is simulated on
(:mod:`graphcal.simulate.robot_manoeuvres`, :mod:`graphcal.simulate.robot`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from graphcal.simulate.streams import StreamSettings

if TYPE_CHECKING:
    from graphcal.vehicle import VehicleProfile

#: Fine grid [s] of the noise-free simulation the streams sample (500 Hz).
FINE_DT = 0.002


@dataclass(frozen=True)
class RobotSettings:
    """How the robot drives and what its sensors record (SI; ranges are ``(low, high)``,
    drawn uniformly per run, spin or stop).

    Attributes:
        run_length: [m] of a run. cruise_speed: [m/s] a run's top speed.
        acceleration: [m/s²] of the speed ramps (and braking).
        lateral_acceleration_limit: [m/s²] in bends; yaw_rate_limit: [rad/s] while driving.
        gentle_curvature: [1/m] of a gentle bend's |curvature|.
        tight_radius: [m] of a small-radius arc; tight_share: share of a run's pieces that are
            one. piece_length: [m] of a straight or gently curved piece.
        spin_angle: [rad] of a spin's |yaw|; spin_rate: [rad/s] its peak yaw rate;
            spin_acceleration: [rad/s²].
        stop_duration: [s] standing still between manoeuvres (and at both ends).
        reversing: reverse straight back after every second run; reverse_length [m],
            reverse_speed [m/s].
        pose_rate: [Hz] of the motion capture; position_noise [m] (per axis) and
            heading_noise [rad] per pose.
        wheel_rate: [Hz] of the encoder counts; ticks_per_revolution; clock_jitter [s], uniform
            ± on the wheel timestamps.
        log_rate: [Hz] of the drive-log view and the manifest's ``rate`` (``None``: the pose
            rate, so that each pose gets a row of its own).
    """

    run_length: tuple[float, float] = (5.0, 15.0)
    cruise_speed: tuple[float, float] = (0.4, 1.5)
    acceleration: float = 0.5
    lateral_acceleration_limit: float = 0.8
    yaw_rate_limit: float = 1.5
    gentle_curvature: tuple[float, float] = (0.05, 0.4)
    tight_radius: tuple[float, float] = (0.3, 1.0)
    tight_share: float = 0.2
    piece_length: tuple[float, float] = (1.0, 3.0)
    spin_angle: tuple[float, float] = (0.5 * math.pi, 2.0 * math.pi)
    spin_rate: tuple[float, float] = (0.5, 1.5)
    spin_acceleration: float = 2.0
    stop_duration: tuple[float, float] = (1.0, 3.0)
    reversing: bool = False
    reverse_length: tuple[float, float] = (0.5, 2.0)
    reverse_speed: float = 0.3
    pose_rate: float = 50.0
    position_noise: float = 0.001
    heading_noise: float = float(np.deg2rad(0.2))
    wheel_rate: float = 100.0
    ticks_per_revolution: int = 2797
    clock_jitter: float = 0.0005
    log_rate: float | None = None

    def __post_init__(self) -> None:
        ranges = ("run_length", "cruise_speed", "gentle_curvature", "tight_radius")
        ranges += ("piece_length", "spin_angle", "spin_rate", "stop_duration", "reverse_length")
        for name in ranges:
            low, high = getattr(self, name)
            if not (0 < low <= high < math.inf):
                raise ValueError(f"{name} must be (low, high) with 0 < low <= high")
        positive = ("acceleration", "lateral_acceleration_limit", "yaw_rate_limit")
        positive += ("spin_acceleration", "reverse_speed", "pose_rate", "wheel_rate")
        for name in positive:
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ValueError(f"{name} must be a positive number")
        for name in ("position_noise", "heading_noise"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"{name} must be >= 0")
        if not 0 <= self.tight_share <= 1:
            raise ValueError("tight_share must be within 0 … 1")
        if max(self.pose_rate, self.wheel_rate, self.rate) > 0.5 / FINE_DT:
            raise ValueError(f"rates must be at most {0.5 / FINE_DT:g} Hz (the fine grid's half)")
        if not 0 <= self.clock_jitter < 0.25 / self.wheel_rate:
            raise ValueError("clock_jitter must be >= 0 and well below the wheel interval")
        ticks = self.ticks_per_revolution
        if not (isinstance(ticks, int) and not isinstance(ticks, bool) and ticks >= 1):
            raise ValueError(f"ticks_per_revolution must be a whole number >= 1, got {ticks!r}")

    @property
    def rate(self) -> float:
        """[Hz] of the drive-log view: ``log_rate``, else ``pose_rate``."""
        return float(self.pose_rate if self.log_rate is None else self.log_rate)

    @classmethod
    def from_vehicle(cls, vehicle: VehicleProfile, **overrides) -> RobotSettings:
        """Settings with a vehicle profile's sensor noise and encoder resolution."""
        keys = {
            "position_noise": float(vehicle.position_sigma),
            "heading_noise": float(vehicle.heading_sigma),
        }
        if vehicle.ticks_per_revolution is not None:
            keys["ticks_per_revolution"] = int(vehicle.ticks_per_revolution)
        return cls(**{**keys, **overrides})

    def stream_settings(self) -> StreamSettings:
        """The :class:`StreamSettings` equivalent (``truth.json``'s ``streams``)."""
        return StreamSettings(
            gnss_rate=self.pose_rate,
            wheel_rate=self.wheel_rate,
            position_noise=self.position_noise,
            heading_noise=self.heading_noise,
            wheel_kind="ticks",
            ticks_per_revolution=self.ticks_per_revolution,
            clock_jitter=self.clock_jitter,
        )
