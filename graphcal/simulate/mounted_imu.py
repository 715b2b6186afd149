"""A synthetic recording's IMU mounted at an angle: 3-axis specific force and angular velocity
in the IMU's own frame, with the manifest keys that rotate them back
(:mod:`graphcal.recording.imu.mounting`).

The vehicle frame's signals are the noise-free drive's: longitudinal acceleration the
derivative of the true speed, lateral acceleration and yaw rate as the vehicle-frame IMU of
:func:`graphcal.simulate.streams.simulate_streams` has them, gravity up, roll and pitch rates
zero. :func:`mount_imu` rotates them into the IMU's frame and adds white noise.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from graphcal.recording.imu.frame import rotation, to_sensor
from graphcal.recording.vocabulary import GRAVITY
from graphcal.simulate.streams import EPOCH, SyntheticRecording


@dataclass(frozen=True)
class MountedImuRecording(SyntheticRecording):
    """A :class:`SyntheticRecording` whose ``imu`` holds ``t, ax, ay, az, wx, wy, wz`` in the
    IMU's frame [m/s², rad/s]; ``recording`` keeps the vehicle-frame IMU (what an import
    should give back, but for the noise).

    Attributes:
        mounting: ``(roll, pitch, yaw)`` [deg] of the IMU in the vehicle frame (vehicle =
            Rz(yaw) · Ry(pitch) · Rx(roll) · IMU).
        estimate: the manifest says ``mounting = "estimate"`` instead of the angles.
    """

    mounting: tuple[float, float, float] = (0.0, 0.0, 0.0)
    estimate: bool = False

    def manifest(self) -> str:
        """The base manifest with its ``[imu]`` section naming the 3-axis columns."""
        text = super().manifest()
        start = text.index("\n[imu]\n")
        end = text.find("\n[", start + 1)
        mounting = (
            '"estimate"' if self.estimate else "[" + ", ".join(map(repr, self.mounting)) + "]"
        )
        section = (
            '\n[imu]\nfile = "imu.csv"\ntime = "t"\n'
            'acceleration = ["ax", "ay", "az"]  # m/s², the IMU\'s frame, gravity included\n'
            'angular_velocity = ["wx", "wy", "wz"]  # rad/s\n'
            f"mounting = {mounting}  # roll, pitch, yaw [deg]: vehicle = Rz·Ry·Rx·IMU\n"
        )
        return text[:start] + section + ("" if end < 0 else text[end:])

    def metadata(self) -> dict:
        """``truth.json``'s ``imu_mounting_deg``: the true mounting."""
        roll, pitch, yaw = self.mounting
        return {
            **super().metadata(),
            "imu_mounting_deg": {"roll": roll, "pitch": pitch, "yaw": yaw},
        }


def vehicle_frame_imu(sim: SyntheticRecording, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The noise-free specific force [m/s²] and angular velocity [rad/s] ``(N, 3)`` in the
    vehicle frame at the times ``t`` [s, the streams' time base], of an IMU at the centre of
    gravity of the rigid car: its acceleration along and across the heading and ``g``, and
    ``(0, 0, ω_z)``."""
    truth = sim.drive.truth
    t_fine = EPOCH + truth.t
    middle = 0.5 * (t_fine[1:] + t_fine[:-1])  # rates hold between fine samples
    velocity = np.gradient(np.column_stack([truth.px, truth.py]), truth.t, axis=0)
    acceleration = np.gradient(velocity, truth.t, axis=0)
    longitudinal = acceleration[:, 0] * np.cos(truth.psi) + acceleration[:, 1] * np.sin(truth.psi)
    yaw_rate = np.diff(truth.psi) / np.diff(truth.t)
    force = np.column_stack(
        [
            np.interp(t, t_fine, longitudinal),
            np.interp(t, t_fine, truth.ay),
            np.full(len(t), GRAVITY),
        ]
    )
    rates = np.column_stack([np.zeros(len(t)), np.zeros(len(t)), np.interp(t, middle, yaw_rate)])
    return force, rates


def mount_imu(
    sim: SyntheticRecording,
    roll: float = 0.0,
    pitch: float = 0.0,
    yaw: float = 0.0,
    *,
    acceleration_noise: float = 0.05,
    angular_velocity_noise: float = 0.002,
    estimate: bool = False,
    seed: int = 0,
) -> MountedImuRecording:
    """``sim`` with its IMU mounted at ``roll``, ``pitch``, ``yaw`` [deg] (vehicle =
    Rz(yaw) · Ry(pitch) · Rx(roll) · IMU), sampled at the vehicle-frame IMU's times.

    Args:
        sim: a recording with an IMU stream.
        roll, pitch, yaw: the mounting [deg].
        acceleration_noise: white noise [m/s²] per axis and sample.
        angular_velocity_noise: white noise [rad/s] per axis and sample.
        estimate: write ``mounting = "estimate"`` in the manifest instead of the angles.
        seed: of the noise.
    """
    if sim.imu is None:
        raise ValueError("the recording has no IMU to mount")
    t = sim.imu["t"].to_numpy()
    force, rates = vehicle_frame_imu(sim, t)
    matrix = rotation(*np.radians([roll, pitch, yaw]))
    rng = np.random.default_rng(np.random.SeedSequence([seed, 28]))
    force = to_sensor(matrix, force) + acceleration_noise * rng.standard_normal(force.shape)
    rates = to_sensor(matrix, rates) + angular_velocity_noise * rng.standard_normal(rates.shape)
    imu = pd.DataFrame(
        {
            "t": t,
            **{f"a{axis}": force[:, i] for i, axis in enumerate("xyz")},
            **{f"w{axis}": rates[:, i] for i, axis in enumerate("xyz")},
        }
    )
    base = {f.name: getattr(sim, f.name) for f in fields(SyntheticRecording)}
    base["imu"] = imu
    return MountedImuRecording(
        **base, mounting=(float(roll), float(pitch), float(yaw)), estimate=estimate
    )
