"""Synthetic drives of a rigid car with the paper's measurement noise.

A random route (:mod:`graphcal.simulate.route`) is driven with a speed profile limited by
lateral and longitudinal acceleration, sampled at 40 Hz. The car is one rigid body on a
single-track model: the route is its heading's curvature along the rear axle's path, the
rear axle moves along the heading turned by the rear tyres' slip angle (the lateral force
over the rear cornering stiffness, so it grows with the lateral acceleration; none for a
kinematic car), and the centre of gravity is ``l_r`` ahead of the rear axle on the body's
axis. The sideslip ``beta`` is the centre of gravity's, the lateral acceleration the body's
at the centre of gravity; the wheel rotations are eqs. (2)–(3) inverted with
``theta_true`` for each step's longitudinal travel and yaw, so the noise-free log satisfies
eq. (1) (:mod:`graphcal.model`) exactly. Gaussian noise at the paper's levels (§3.3) is
then added.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graphcal.files import atomic_write_text
from graphcal.log.drive_log import DriveLog, write_drive_log
from graphcal.model import PARAMETER_NAMES, wheel_rotations_for_motion, wrap_angle
from graphcal.simulate.route import ROUTES, Route

if TYPE_CHECKING:
    from graphcal.simulate.defect_settings import Defects

#: Default true parameters, away from nominal: [1.985 m, 1.2 mm, 1.585 m, 1.5 mm·s²/m] in SI.
THETA_TRUE_DEFAULT = np.array([1.985, 1.2e-3, 1.585, 1.5e-3])


@dataclass(frozen=True)
class NoiseLevels:
    """Standard deviations of the additive Gaussian measurement noise (SI).

    Defaults are the paper's (§3.3): position 0.2 m, heading 1.5°, wheel rotation 0.0005 rev.
    """

    position: float = 0.2
    heading: float = float(np.deg2rad(1.5))
    wheel_rotation: float = 0.0005
    sideslip: float = 0.0
    lateral_acceleration: float = 0.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"noise level {name} must be a finite number >= 0, got {value}")


@dataclass(frozen=True)
class VehicleMotion:
    """Driving-style and vehicle constants of the simulation (SI).

    Attributes:
        lateral_acceleration_limit, acceleration_limit, deceleration_limit: [m/s²] of the
            speed profile.
        start_speed: [m/s] at the route's ends.
        rear_axle_to_cg: ``l_r`` [m], the centre of gravity ahead of the rear axle.
        wheelbase: ``L`` [m].
        mass: [kg].
        rear_cornering_stiffness: [N/rad] of the rear axle (both tyres): its slip angle is
            the lateral force it carries, ``mass · a_y · (L - l_r) / L``, over this.
            ``math.inf``: a kinematic car, whose rear axle never moves sideways.
    """

    lateral_acceleration_limit: float = 2.5
    acceleration_limit: float = 1.5
    deceleration_limit: float = 2.0
    start_speed: float = 3.0
    rear_axle_to_cg: float = 1.35
    wheelbase: float = 2.7
    mass: float = 1500.0
    rear_cornering_stiffness: float = 160_000.0

    def __post_init__(self) -> None:
        if not (0.0 <= self.rear_axle_to_cg <= self.wheelbase and self.wheelbase > 0):
            raise ValueError(
                f"need 0 <= rear_axle_to_cg <= wheelbase, got {self.rear_axle_to_cg} m and "
                f"{self.wheelbase} m"
            )
        if not (self.mass > 0 and self.rear_cornering_stiffness > 0):
            raise ValueError("mass and rear_cornering_stiffness must be positive")

    @property
    def rear_slip_gain(self) -> float:
        """The rear tyres' slip angle per lateral acceleration [rad per m/s²], steady state
        (0.0075 by default: 0.43° per m/s²)."""
        rear_share = (self.wheelbase - self.rear_axle_to_cg) / self.wheelbase
        return self.mass * rear_share / self.rear_cornering_stiffness


@dataclass(frozen=True)
class SyntheticDrive:
    """A simulated drive: the measured (noisy) log, the noise-free truth and how it was made.

    ``defects`` (with the seed of their random choices, ``defect_seed``) are the defects of
    real logs :func:`graphcal.simulate.defects.degrade` added to ``measured``; ``None``: a
    clean drive.
    """

    measured: DriveLog
    truth: DriveLog
    theta_true: np.ndarray
    noise: NoiseLevels
    seed: int
    length_km: float
    motion: VehicleMotion = field(default_factory=VehicleMotion)
    route: str = "city"
    theta_change: ThetaStep | None = None
    defects: Defects | None = None
    defect_seed: int | None = None


@dataclass(frozen=True)
class ThetaStep:
    """A sudden change of the true parameters during a drive (e.g. a tyre-pressure drop).

    Attributes:
        at_km: travelled distance [km] where ``theta_after`` replaces ``theta_true``.
        theta_after: the parameters from then on (SI).
    """

    at_km: float
    theta_after: np.ndarray


def _speed_profile(
    arc_length: np.ndarray, curvature: np.ndarray, speed_limit: np.ndarray, motion: VehicleMotion
) -> np.ndarray:
    """Fastest speed [m/s] within the limits, as closed-form cumulative minima (no loop).

    Forward: v(s)² <= v(s')² + 2 a_acc (s - s') for s' <= s; backward likewise with a_dec.
    """
    v_max = np.minimum(
        speed_limit,
        np.sqrt(motion.lateral_acceleration_limit / np.maximum(np.abs(curvature), 1e-9)),
    )
    v_max[0] = v_max[-1] = motion.start_speed
    v2 = v_max**2
    a, b = 2.0 * motion.acceleration_limit, 2.0 * motion.deceleration_limit
    forward = a * arc_length + np.minimum.accumulate(v2 - a * arc_length)
    backward = -b * arc_length + np.minimum.accumulate((v2 + b * arc_length)[::-1])[::-1]
    return np.sqrt(np.minimum(forward, backward))


def simulate_drive(
    length_km: float = 24.0,
    seed: int = 0,
    theta_true: np.ndarray = THETA_TRUE_DEFAULT,
    noise: NoiseLevels | None = None,
    dt: float = 0.025,
    motion: VehicleMotion | None = None,
    route: str = "city",
    theta_change: ThetaStep | None = None,
) -> SyntheticDrive:
    """Simulate a city/suburban drive of ``length_km`` km sampled every ``dt`` seconds.

    Args:
        length_km: route length [km].
        seed: seed of every random choice (route and noise); same seed, same drive.
        theta_true: true parameters ``[c_e, c_d, t_r, d]`` (SI) used to make wheel rotations.
        noise: measurement noise levels (default: the paper's).
        dt: sampling interval [s] (paper: 0.025 s).
        motion: driving-style constants.
        route: ``"city"`` (bends, turns, roundabouts; the paper's kind of drive) or
            ``"straight"`` (a straight road, where t_r and d are not observable).
        theta_change: optional change of the true theta part-way (``theta_true`` before it).
    """
    if not length_km > 0:
        raise ValueError(f"drive length must be positive, got {length_km} km")
    if not dt > 0:
        raise ValueError(f"sampling interval must be positive, got {dt} s")
    if route not in ROUTES:
        raise ValueError(f"unknown route {route!r}; use one of {', '.join(ROUTES)}")
    noise = noise or NoiseLevels()
    motion = motion or VehicleMotion()
    theta_true = np.asarray(theta_true, dtype=float)
    route_seed, noise_seed, heading_seed = np.random.SeedSequence(seed).spawn(3)

    path = ROUTES[route](1000.0 * length_km, np.random.default_rng(route_seed))
    heading0 = np.random.default_rng(heading_seed).uniform(-np.pi, np.pi)
    sampled = _sampled_motion(path, motion, dt, heading0)
    truth = _true_log(sampled, theta_true, motion, theta_change)
    measured = _measured_log(truth, noise, np.random.default_rng(noise_seed))
    return SyntheticDrive(
        measured, truth, theta_true, noise, int(seed), float(length_km), motion, route, theta_change
    )


@dataclass(frozen=True)
class _SampledMotion:
    """The route driven, at the sampling times: time ``t`` [s], travelled distance
    ``distance`` [m], ``speed`` [m/s], ``curvature`` [1/m] and ``course`` [rad]."""

    t: np.ndarray
    distance: np.ndarray
    speed: np.ndarray
    curvature: np.ndarray
    course: np.ndarray


def _sampled_motion(
    path: Route, motion: VehicleMotion, dt: float, heading0: float
) -> _SampledMotion:
    """The route driven with its speed profile, resampled every ``dt`` [s]: time along the
    route by the trapezoidal rule on ds / v, the course integrated from ``heading0`` [rad]."""
    s, kappa = path.arc_length, path.curvature
    speed = _speed_profile(s, kappa, path.speed_limit, motion)
    time_at_s = np.concatenate([[0.0], np.cumsum(2.0 * np.diff(s) / (speed[1:] + speed[:-1]))])
    course_at_s = np.concatenate([[0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s))])
    t = np.arange(0.0, time_at_s[-1], dt)
    s_t = np.interp(t, time_at_s, s)
    v_t = np.interp(t, time_at_s, speed)
    kappa_t = np.interp(s_t, s, kappa)
    course_t = heading0 + np.interp(s_t, s, course_at_s)
    return _SampledMotion(t, s_t, v_t, kappa_t, course_t)


def _rigid_body_path(
    sampled: _SampledMotion, motion: VehicleMotion
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body's motion at the sampling times: the centre of gravity's positions ``(N, 2)``
    [m], the heading ``(N,)`` [rad] and the rear tyres' slip angle ``(N,)`` [rad].

    The heading is the route's course (its curvature integrated along the rear axle's path);
    the rear axle moves at ``speed`` along the heading plus the slip angle, each step an arc
    between the samples (exact for a course changing linearly over the step); the centre of
    gravity is ``l_r`` ahead of it on the body's axis."""
    heading, speed = sampled.course, sampled.speed
    slip = -motion.rear_slip_gain * speed**2 * sampled.curvature  # steady-state a_y
    direction = heading + slip
    travel = np.diff(sampled.distance)
    turn = np.diff(direction)
    middle = direction[:-1] + 0.5 * turn
    chord = travel * np.sinc(turn / (2.0 * np.pi))  # np.sinc(x) = sin(pi x) / (pi x)
    rear = np.zeros((len(heading), 2))
    np.cumsum(chord * np.cos(middle), out=rear[1:, 0])
    np.cumsum(chord * np.sin(middle), out=rear[1:, 1])
    cg = rear + motion.rear_axle_to_cg * np.column_stack([np.cos(heading), np.sin(heading)])
    return cg, heading, slip


def _body_lateral_acceleration(
    t: np.ndarray, position: np.ndarray, heading: np.ndarray
) -> np.ndarray:
    """The acceleration [m/s²] of the point at ``position (N, 2)`` across the heading (left
    positive), by second differences over the samples (the ends repeat their neighbours)."""
    acceleration = np.gradient(np.gradient(position, t, axis=0), t, axis=0)
    lateral = -acceleration[:, 0] * np.sin(heading) + acceleration[:, 1] * np.cos(heading)
    lateral[0], lateral[-1] = lateral[1], lateral[-2]
    return lateral


def _true_log(
    sampled: _SampledMotion,
    theta_true: np.ndarray,
    motion: VehicleMotion,
    theta_change: ThetaStep | None,
) -> DriveLog:
    """The noise-free log of the rigid car (:func:`_rigid_body_path`): per step the yaw
    increment, the centre of gravity's chord, its sideslip to the step's mean heading and the
    longitudinal travel (the chord along that heading); the wheel rotations eqs. (2)–(3)
    inverted for them. Eq. (1) with that sideslip reproduces the positions to rounding."""
    cg, heading, _ = _rigid_body_path(sampled, motion)
    lateral_acceleration = _body_lateral_acceleration(sampled.t, cg, heading)
    yaw_increment = np.diff(heading)
    chord = np.diff(cg, axis=0)
    chord_course = np.arctan2(chord[:, 1], chord[:, 0])
    sideslip = wrap_angle(chord_course - heading[:-1] - 0.5 * yaw_increment)
    length = np.hypot(chord[:, 0], chord[:, 1])
    sideslip = np.where(length > 0, sideslip, 0.0)  # standing: no direction to have
    distance = length * np.cos(sideslip)
    n_rl, n_rr = wheel_rotations_for_motion(
        distance, yaw_increment, lateral_acceleration[:-1], theta_true
    )
    if theta_change is not None:  # the same motion, rolled by the other wheels from then on
        change = int(np.searchsorted(sampled.distance[:-1], 1000.0 * theta_change.at_km))
        after_rl, after_rr = wheel_rotations_for_motion(
            distance, yaw_increment, lateral_acceleration[:-1], theta_change.theta_after
        )
        n_rl[change:], n_rr[change:] = after_rl[change:], after_rr[change:]
    # The last sample's inputs drive no step; repeat the previous ones.
    return DriveLog(
        t=sampled.t,
        px=cg[:, 0],
        py=cg[:, 1],
        psi=heading,
        n_rl=np.append(n_rl, n_rl[-1]),
        n_rr=np.append(n_rr, n_rr[-1]),
        beta=np.append(sideslip, sideslip[-1]),
        ay=lateral_acceleration,
        source="<synthetic truth>",
    )


def _measured_log(truth: DriveLog, noise: NoiseLevels, rng: np.random.Generator) -> DriveLog:
    """``truth`` with Gaussian noise at ``noise``'s levels, drawn signal by signal."""
    n = len(truth.t)
    return DriveLog(
        t=truth.t.copy(),
        px=truth.px + noise.position * rng.standard_normal(n),
        py=truth.py + noise.position * rng.standard_normal(n),
        psi=truth.psi + noise.heading * rng.standard_normal(n),
        n_rl=truth.n_rl + noise.wheel_rotation * rng.standard_normal(n),
        n_rr=truth.n_rr + noise.wheel_rotation * rng.standard_normal(n),
        beta=truth.beta + noise.sideslip * rng.standard_normal(n),
        ay=truth.ay + noise.lateral_acceleration * rng.standard_normal(n),
        source="<synthetic>",
    )


def truth_path(csv_path: str | os.PathLike[str]) -> Path:
    """Where the noise-free signals of a synthetic drive written to ``csv_path`` live."""
    p = Path(csv_path)
    return p.with_name(f"{p.stem}_truth.csv")


def sidecar_path(csv_path: str | os.PathLike[str]) -> Path:
    """The JSON sidecar of a synthetic drive written to ``csv_path``."""
    p = Path(csv_path)
    return p.with_name(f"{p.stem}.json")


def write_synthetic_drive(drive: SyntheticDrive, csv_path: str | os.PathLike[str]) -> list[Path]:
    """Write the measured CSV, the noise-free ``*_truth.csv`` and the ``*.json`` sidecar.

    The sidecar names a degraded drive's defects (``"defects"``: their names, settings in SI
    units and seed). Each file is written atomically, and the three as a set: an interrupt
    or a failure part-way removes those already written (a drive without its truth is none).
    Returns the three paths.
    """
    csv_path = Path(csv_path)
    paths = [csv_path, truth_path(csv_path), sidecar_path(csv_path)]
    try:
        write_drive_log(drive.measured, paths[0])
        write_drive_log(drive.truth, paths[1])
        atomic_write_text(paths[2], json.dumps(_sidecar(drive, paths[1]), indent=2) + "\n")
    except BaseException:
        for path in paths:
            path.unlink(missing_ok=True)
        raise
    return paths


def _sidecar(drive: SyntheticDrive, truth_csv: Path) -> dict:
    """The JSON sidecar's content of ``drive`` (its truth in ``truth_csv``)."""
    from graphcal import __version__

    meta = {
        "generator": f"graphcal {__version__} simulate",
        "seed": drive.seed,
        "length_km": drive.length_km,
        "route": drive.route,
        "dt_s": float(drive.measured.dt),
        "samples": len(drive.measured),
        "theta_true": dict(zip(PARAMETER_NAMES, map(float, drive.theta_true), strict=True)),
        "theta_units": {"c_e": "m", "c_d": "m", "t_r": "m", "d": "s^2 (m per m/s^2)"},
        "noise": {
            "position_m": drive.noise.position,
            "heading_rad": drive.noise.heading,
            "wheel_rotation_rev": drive.noise.wheel_rotation,
            "sideslip_rad": drive.noise.sideslip,
            "lateral_acceleration_m_s2": drive.noise.lateral_acceleration,
        },
        "motion": asdict(drive.motion),
        "truth_file": truth_csv.name,
    }
    if drive.theta_change is not None:
        meta["theta_change"] = {
            "at_km": drive.theta_change.at_km,
            "theta_after": dict(
                zip(PARAMETER_NAMES, map(float, drive.theta_change.theta_after), strict=True)
            ),
        }
    if drive.defects is not None:
        meta["defects"] = {"seed": drive.defect_seed, **drive.defects.to_dict()}
    return meta


def read_sidecar(csv_path: str | os.PathLike[str], n_samples: int | None = None) -> dict | None:
    """The sidecar of a synthetic drive (``theta_true`` as an SI array), or ``None``.

    ``None`` unless ``<stem>.json`` next to the CSV is a graphcal simulation sidecar (valid
    JSON from ``graphcal simulate`` with a finite ``theta_true``) and, when ``n_samples`` is
    given, describes a log of that many samples — so unrelated JSON or a stale sidecar is
    never mistaken for the truth.
    """
    path = sidecar_path(csv_path)
    try:
        meta = json.loads(path.read_text())
        if not str(meta.get("generator", "")).startswith("graphcal"):
            return None
        theta = np.array([float(meta["theta_true"][name]) for name in PARAMETER_NAMES])
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None
    if not np.all(np.isfinite(theta)):
        return None
    if n_samples is not None and meta.get("samples") != n_samples:
        return None
    if "theta_change" in meta:  # no single true theta to compare a calibration with
        return None
    meta["theta_true"] = theta
    return meta
