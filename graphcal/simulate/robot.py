"""A differential-drive robot in a motion-capture hall, as raw sensor streams.

The robot drives ``runs`` runs of 5–15 m (straight and gently curved, some arcs of small
radius, 0.1–1.5 m/s with acceleration and deceleration ramps), each ended by a stop and
followed by a spin on the spot (±90–360°, the wheels turning in opposite directions) that
points it roughly back to where it started, so that it stays in the hall; optionally it
reverses a little after every second run (:mod:`graphcal.simulate.robot_manoeuvres`). The
motion is simulated noise-free on a fine grid (:data:`FINE_DT`): the wheel rotations are
eqs. (2)–(3) inverted with ``theta_true`` and the true poses eq. (1) integrated from them
(:func:`graphcal.model.integrate`), so the truth is exactly the model's. The pose is the
axle midpoint: no sideslip, no lever arm.

The streams sample that truth as a lab records it, each on its own clock: motion-capture poses
(x, y [m] in the hall's frame, heading [rad] wrapped to ±π) at 20–100 Hz with 1 mm / 0.2°
noise, and the wheels' cumulative encoder counts (floored integers) at 100 Hz with timestamp
jitter. No IMU. :func:`graphcal.simulate.streams.write_streams` writes them as
``pose.csv``, ``wheels.csv``, ``manifest.toml`` and ``truth.json``;
:func:`graphcal.simulate.bags.write_bag` writes ``recording`` as a bag (nav_msgs/Odometry
and JointState positions).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
import pandas as pd

from graphcal.log.drive_log import DriveLog
from graphcal.model import integrate, partial_steps, wheel_rotations_for_motion, wrap_angle
from graphcal.recording.streams import PoseStream, Recording, WheelStream
from graphcal.simulate.drive import NoiseLevels, SyntheticDrive
from graphcal.simulate.robot_manoeuvres import MANOEUVRES, plan_manoeuvres
from graphcal.simulate.robot_settings import FINE_DT, RobotSettings
from graphcal.simulate.streams import EPOCH, SyntheticRecording, manifest_text
from graphcal.vehicle import VehicleProfile

#: Default true parameters [c_e m, c_d m, t_r m, d s²]: an 84 mm wheel (nominal 85 mm,
#: 0.267 m) on a 0.205 m track (nominal 0.200 m); a differential drive has no load transfer.
ROBOT_THETA_TRUE = np.array([0.2639, 0.1e-3, 0.205, 0.0])
#: The datasheet theta of data/vehicles/mocap_robot.toml that ROBOT_THETA_TRUE departs from.
ROBOT_THETA_NOMINAL = np.array([0.2670, 0.0, 0.200, 0.0])


def theta_true_for(vehicle: VehicleProfile) -> np.ndarray:
    """A true theta for simulating ``vehicle`` [m, m, m, s²]: :data:`ROBOT_THETA_TRUE` for the
    motion-capture robot's datasheet; for another profile the same departures from its
    nominal (c_e 1.2 % smaller, c_d 0.04 % of c_e, t_r 2.5 % wider, d its nominal)."""
    nominal = np.asarray(vehicle.theta_nominal, float)
    if np.array_equal(nominal, ROBOT_THETA_NOMINAL):
        return ROBOT_THETA_TRUE.copy()
    c_e = nominal[0] * ROBOT_THETA_TRUE[0] / ROBOT_THETA_NOMINAL[0]
    c_d = nominal[1] + c_e * ROBOT_THETA_TRUE[1] / ROBOT_THETA_TRUE[0]
    t_r = nominal[2] * ROBOT_THETA_TRUE[2] / ROBOT_THETA_NOMINAL[2]
    return np.array([c_e, c_d, t_r, nominal[3]])


@dataclass(frozen=True)
class RobotRecording(SyntheticRecording):
    """A simulated robot recording: the streams (``gnss`` is the motion-capture pose frame
    ``t, x, y, heading``; ``wheels`` ``t, rl, rr`` counts; no IMU), ``drive`` its drive-log
    view at ``robot.rate`` (``measured``: noisy poses and counted rotations; ``truth``), and
    the model-exact truth on the fine grid.

    Attributes:
        robot: how it was simulated.
        fine: noise-free truth at :data:`FINE_DT` (``t`` from 0): its poses are eq. (1)
            integrated from its wheel rotations with ``drive.theta_true``.
        manoeuvres: one row per manoeuvre: ``kind`` (:data:`MANOEUVRES`), ``start``, ``end``
            [s, fine time], ``distance`` [m, signed, along the path] and ``yaw`` [rad].
    """

    robot: RobotSettings = field(default_factory=RobotSettings)
    fine: DriveLog | None = None
    manoeuvres: pd.DataFrame = field(default_factory=pd.DataFrame)

    @property
    def total_distance(self) -> float:
        """Path length [m] driven, forwards and backwards."""
        rows = self.manoeuvres
        return float(rows["distance"].abs().sum())

    def manifest(self) -> str:
        """The manifest: x/y pose, tick counts, no IMU, ``rate`` the drive-log view's."""
        return manifest_text(self.settings, self.robot.rate, local_pose=True, imu=False)

    def metadata(self) -> dict:
        """``truth.json``'s ``streams`` (the robot's settings, SI) and the manoeuvres' totals."""
        counts = self.manoeuvres["kind"].value_counts()
        settings = asdict(self.robot)
        return {
            "streams": {k: list(v) if isinstance(v, tuple) else v for k, v in settings.items()},
            "manoeuvres": {kind: int(counts.get(kind, 0)) for kind in MANOEUVRES},
            "distance_m": self.total_distance,
        }


@dataclass(frozen=True)
class _FineTruth:
    """The noise-free motion on the fine grid: times ``t`` [s] from 0, eq. (1)'s ``inputs``
    ``(N, 4)`` and ``states`` ``(N+1, 3)`` with ``theta``, the cumulative wheel rotations
    [rev] by side (``rl``, ``rr``) and all of it as a drive log ``log``."""

    t: np.ndarray
    inputs: np.ndarray
    states: np.ndarray
    theta: np.ndarray
    cumulative: dict[str, np.ndarray]
    log: DriveLog

    def states_at(self, t: np.ndarray) -> np.ndarray:
        """The model's states ``(len(t), 3)`` at times ``t`` within the fine grid: eq. (1)
        over the part of the fine step each falls in (:func:`graphcal.model.partial_steps`)."""
        t_fine, states, inputs = self.t, self.states, self.inputs
        k = np.clip(np.searchsorted(t_fine, t, side="left") - 1, 0, len(inputs) - 1)
        fraction = np.clip((t - t_fine[k]) / (t_fine[k + 1] - t_fine[k]), 0.0, 1.0)
        pairs = np.stack([states[k], states[k + 1]], axis=1)  # (Q, 2, 3)
        (out,) = partial_steps(pairs, inputs[k][:, None, :], self.theta, fraction[:, None])
        out = out[:, 0, :]
        at_start = fraction == 0.0
        out[at_start] = states[k[at_start]]
        return out

    def counts(self, t: np.ndarray, offsets: np.ndarray, tpr: int) -> dict[str, np.ndarray]:
        """The encoders' cumulative counts at times ``t``: ``tpr`` ticks per revolution,
        floored, each counter from a random start ``offsets`` [ticks] within a tick."""
        return {
            side: np.floor(np.interp(t, self.t, cum) * tpr + offset).astype(np.int64)
            for (side, cum), offset in zip(self.cumulative.items(), offsets, strict=True)
        }


def _repeat_last(x: np.ndarray) -> np.ndarray:
    """``x`` with its last entry repeated: the last sample drives no step."""
    return np.append(x, x[-1])


def _per_row(cumulative: np.ndarray) -> np.ndarray:
    """Increments of a cumulative signal over each row's interval to the next."""
    return _repeat_last(np.diff(cumulative))


def _times(start: float, end: float, rate: float, jitter: float, rng) -> np.ndarray:
    t = np.arange(start, end, 1.0 / rate)
    if jitter > 0:
        t = t + rng.uniform(-jitter, jitter, len(t))
    return t


def simulate_robot(
    seed: int = 0,
    runs: int = 10,
    settings: RobotSettings | None = None,
    theta_true: np.ndarray = ROBOT_THETA_TRUE,
) -> RobotRecording:
    """Simulate a differential-drive robot's recording (module docstring).

    Args:
        seed: seed of every random choice (path, spins, stops, clocks, noise, counter
            offsets); same seed and settings, same recording.
        runs: number of runs (each 5–15 m by default), separated by stops and spins.
        settings: motion and sensors (default :class:`RobotSettings`).
        theta_true: true ``[c_e, c_d, t_r, d]`` [m, m, m, s²].

    Returns:
        A :class:`RobotRecording` for :func:`~graphcal.simulate.streams.write_streams` and
        :func:`~graphcal.simulate.bags.write_bag` (its ``recording``).
    """
    if not (isinstance(runs, int) and runs >= 1):
        raise ValueError(f"runs must be a whole number >= 1, got {runs!r}")
    s = settings or RobotSettings()
    theta_true = np.asarray(theta_true, dtype=float)
    if theta_true.shape != (4,) or not (theta_true[0] > 0 and theta_true[2] > 0):
        raise ValueError("theta_true must be [c_e, c_d, t_r, d] with c_e > 0 and t_r > 0")
    motion_seed, pose_seed, wheel_seed, log_seed = np.random.SeedSequence(seed).spawn(4)
    motion_rng = np.random.default_rng(motion_seed)
    heading0 = float(motion_rng.uniform(-math.pi, math.pi))
    distance, yaw, manoeuvres = plan_manoeuvres(runs, motion_rng, s, heading0)
    fine = _fine_truth(distance, yaw, heading0, theta_true)
    pose_frame = _motion_capture(fine, s, np.random.default_rng(pose_seed))
    wheel_frame, offsets = _encoders(fine, s, np.random.default_rng(wheel_seed))
    truth, measured = _drive_logs(fine, s, offsets, np.random.default_rng(log_seed))
    levels = NoiseLevels(position=s.position_noise, heading=s.heading_noise, wheel_rotation=0.0)
    total = float(np.sum(np.abs(distance)))
    drive = SyntheticDrive(
        measured, truth, theta_true, levels, int(seed), total / 1000.0, route="robot"
    )
    return RobotRecording(
        recording=_recording(pose_frame, wheel_frame, s.ticks_per_revolution),
        drive=drive,
        settings=s.stream_settings(),
        gnss=pose_frame,
        wheels=wheel_frame,
        imu=None,
        robot=s,
        fine=fine.log,
        manoeuvres=manoeuvres,
    )


def _fine_truth(
    distance: np.ndarray, yaw: np.ndarray, heading0: float, theta_true: np.ndarray
) -> _FineTruth:
    """Noise-free truth on the fine grid: eqs. (2)-(3) inverted, eq. (1) integrated."""
    n_steps = len(distance)
    t_fine = FINE_DT * np.arange(n_steps + 1)
    ay = distance * yaw / FINE_DT**2  # speed × yaw rate [m/s²]
    n_rl, n_rr = wheel_rotations_for_motion(distance, yaw, ay, theta_true)
    zero = np.zeros(n_steps)
    inputs = np.column_stack([n_rl, n_rr, zero, ay])
    states = integrate(np.array([0.0, 0.0, heading0]), inputs, theta_true)
    log = DriveLog(
        t=t_fine,
        px=states[:, 0],
        py=states[:, 1],
        psi=states[:, 2],
        n_rl=_repeat_last(n_rl),
        n_rr=_repeat_last(n_rr),
        beta=np.zeros(n_steps + 1),
        ay=_repeat_last(ay),
        source="<synthetic robot truth, fine>",
    )
    cumulative = {
        "rl": np.concatenate([[0.0], np.cumsum(n_rl)]),
        "rr": np.concatenate([[0.0], np.cumsum(n_rr)]),
    }
    return _FineTruth(t_fine, inputs, states, theta_true, cumulative, log)


def _motion_capture(fine: _FineTruth, s: RobotSettings, rng: np.random.Generator) -> pd.DataFrame:
    """Motion-capture poses ``t, x, y, heading``: its own clock (starts 0.3 s in, ends 0.2 s
    early), noisy, the heading wrapped."""
    end = float(fine.t[-1])
    first_pose = 0.3 + rng.uniform(0.0, 1.0 / s.pose_rate)
    t_pose = _times(first_pose, end - 0.2, s.pose_rate, 0.0, rng)
    true_pose = fine.states_at(t_pose)
    noise = rng.standard_normal((len(t_pose), 3)) * [
        s.position_noise,
        s.position_noise,
        s.heading_noise,
    ]
    measured_pose = true_pose + noise
    return pd.DataFrame(
        {
            "t": EPOCH + t_pose,
            "x": measured_pose[:, 0],
            "y": measured_pose[:, 1],
            "heading": wrap_angle(measured_pose[:, 2]),
        }
    )


def _encoders(
    fine: _FineTruth, s: RobotSettings, rng: np.random.Generator
) -> tuple[pd.DataFrame, np.ndarray]:
    """The encoders' cumulative counts ``t, rl, rr`` (floored, from a random start within a
    tick; starting 0.5 s in, with clock jitter) and those starts [ticks]."""
    offsets = rng.uniform(0.0, 1.0, 2)
    t_wheels = _times(0.5, float(fine.t[-1]), s.wheel_rate, s.clock_jitter, rng)
    counts = fine.counts(t_wheels, offsets, s.ticks_per_revolution)
    return pd.DataFrame({"t": EPOCH + t_wheels, **counts}), offsets


def _recording(pose_frame: pd.DataFrame, wheel_frame: pd.DataFrame, tpr: int) -> Recording:
    """The streams as the manifest reader would return them (SI, no IMU)."""
    return Recording(
        pose=PoseStream(
            t=pose_frame["t"].to_numpy(),
            x=pose_frame["x"].to_numpy(),
            y=pose_frame["y"].to_numpy(),
            heading=pose_frame["heading"].to_numpy(),
            sideslip=None,
            source="<synthetic motion capture>",
        ),
        wheels=WheelStream(
            t=wheel_frame["t"].to_numpy(),
            left=wheel_frame["rl"].to_numpy(dtype=float) / tpr,
            right=wheel_frame["rr"].to_numpy(dtype=float) / tpr,
            cumulative=True,
            source="<synthetic wheel encoders>",
            resolution=1.0 / tpr,
        ),
        imu=None,
        source="<synthetic robot streams>",
    )


def _drive_logs(
    fine: _FineTruth, s: RobotSettings, offsets: np.ndarray, rng: np.random.Generator
) -> tuple[DriveLog, DriveLog]:
    """The drive-log view at ``s.rate``, truth and measured: true states at the rows,
    rotations between rows; measured poses with the motion capture's noise and rotations
    from the counters (started at ``offsets``)."""
    tpr = s.ticks_per_revolution
    theta_true = fine.theta
    t_log = np.arange(0.0, float(fine.t[-1]) + 1e-9, 1.0 / s.rate)
    true_log = fine.states_at(t_log)
    true_rot = {side: _per_row(np.interp(t_log, fine.t, c)) for side, c in fine.cumulative.items()}
    counted = {
        side: _per_row(c.astype(float) / tpr)
        for side, c in fine.counts(t_log, offsets, tpr).items()
    }
    speed = 0.5 * (true_rot["rl"] + true_rot["rr"]) * theta_true[0] * s.rate
    yaw_rate = _per_row(true_log[:, 2]) * s.rate
    log_ay = speed * yaw_rate
    truth = DriveLog(
        t=t_log,
        px=true_log[:, 0],
        py=true_log[:, 1],
        psi=true_log[:, 2],
        n_rl=true_rot["rl"],
        n_rr=true_rot["rr"],
        beta=np.zeros(len(t_log)),
        ay=log_ay,
        source="<synthetic robot truth>",
    )
    log_noise = rng.standard_normal((len(t_log), 3)) * [
        s.position_noise,
        s.position_noise,
        s.heading_noise,
    ]
    measured = DriveLog(
        t=t_log.copy(),
        px=truth.px + log_noise[:, 0],
        py=truth.py + log_noise[:, 1],
        psi=truth.psi + log_noise[:, 2],
        n_rl=counted["rl"],
        n_rr=counted["rr"],
        beta=np.zeros(len(t_log)),
        ay=log_ay.copy(),
        source="<synthetic robot>",
        tick_resolution=1.0 / tpr,
    )
    return truth, measured
