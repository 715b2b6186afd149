"""An independent twin of a recording: streams from a simulator graphcal's code did not build.

    python scripts/independent_twin.py --length-km 12 --seeds 0 1 2 --jobs 2

(every case of the default grid; restrict an axis with ``--rates 10``, ``--heading yes``,
``--imu no``, ``--wheels ticks``; ``--keep DIR`` keeps the recordings and results).
Other shapes (``--route``, several in one run; described below, after the town car):

    python scripts/independent_twin.py --route straight --lengths 1 2 6 24 --jobs 1
    python scripts/independent_twin.py --route skid-steer --jobs 1
    python scripts/independent_twin.py --route ticks-csv --jobs 1
    python scripts/independent_twin.py --route straight skid-steer ticks-csv --jobs 1

Why: graphcal's own simulator (``graphcal.simulate``) generates its data with the very model
graphcal calibrates (the paper's eqs. 1–3: rear-wheel rotations -> distance and yaw of the
centre of gravity, with a sideslip input), so it cannot show what a car that is *not* that
model does to the calibration. This script simulates a car with numpy and pandas only —
nothing from ``graphcal.simulate`` or ``graphcal.model`` — writes what its sensors would log
as CSV files with a streams manifest, and calibrates each recording with the ``graphcal``
command line in a subprocess (exactly what a user runs):

    graphcal calibrate DIR/manifest.toml --method whole --out DIR/result --workers 1

The car
-------
A kinematic single-track ("bicycle") model whose state is the REAR AXLE centre (x, y, yaw).
A random town route is built on arc length from straights, bends, crossroads turns,
roundabouts and chicanes, with smooth (raised-cosine) curvature transitions; its yaw
curvature kappa(s) = dyaw/ds is what the steering produces. The speed (3–15 m/s) follows a
target per piece — cruising, braking for traffic — limited to |lateral acceleration| <= 2.7
m/s² in the bends, with +1.5 m/s² acceleration and -2.5 m/s² braking (forward/backward
passes over the arc length). The rear axle moves along its heading (a kinematic bicycle has
no sideslip at the rear axle), except for a tyre slip angle beta_r = -k·a_y, k = 0.004 s²/m
(``--slip-k``; at most 0.7° at 3 m/s²), which rotates the rear axle's velocity away from the
heading, outwards in a bend. a_y is the rear axle's lateral acceleration in the body frame
(REP 103: positive left), differentiated from the trajectory, slip included.

Rear wheels roll along the heading: their path lengths are
ds_l = ds·cos(beta_r) - (t_r/2)·dyaw and ds_r = ds·cos(beta_r) + (t_r/2)·dyaw — the
brief's ds·(1 ∓ kappa·t_r/2) with ds the rear axle's travel along its heading (the cosine
differs from 1 by < 7e-5). Effective rolling circumferences c_l = c_e + c_d/2 + d·a_y,
c_r = c_e - c_d/2 - d·a_y with the TRUE theta = [c_e, c_d, t_r, d] = [1.99 m, 0.8 mm,
1.60 m, 0.0012 s²] (graphcal's parameter definition); rotations = path length / circumference.

The sensors (each on its own clock, absolute Unix-like time)
------------------------------------------------------------
* GNSS antenna 1.0 m ahead of and 0.3 m left of the rear axle, fixes at 1, 5 or 10 Hz
  (epochs at a random phase, timestamps with ±2 ms uniform jitter), white noise σ = 0.15 m
  per axis, as WGS-84 latitude/longitude around (47.5, 19.04). Optionally a heading
  (compass: 0 = north, clockwise; degrees; σ = 0.3°) — the body's heading, as an INS gives.
* Rear wheels at 100 Hz: speeds in m/s (rotation rate × the ECU's circumference 2.0 m,
  white noise 0.05 m/s) or cumulative tick counts (96 per revolution, each counter starting
  at a random phase).
* Optionally an IMU at 100 Hz at the rear axle: lateral acceleration (σ 0.05 m/s²) and yaw
  rate (σ 0.1°/s), REP 103 signs.

Geodesy: a spherical tangent plane, degrees = metres / (111320, 111320·cos lat0), is 0.12 %
off the WGS-84 meridian radius and 0.18 % off the prime-vertical one at 47.5° (and the fixed
cos lat0 another 3e-4 per 2 km north), while graphcal converts with the exact WGS-84
(pymap3d): the map would be stretched east and shrunk north, an error of the simulator, not
of graphcal (it mostly cancels over a route in all directions: c_e moved by +0.4 mm, 1.5σ,
at 10 Hz on seeds 0 and 1). So the default (``--geodesy wgs84``) puts the local
east/north/up frame's points on the WGS-84 ellipsoid exactly (ENU -> ECEF -> geodetic,
numpy; within 1e-6 m of pymap3d's inverse); ``--geodesy flat`` is the spherical plane.

What a user should expect (the physics differs from graphcal's model)
-------------------------------------------------------------------
* The antenna is not at graphcal's reference point (its "centre of gravity"): graphcal
  estimates a lever arm (antenna ahead/left of its reference point) in the joint solve. The
  reference point at which graphcal's model is right is the rear axle (the wheels measure
  its arcs and its velocity is along the heading), so the lever arm should come out near
  (+1.0, +0.3) m, and theta should be unbiased by the antenna's position.
* The rear wheels measure the rear axle's arcs: with the rear axle as the reference point,
  eq. 2 (distance = mean of the wheel arcs, yaw = their difference / t_r) holds exactly. No
  sideslip is logged (graphcal takes 0), right for the rear axle.
* The tyre slip angle is not in graphcal's model: the rear axle's course leaves the heading
  by -k·a_y (up to 0.7°), a lateral drift of some decimetres over a roundabout; graphcal
  gets no sideslip input for it. A lever arm ahead of the reference point makes a course
  offset ∝ a_y/v², the tyre's is ∝ a_y, so the lever arm absorbs part of it (and is biased
  short), the rest could move t_r and d (the parameters that read the bends).
  ``--slip-k 0`` removes it, a check of this simulator itself.

Measured (12 km, seeds 0–2, all 24 shapes; 18 min with 2 jobs on a busy 2-core machine): all
72 runs exit 0, trusted, every parameter within 3σ (worst |error/σ| 2.6, c_e at 10 Hz with
wheel speeds); mean (error/σ)² 1.04 (c_e), 0.40 (c_d), 0.49 (t_r), 0.46 (d). The lever arm
came out 0.81–0.98 m ahead (true 1.0: the slip absorbed) and 0.28–0.31 m left. With
``--slip-k 0`` (10 Hz, heading, IMU; 10 runs) it is 1.00 m ahead and all within 3σ.

Other shapes (``--route``)
--------------------------
``--route straight`` — a highway. The same car and sensors on a road of straights and very
wide bends (|curvature| <= 8e-5 1/m, ``--highway-curvature``; 0 is dead straight), 20-30
m/s per 300-1500 m piece with +0.3/-0.4 m/s² between them, recorded from mid-drive and cut
at the length (``--lengths``, default 1 2 6 24 km). Recorded by default as GNSS at 10 Hz
(σ 0.15 m, no heading), CAN wheel speeds, no IMU (``--rates``, ``--heading``, ``--imu``,
``--wheels`` override it). Expected: exit 0, c_e and c_d (relative to t_r) calibrated within
3σ, t_r and d "not observable".

``--route skid-steer`` — a small skid-steer robot outdoors, ``--robot-length-m`` (360) of
straights and arcs at 0.5-1.5 m/s, tight turns (radius 0.3-1 m), turns on the spot and
stops, in random order, the commands smoothed over 0.8 s. Its centre moves along its heading
at v = (v_l + v_r)/2 and turns at (v_r - v_l)/t_eff with the EFFECTIVE track t_eff = 1.08 m,
about twice the physical 0.55 m (the tracks slide sideways in turns); each side's speed is
its sprocket's rotation times the effective circumference c_e ± c_d/2 (true theta
[0.785 m, 0.6 mm, 1.08 m, 0]). Sensors: a consumer GPS at 2.5 Hz, σ 1 m per axis, white
(``--robot-gnss-tau S`` makes it a Gauss-Markov error with that correlation time), no
heading, its antenna 0.15 m behind the centre; an IMU at the centre at 100 Hz (lateral
acceleration σ 0.1 m/s², yaw rate σ 0.2°/s); each sprocket's angular speed [rad/s] at 50 Hz
(σ 0.05 rad/s). Calibrated with ``--vehicle data/vehicles/skid_steer_robot.toml`` (nominal:
the physical 0.55 m track, 0.80 m circumference, track prior σ 0.5 m), with and without
``--no-defect-model`` (``--defect-model yes no``). Expected: exit 0, c_e and t_r (the
effective track) calibrated within 3σ.

``--route ticks-csv`` — a 24 km town drive (the town car above) written as graphcal's
drive-log CSV at 40 Hz (t, px, py, psi, n_rl, n_rr, beta, ay) as a logger would: the antenna's
position (lever arm 1.0 m ahead, 0.3 m left) with 0.2 m white noise, a fused heading with
0.3° noise, each interval's wheel rotation the difference of two 96-tick counter readings
taken 15 ms before the row's time (wheels late), except the first row's (the rotation since
an instant between two counts: off the tick grid), beta 0 and the IMU's lateral acceleration
(σ 0.05 m/s²). Calibrated with defaults and with ``ticks_per_revolution = 96`` in a
``--config`` file's ``[vehicle]`` (``--tick-config no yes``). Expected: "wheel rotations are
counts of 96 ticks per revolution (found in the rotations)" and every parameter within 3σ.

The table
---------
Per run: the exit status of ``graphcal calibrate`` (0; 2 refused or failed; 3 when a trust
check fails), whether the run is trusted, error/σ per parameter against the case's TRUE
theta with graphcal's verdict where it is not plain "calibrated" (``given d``: calibrated
given d = prior; ``n/o``: not observable; ``fixed``: held by the vehicle profile), and how
the run departs from what its case expects. The summary: runs with every parameter that has
a σ within 3σ, mean (error/σ)² per parameter (1 when the σ are right); per case over its
seeds the worst |error/σ| and the mean (error/σ)²; then graphcal's own lines on the time
offset, the lever arm, the model check and the tick count, and its warnings and errors.
(``calibration.json`` holds the lever arm only when the model check keeps the defect model,
so the lines are read from graphcal's progress output, kept as ``calibrate.log`` beside each
result with the exact command in ``command.txt``.)
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

NAMES = ("c_e", "c_d", "t_r", "d")
#: The TRUE theta [c_e, c_d, t_r, d] in SI (m, m, m, s²).
THETA_TRUE = np.array([1.99, 0.0008, 1.60, 0.0012])
#: Display scale of the errors in the summary (mm, mm, mm, mm·s²/m).
DISPLAY = {"c_e": 1e3, "c_d": 1e3, "t_r": 1e3, "d": 1e3}

LAT0, LON0 = 47.5, 19.04
ANTENNA = (1.0, 0.3)  # m ahead of, left of the rear axle
ECU_CIRCUMFERENCE = 2.0
TICKS_PER_REV = 96
DS = 0.05  # m, arc-length grid of the drive
A_LAT_MAX = 2.7  # m/s², the driver's limit in bends (actual |a_y| stays <= 3)
A_ACCEL, A_BRAKE = 1.5, 2.5  # m/s²
V_MIN, V_MAX = 3.0, 15.0
DEG = math.pi / 180.0
#: The highway (``--route straight``): target speeds, acceleration and braking, and the
#: largest |curvature| of its wide bends [1/m] (``--highway-curvature``).
HIGHWAY_SPEED = (20.0, 30.0)
HIGHWAY_ACCEL = (0.3, 0.4)
HIGHWAY_CURVATURE = 8e-5


# ------------------------------------------------------------------------------------------
# The drive
# ------------------------------------------------------------------------------------------


class _Route:
    """Yaw curvature and a target speed over arc length, piece by piece."""

    def __init__(self) -> None:
        self.kappa: list[np.ndarray] = []
        self.target: list[np.ndarray] = []

    @property
    def length(self) -> float:
        return DS * sum(len(k) for k in self.kappa)

    def _add(self, kappa: np.ndarray, target: float) -> None:
        self.kappa.append(kappa)
        self.target.append(np.full(len(kappa), target))

    def straight(self, length: float, target: float) -> None:
        self._add(np.zeros(max(round(length / DS), 1)), target)

    def turn(self, radius: float, angle: float, ramp: float, target: float) -> None:
        """Turn by ``angle`` [rad] (sign = side) at ``radius`` with raised-cosine ramps of
        curvature (each ramp turns half its length's worth of full curvature)."""
        peak = 1.0 / radius
        ramp = min(ramp, abs(angle) / peak)  # ramps alone turn peak·ramp
        hold = abs(angle) / peak - ramp
        n_ramp, n_hold = max(round(ramp / DS), 2), round(hold / DS)
        rise = 0.5 * (1.0 - np.cos(np.pi * (np.arange(n_ramp) + 0.5) / n_ramp))
        shape = np.concatenate([rise, np.ones(n_hold), rise[::-1]])
        self._add(math.copysign(peak, angle) * shape, target)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.concatenate(self.kappa), np.concatenate(self.target)


def make_route(length: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Yaw curvature [1/m] and target speed [m/s] on the arc-length grid, >= ``length`` m."""
    route = _Route()
    route.straight(60.0, 8.0)
    while route.length < length:
        cruise = rng.uniform(9.0, V_MAX)
        side = rng.choice([-1.0, 1.0])
        kind = rng.choice(
            ["bend", "crossroads", "roundabout", "chicane", "traffic"],
            p=[0.28, 0.30, 0.20, 0.16, 0.06],
        )
        route.straight(rng.uniform(10.0, 90.0), cruise)
        if kind == "bend":
            route.turn(
                rng.uniform(20.0, 120.0), side * rng.uniform(30.0, 150.0) * DEG,
                rng.uniform(10.0, 30.0), cruise,
            )  # fmt: skip
        elif kind == "crossroads":
            slow = rng.uniform(4.0, 7.0)
            route.straight(15.0, slow)
            route.turn(rng.uniform(6.0, 14.0), side * rng.uniform(80.0, 100.0) * DEG, 4.0, slow)
        elif kind == "roundabout":  # right-hand traffic: in to the right, round to the left
            slow = rng.uniform(5.0, 7.0)
            route.turn(20.0, -30.0 * DEG, 5.0, slow)
            route.turn(
                rng.uniform(11.0, 20.0), rng.choice([100.0, 190.0, 280.0, 340.0]) * DEG,
                rng.uniform(3.0, 6.0), slow,
            )  # fmt: skip
            route.turn(20.0, -30.0 * DEG, 5.0, slow)
        elif kind == "chicane":
            radius, angle = rng.uniform(25.0, 80.0), rng.uniform(25.0, 60.0) * DEG
            route.turn(radius, side * angle, 10.0, cruise)
            route.straight(rng.uniform(0.0, 15.0), cruise)
            route.turn(radius, -side * angle, 10.0, cruise)
        else:  # traffic: brake to walking pace, then go on
            route.straight(rng.uniform(20.0, 60.0), rng.uniform(V_MIN, 5.0))
    route.straight(60.0, 8.0)
    return route.arrays()


def speed_profile(
    kappa: np.ndarray,
    target: np.ndarray,
    v_range: tuple[float, float] = (V_MIN, V_MAX),
    accel: tuple[float, float] = (A_ACCEL, A_BRAKE),
    v_start: float | None = 5.0,
) -> np.ndarray:
    """Speed [m/s] on the grid: the target, the bends' lateral-acceleration limit, and
    bounded acceleration and braking (a forward and a backward pass). ``v_start`` caps the
    first sample's speed (``None``: the recording starts at the target, mid-drive)."""
    limit = np.minimum(target, np.sqrt(A_LAT_MAX / np.maximum(np.abs(kappa), 1e-9)))
    limit = np.clip(limit, *v_range)
    v2 = limit**2
    out = v2.copy()
    if v_start is not None:
        out[0] = min(out[0], v_start**2)
    up, down = 2.0 * accel[0] * DS, 2.0 * accel[1] * DS
    for i in range(1, len(out)):  # forward: acceleration
        out[i] = min(out[i], out[i - 1] + up)
    for i in range(len(out) - 2, -1, -1):  # backward: braking
        out[i] = min(out[i], out[i + 1] + down)
    return np.sqrt(out)


def make_highway_route(
    length: float, rng: np.random.Generator, max_curvature: float = HIGHWAY_CURVATURE
) -> tuple[np.ndarray, np.ndarray]:
    """A highway's yaw curvature [1/m] and target speed [m/s], >= ``length`` m: straights
    and very wide bends (radius >= 1 / ``max_curvature``, 0: dead straight), either side,
    each piece 300-1500 m at a target of 20-30 m/s."""
    route = _Route()
    while route.length < length:
        target = rng.uniform(*HIGHWAY_SPEED)
        piece = rng.uniform(300.0, 1500.0)
        if max_curvature > 0 and rng.uniform() < 0.5:
            radius = 1.0 / rng.uniform(0.25 * max_curvature, max_curvature)
            route.turn(radius, rng.choice([-1.0, 1.0]) * piece / radius, 200.0, target)
        else:
            route.straight(piece, target)
    return route.arrays()


def _cumtrapz(y: np.ndarray, dx: float | np.ndarray) -> np.ndarray:
    out = np.zeros_like(y, dtype=float)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * dx)
    return out


@dataclass
class Drive:
    """The rear axle's motion on the arc-length grid and the rear wheels' rotations."""

    t: np.ndarray  # s from the start
    x: np.ndarray  # m east (rear axle)
    y: np.ndarray  # m north
    yaw: np.ndarray  # rad, ENU (0 = east, counter-clockwise), unwrapped
    yaw_rate: np.ndarray  # rad/s
    ay: np.ndarray  # m/s², body-frame lateral acceleration of the rear axle (left +)
    rev_l: np.ndarray  # cumulative rotations of the rear-left wheel
    rev_r: np.ndarray
    rate_l: np.ndarray  # rev/s
    rate_r: np.ndarray
    slip: np.ndarray  # rad, tyre slip angle of the rear axle's velocity

    @property
    def length(self) -> float:
        return float(len(self.t) - 1) * DS


def simulate_drive(
    length: float,
    seed: int,
    slip_k: float,
    route: str = "town",
    max_curvature: float = 0.0,
) -> Drive:
    """A drive of >= ``length`` m with the TRUE theta: a town route (``route="town"``) or a
    highway (``"straight"``: curvature below ``max_curvature``, 20-30 m/s, accelerating at
    most 0.3 m/s² and braking 0.4 m/s², recorded from the middle of a drive)."""
    if route == "straight":
        rng = np.random.default_rng([seed, 20251, 1])
        kappa, target = make_highway_route(length, rng, max_curvature)
        n = round(length / DS) + 1  # the highway's pieces are long: cut it at ``length``
        kappa, target = kappa[:n], target[:n]
        v = speed_profile(kappa, target, HIGHWAY_SPEED, HIGHWAY_ACCEL, v_start=None)
    else:
        rng = np.random.default_rng([seed, 20251])
        kappa, target = make_route(length, rng)
        v = speed_profile(kappa, target)
    s = np.arange(len(kappa)) * DS
    t = np.concatenate([[0.0], np.cumsum(2.0 * DS / (v[1:] + v[:-1]))])
    yaw = rng.uniform(-np.pi, np.pi) + _cumtrapz(kappa, DS)
    a_steady = v**2 * kappa
    slip = -slip_k * a_steady
    course = yaw + slip  # direction of the rear axle's velocity
    x = _cumtrapz(np.cos(course), DS)
    y = _cumtrapz(np.sin(course), DS)
    dcourse_ds = np.gradient(course, s)
    dv_ds = np.gradient(v, s)
    # body-frame lateral acceleration: tangential part along the slip, centripetal part
    ay = v * dv_ds * np.sin(slip) + v**2 * dcourse_ds * np.cos(slip)
    c_e, c_d, t_r, d = THETA_TRUE
    c_l = c_e + 0.5 * c_d + d * ay
    c_r = c_e - 0.5 * c_d - d * ay
    along = np.cos(slip)  # the wheels roll along the heading
    per_m_l = (along - 0.5 * t_r * kappa) / c_l  # rotations per metre of the axle's path
    per_m_r = (along + 0.5 * t_r * kappa) / c_r
    return Drive(
        t=t, x=x, y=y, yaw=yaw, yaw_rate=v * kappa, ay=ay,
        rev_l=_cumtrapz(per_m_l, DS), rev_r=_cumtrapz(per_m_r, DS),
        rate_l=per_m_l * v, rate_r=per_m_r * v, slip=slip,
    )  # fmt: skip


# ------------------------------------------------------------------------------------------
# Geodesy (numpy only)
# ------------------------------------------------------------------------------------------

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


def enu_to_geodetic(east: np.ndarray, north: np.ndarray, flat: bool = False):
    """Latitude, longitude [deg] of local east/north metres around (LAT0, LON0) on the
    ground (the ellipsoid), or with the brief's spherical tangent-plane constants."""
    if flat:
        return LAT0 + north / 111320.0, LON0 + east / (111320.0 * math.cos(LAT0 * DEG))
    lat0, lon0 = LAT0 * DEG, LON0 * DEG
    up = -(east**2 + north**2) / (2.0 * 6371000.0)  # the plane's points dropped to the ground
    n0 = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(lat0) ** 2)
    x0 = n0 * math.cos(lat0) * math.cos(lon0)
    y0 = n0 * math.cos(lat0) * math.sin(lon0)
    z0 = n0 * (1.0 - WGS84_E2) * math.sin(lat0)
    sl, cl, sp, cp = math.sin(lon0), math.cos(lon0), math.sin(lat0), math.cos(lat0)
    x = x0 - sl * east - sp * cl * north + cp * cl * up
    y = y0 + cl * east - sp * sl * north + cp * sl * up
    z = z0 + cp * north + sp * up
    lon = np.arctan2(y, x)
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - WGS84_E2))
    for _ in range(6):
        n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
        h = p / np.cos(lat) - n
        lat = np.arctan2(z, p * (1.0 - WGS84_E2 * n / (n + h)))
    return lat / DEG, lon / DEG


# ------------------------------------------------------------------------------------------
# The streams
# ------------------------------------------------------------------------------------------


def _antenna(
    x: np.ndarray, y: np.ndarray, yaw: np.ndarray, antenna: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """East and north [m] of an antenna ``antenna`` = (ahead, left) [m] of the point at
    ``x``, ``y`` [m] on a body of heading ``yaw`` [rad]."""
    ahead, left = antenna
    east = x + ahead * np.cos(yaw) - left * np.sin(yaw)
    north = y + ahead * np.sin(yaw) + left * np.cos(yaw)
    return east, north


def _clock(start: float, end: float, rate: float, rng: np.random.Generator) -> np.ndarray:
    """Sample instants at ``rate`` with a random phase, from ``start`` to ``end``."""
    phase = rng.uniform(0.0, 1.0 / rate)
    return np.arange(start + phase, end, 1.0 / rate)


def write_streams(
    drive: Drive,
    directory: Path,
    gnss_rate: float,
    wheel_kind: str,
    seed: int,
    flat: bool,
) -> None:
    """Write gnss.csv, wheels.csv and imu.csv of one recording of ``drive`` into
    ``directory``; the noise depends on the seed, the GNSS rate and the wheel kind."""
    rng = np.random.default_rng([seed, int(gnss_rate * 10), 0 if wheel_kind == "speeds" else 1])
    directory.mkdir(parents=True, exist_ok=True)
    t_end = drive.t[-1]
    epoch = 1.76e9 + 86400.0 * seed + rng.uniform(0.0, 3600.0)

    def at(t: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.interp(t, drive.t, values)

    # GNSS: true epochs, stamped with jitter
    tg = _clock(rng.uniform(0.0, 1.0), t_end - rng.uniform(0.0, 1.0), gnss_rate, rng)
    yaw = at(tg, drive.yaw)
    east, north = _antenna(at(tg, drive.x), at(tg, drive.y), yaw, ANTENNA)
    east = east + 0.15 * rng.standard_normal(len(tg))
    north = north + 0.15 * rng.standard_normal(len(tg))
    lat, lon = enu_to_geodetic(east, north, flat)
    heading = np.mod(90.0 - np.degrees(yaw) + 0.3 * rng.standard_normal(len(tg)), 360.0)
    stamp = tg + rng.uniform(-0.002, 0.002, len(tg))
    gnss = pd.DataFrame({"t": epoch + stamp, "lat": lat, "lon": lon, "heading": heading})
    gnss.to_csv(directory / "gnss.csv", index=False, float_format="%.10f")

    # Rear wheels: 100 Hz, sampled when stamped (±0.5 ms bus jitter)
    tw = _clock(rng.uniform(0.0, 0.5), t_end - rng.uniform(0.0, 0.5), 100.0, rng)
    tw = tw + rng.uniform(-0.0005, 0.0005, len(tw))
    wheels = pd.DataFrame({"t": epoch + tw})
    if wheel_kind == "ticks":
        for col, rev in (("rl", drive.rev_l), ("rr", drive.rev_r)):
            phase = rng.uniform(0.0, 1.0)  # where within a tick each counter starts
            wheels[col] = np.floor(at(tw, rev) * TICKS_PER_REV + phase).astype(np.int64)
        wheels.to_csv(directory / "wheels.csv", index=False, float_format="%.6f")
    else:
        for col, rate in (("rl", drive.rate_l), ("rr", drive.rate_r)):
            speed = at(tw, rate) * ECU_CIRCUMFERENCE + 0.05 * rng.standard_normal(len(tw))
            wheels[col] = speed
        wheels.to_csv(directory / "wheels.csv", index=False, float_format="%.6f")

    # IMU at the rear axle: 100 Hz, REP 103 (y left, z up)
    ti = _clock(rng.uniform(0.0, 0.5), t_end - rng.uniform(0.0, 0.5), 100.0, rng)
    imu = pd.DataFrame(
        {
            "t": epoch + ti,
            "ay": at(ti, drive.ay) + 0.05 * rng.standard_normal(len(ti)),
            "wz": at(ti, drive.yaw_rate) + 0.1 * DEG * rng.standard_normal(len(ti)),
        }
    )
    imu.to_csv(directory / "imu.csv", index=False, float_format="%.6f")


def manifest_text(wheel_kind: str, heading: bool, imu: bool, prefix: str = "../") -> str:
    """A streams manifest over the CSV files in the parent directory."""
    lines = [
        "# Written by scripts/independent_twin.py (an independent simulator).",
        "rate = 40.0",
        "",
        "[gnss]",
        f'file = "{prefix}gnss.csv"',
        'time = "t"',
        'latitude = "lat"',
        'longitude = "lon"',
    ]
    if heading:
        lines += ['heading = "heading"', 'heading_unit = "deg"', 'heading_convention = "compass"']
    lines += ["", "[wheels]", f'file = "{prefix}wheels.csv"', 'time = "t"']
    lines += ['rear_left = "rl"', 'rear_right = "rr"']
    if wheel_kind == "ticks":
        lines += ['kind = "ticks"', f"ticks_per_revolution = {TICKS_PER_REV}"]
    else:
        lines += ['kind = "speed"', 'speed_unit = "m/s"', f"circumference = {ECU_CIRCUMFERENCE}"]
    if imu:
        lines += ["", "[imu]", f'file = "{prefix}imu.csv"', 'time = "t"']
        lines += ['lateral_acceleration = "ay"', 'yaw_rate = "wz"', 'yaw_rate_unit = "rad/s"']
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------
# A skid-steer robot (--route skid-steer)
# ------------------------------------------------------------------------------------------

#: The robot's TRUE theta: effective sprocket circumference 0.785 m (datasheet 0.80 m: the
#: tracks slip), left/right difference 0.6 mm, EFFECTIVE track 1.08 m (the physical one is
#: 0.55 m: a skid-steer vehicle turns as if its tracks were about twice as far apart), d 0.
ROBOT_THETA_TRUE = np.array([0.785, 0.0006, 1.08, 0.0])
ROBOT_PROFILE = Path(__file__).resolve().parents[1] / "data" / "vehicles" / "skid_steer_robot.toml"
ROBOT_ANTENNA = (-0.15, 0.0)  # m ahead of, left of the robot's centre (a mast at the back)
ROBOT_DT = 0.002  # s, the fine time grid of the robot's motion
ROBOT_GNSS_RATE, ROBOT_GNSS_SIGMA = 2.5, 1.0  # Hz, m per axis (a consumer receiver)
ROBOT_WHEEL_RATE, ROBOT_WHEEL_NOISE = 50.0, 0.05  # Hz, rad/s of a sprocket's angular speed
ROBOT_IMU_RATE = 100.0  # Hz
ROBOT_IMU_NOISE = (0.1, 0.2 * DEG)  # m/s² lateral acceleration (track vibration), rad/s yaw
ROBOT_YAW_RATE_MAX = 1.2  # rad/s while driving


@dataclass
class RobotDrive:
    """The robot's centre on the fine time grid, and its sprockets' angular speeds."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    v: np.ndarray  # m/s forward
    yaw_rate: np.ndarray  # rad/s
    ay: np.ndarray  # m/s², lateral, left +
    omega_l: np.ndarray  # rad/s of the left sprocket
    omega_r: np.ndarray
    kinds: dict  # manoeuvre kind -> count

    @property
    def length(self) -> float:
        return float(np.sum(np.abs(self.v[1:]) * np.diff(self.t)))


def _moving_average(x: np.ndarray, width: int) -> np.ndarray:
    kernel = np.ones(width) / width
    padded = np.concatenate([np.full(width, x[0]), x, np.full(width, x[-1])])
    return np.convolve(padded, kernel, mode="same")[width:-width]


def simulate_robot(length: float, seed: int, theta: np.ndarray = ROBOT_THETA_TRUE) -> RobotDrive:
    """A skid-steer robot driving >= ``length`` m outdoors: straights and arcs at 0.5-1.5
    m/s, tight turns (radius 0.3-1.0 m, yaw rate <= 1.2 rad/s), turns on the spot (60-270°)
    and stops, in random order. The commanded (v, yaw rate) are piecewise constant, then
    smoothed twice over 0.8 s (ramps of about 2 m/s² and 1.5 rad/s²). Skid steering: the
    centre moves along its heading at v = (v_l + v_r)/2 and turns at (v_r - v_l)/t_eff, the
    EFFECTIVE track; each side's speed is its sprocket's rotation rate times its effective
    circumference c_e ± c_d/2 (d = 0: no load transfer modelled)."""
    rng = np.random.default_rng([seed, 20252])
    v_cmd: list[np.ndarray] = []
    w_cmd: list[np.ndarray] = []
    kinds: dict[str, int] = {}

    def hold(v: float, w: float, seconds: float, kind: str) -> None:
        n = max(round(seconds / ROBOT_DT), 1)
        v_cmd.append(np.full(n, v))
        w_cmd.append(np.full(n, w))
        kinds[str(kind)] = kinds.get(str(kind), 0) + 1

    hold(0.0, 0.0, 3.0, "stop")
    planned = 0.0
    while planned < length:
        kind = rng.choice(
            ["straight", "arc", "tight", "spin", "stop"], p=[0.35, 0.28, 0.15, 0.15, 0.07]
        )
        side = rng.choice([-1.0, 1.0])
        if kind == "straight":
            v, dist = rng.uniform(0.5, 1.5), rng.uniform(5.0, 25.0)
            hold(v, rng.uniform(-0.03, 0.03), dist / v, kind)
            planned += dist
        elif kind == "arc":
            v, radius = rng.uniform(0.5, 1.5), rng.uniform(2.0, 10.0)
            angle = rng.uniform(30.0, 180.0) * DEG
            hold(v, side * v / radius, angle * radius / v, kind)
            planned += angle * radius
        elif kind == "tight":
            radius = rng.uniform(0.3, 1.0)
            v = min(rng.uniform(0.5, 0.7), ROBOT_YAW_RATE_MAX * radius)
            angle = rng.uniform(60.0, 180.0) * DEG
            hold(v, side * v / radius, angle * radius / v, kind)
            planned += angle * radius
        elif kind == "spin":
            rate, angle = rng.uniform(0.5, 1.0), rng.uniform(60.0, 270.0) * DEG
            hold(0.0, side * rate, angle / rate, kind)
        else:
            hold(0.0, 0.0, rng.uniform(0.5, 2.0), kind)
    hold(0.0, 0.0, 3.0, "stop")
    width = round(0.8 / ROBOT_DT)
    v = _moving_average(_moving_average(np.concatenate(v_cmd), width), width)
    w = _moving_average(_moving_average(np.concatenate(w_cmd), width), width)
    t = np.arange(len(v)) * ROBOT_DT
    yaw = rng.uniform(-np.pi, np.pi) + _cumtrapz(w, ROBOT_DT)
    x = _cumtrapz(v * np.cos(yaw), ROBOT_DT)
    y = _cumtrapz(v * np.sin(yaw), ROBOT_DT)
    c_e, c_d, t_r, _ = theta
    v_l, v_r = v - 0.5 * t_r * w, v + 0.5 * t_r * w
    omega_l = 2.0 * np.pi * v_l / (c_e + 0.5 * c_d)
    omega_r = 2.0 * np.pi * v_r / (c_e - 0.5 * c_d)
    ay = v * w  # at the centre, moving along its heading
    return RobotDrive(t, x, y, yaw, v, w, ay, omega_l, omega_r, kinds)


def gnss_noise(n: int, sigma: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` fixes' errors [m] of standard deviation ``sigma``: white (``tau`` 0) or a
    first-order Gauss-Markov process with a correlation time of ``tau`` fixes (a consumer
    receiver's error wanders: multipath, atmosphere)."""
    if tau <= 0:
        return sigma * rng.standard_normal(n)
    a = math.exp(-1.0 / tau)
    w = sigma * math.sqrt(1.0 - a * a) * rng.standard_normal(n)
    w[0] = sigma * rng.standard_normal()
    out = np.empty(n)
    out[0] = w[0]
    for k in range(1, n):
        out[k] = a * out[k - 1] + w[k]
    return out


def write_robot_streams(
    robot: RobotDrive, directory: Path, seed: int, gnss_tau: float = 0.0
) -> None:
    """gnss.csv (lat/lon at 2.5 Hz, 1 m noise per axis, white or with a correlation time of
    ``gnss_tau`` s, no heading), wheels.csv (each
    sprocket's angular speed [rad/s] at 50 Hz), imu.csv (lateral acceleration and yaw rate
    in the vehicle frame at 100 Hz) and manifest.toml of one recording of ``robot``."""
    rng = np.random.default_rng([seed, 20253])
    directory.mkdir(parents=True, exist_ok=True)
    t_end = robot.t[-1]
    epoch = 1.77e9 + 86400.0 * seed + rng.uniform(0.0, 3600.0)

    def at(t: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.interp(t, robot.t, values)

    tg = _clock(rng.uniform(0.0, 0.4), t_end - rng.uniform(0.0, 0.4), ROBOT_GNSS_RATE, rng)
    yaw = at(tg, robot.yaw)
    east, north = _antenna(at(tg, robot.x), at(tg, robot.y), yaw, ROBOT_ANTENNA)
    east = east + gnss_noise(len(tg), ROBOT_GNSS_SIGMA, gnss_tau * ROBOT_GNSS_RATE, rng)
    north = north + gnss_noise(len(tg), ROBOT_GNSS_SIGMA, gnss_tau * ROBOT_GNSS_RATE, rng)
    lat, lon = enu_to_geodetic(east, north)
    stamp = tg + rng.uniform(-0.005, 0.005, len(tg))
    gnss = pd.DataFrame({"t": epoch + stamp, "lat": lat, "lon": lon})
    gnss.to_csv(directory / "gnss.csv", index=False, float_format="%.10f")

    tw = _clock(rng.uniform(0.0, 0.2), t_end - rng.uniform(0.0, 0.2), ROBOT_WHEEL_RATE, rng)
    tw = tw + rng.uniform(-0.0005, 0.0005, len(tw))
    wheels = pd.DataFrame({"t": epoch + tw})
    for col, omega in (("wl", robot.omega_l), ("wr", robot.omega_r)):
        wheels[col] = at(tw, omega) + ROBOT_WHEEL_NOISE * rng.standard_normal(len(tw))
    wheels.to_csv(directory / "wheels.csv", index=False, float_format="%.6f")

    ti = _clock(rng.uniform(0.0, 0.2), t_end - rng.uniform(0.0, 0.2), ROBOT_IMU_RATE, rng)
    sigma_a, sigma_w = ROBOT_IMU_NOISE
    imu = pd.DataFrame(
        {
            "t": epoch + ti,
            "ay": at(ti, robot.ay) + sigma_a * rng.standard_normal(len(ti)),
            "wz": at(ti, robot.yaw_rate) + sigma_w * rng.standard_normal(len(ti)),
        }
    )
    imu.to_csv(directory / "imu.csv", index=False, float_format="%.6f")
    manifest = [
        "# Written by scripts/independent_twin.py (an independent simulator): a skid-steer robot.",
        "rate = 40.0",
        "",
        "[gnss]",
        'file = "gnss.csv"',
        'time = "t"',
        'latitude = "lat"',
        'longitude = "lon"',
        "",
        "[wheels]",
        'file = "wheels.csv"',
        'time = "t"',
        'rear_left = "wl"',
        'rear_right = "wr"',
        'kind = "angular_speed"',
        "",
        "[imu]",
        'file = "imu.csv"',
        'time = "t"',
        'lateral_acceleration = "ay"',
        'yaw_rate = "wz"',
        'yaw_rate_unit = "rad/s"',
    ]
    (directory / "manifest.toml").write_text("\n".join(manifest) + "\n")


# ------------------------------------------------------------------------------------------
# A drive-log CSV of 96-tick counters (--route ticks-csv)
# ------------------------------------------------------------------------------------------

CSV_RATE = 40.0  # Hz
CSV_POSITION_SIGMA = 0.2  # m per axis
CSV_HEADING_SIGMA = 0.3 * DEG  # rad, a fused heading
CSV_AY_SIGMA = 0.05  # m/s²
CSV_LATENCY = 0.015  # s: the wheel counts are stamped this late (a CAN delay)


def write_tick_log(drive: Drive, path: Path, seed: int) -> None:
    """graphcal's drive-log CSV of ``drive`` at 40 Hz as a logger writes it: the position of
    the GNSS antenna (:data:`ANTENNA`, a lever arm) with 0.2 m white noise, a fused heading
    of the body with 0.3° noise (wrapped to ±180°), each interval's wheel rotation the
    difference of two 96-tick counter readings (whole ticks) taken :data:`CSV_LATENCY` s
    before the row's time (wheels late against the pose) — except the first row's, the
    rotation since an instant between two counts (a log started mid-count: off the tick
    grid) —, no sideslip (0) and the rear axle's lateral acceleration with 0.05 m/s²."""
    rng = np.random.default_rng([seed, 20254])
    t = np.arange(1.0, drive.t[-1] - 1.0, 1.0 / CSV_RATE)

    def at(times: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.interp(times, drive.t, values)

    yaw = at(t, drive.yaw)
    ahead, left = ANTENNA
    px = at(t, drive.x) + ahead * np.cos(yaw) - left * np.sin(yaw)
    py = at(t, drive.y) + ahead * np.sin(yaw) + left * np.cos(yaw)
    px = px + CSV_POSITION_SIGMA * rng.standard_normal(len(t))
    py = py + CSV_POSITION_SIGMA * rng.standard_normal(len(t))
    psi = np.angle(np.exp(1j * (yaw + CSV_HEADING_SIGMA * rng.standard_normal(len(t)))))
    edges = np.append(t, t[-1] + 1.0 / CSV_RATE) - CSV_LATENCY  # counter readings
    rotations = {}
    for side, rev in (("n_rl", drive.rev_l), ("n_rr", drive.rev_r)):
        cumulative = at(edges, rev)
        counts = np.floor(cumulative * TICKS_PER_REV + rng.uniform(0.0, 1.0))
        n = np.diff(counts) / TICKS_PER_REV
        n[0] = cumulative[1] - cumulative[0]  # the first reading: mid-count, off the grid
        rotations[side] = n
    ay = at(t, drive.ay) + CSV_AY_SIGMA * rng.standard_normal(len(t))
    log = pd.DataFrame(
        {"t": t - t[0], "px": px, "py": py, "psi": psi, **rotations, "beta": 0.0, "ay": ay}
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    log.to_csv(path, index=False, float_format="%.9g")


# ------------------------------------------------------------------------------------------
# Calibration and the table
# ------------------------------------------------------------------------------------------


@dataclass
class Case:
    """One recording to calibrate: ``source`` (relative to ``directory``) with ``extra``
    options of ``graphcal calibrate``, judged against ``theta_true``. ``expect`` maps a
    parameter to the verdict it should get (its start: "calibrated", "not observable",
    "fixed"); ``expect_line`` is text graphcal's progress should print."""

    seed: int
    directory: Path
    shape: str
    source: str = "manifest.toml"
    extra: tuple[str, ...] = ()
    theta_true: np.ndarray = field(default_factory=lambda: THETA_TRUE.copy())
    expect: dict = field(default_factory=dict)
    expect_line: str | None = None

    def command(self, graphcal: str, method: str) -> list[str]:
        command = [graphcal, "calibrate", str(self.directory / self.source), "--method", method]
        return command + ["--out", str(self.directory / "result"), "--workers", "1", *self.extra]


def town_case(seed: int, rate: float, heading: bool, imu: bool, wheels: str, directory: Path,
              length_km: float, route: str = "town") -> Case:  # fmt: skip
    h = "heading" if heading else "no heading"
    i = "IMU" if imu else "no IMU"
    where = f"{route} {length_km:g} km"
    case = Case(seed, directory, f"{where}, {rate:g} Hz, {h}, {i}, {wheels}")
    if route == "straight":  # a highway shows c_e and c_d only
        case.expect = {
            "c_e": "calibrated", "c_d": "calibrated", "t_r": "not observable",
            "d": "not observable",
        }  # fmt: skip
    return case


#: Progress lines of ``graphcal calibrate`` worth reporting: the text before the first ':'
#: (or the line's start) picks the line; the last one of each kind is kept.
FINDINGS = (
    "time offset",
    "GNSS antenna ahead",
    "GNSS antenna left",
    "GNSS antenna's lever arm not estimated",
    "model check: ",
    "wheel rotations are counts",
    "no slow wheel slip",
    "slow wheel slip",
)


@dataclass
class Outcome:
    case: Case
    exit_code: int
    trusted: bool | None = None
    ratio: dict | None = None  # name -> error/σ of parameters with a σ
    error: dict | None = None  # name -> error (SI) of parameters with a σ
    verdict: dict | None = None  # name -> graphcal's status
    findings: dict = field(default_factory=dict)  # FINDINGS kind -> its last line
    doubts: list | None = None
    message: str = ""
    seconds: float = 0.0


def calibrate(case: Case, graphcal: str, method: str = "whole") -> Outcome:
    command = case.command(graphcal, method)
    start = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    (case.directory / "command.txt").write_text(" ".join(command) + "\n")
    (case.directory / "calibrate.log").write_text(proc.stderr)
    out = Outcome(case, proc.returncode, seconds=seconds)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    notable = [ln for ln in lines if "warning" in ln or "error" in ln or "not trusted" in ln]
    out.message = " | ".join(notable)[:1500] or (lines[-1][:500] if proc.returncode else "")
    for line in lines:
        text = line.split("]", 1)[-1].strip() if line.startswith("[") else line.strip()
        for kind in FINDINGS:
            if text.startswith(kind):
                out.findings[kind] = text
                break
    return read_result(out)


def read_result(out: Outcome) -> Outcome:
    """Fill ``out`` from its case's ``result/calibration.json`` (if one was written)."""
    path = out.case.directory / "result" / "calibration.json"
    if not path.is_file():
        return out
    doc = json.loads(path.read_text())
    out.trusted = bool((doc.get("trust") or {}).get("trusted"))
    out.doubts = (doc.get("trust") or {}).get("doubts")
    not_calibrated = set(doc.get("not_calibrated") or [])
    out.ratio, out.error, out.verdict = {}, {}, {}
    for i, name in enumerate(NAMES):
        entry = doc["parameters"][name]
        sigma = entry.get("sigma")
        out.verdict[name] = str(entry.get("status", "?"))
        if name in not_calibrated or sigma is None or not sigma > 0:
            continue
        err = float(doc["theta"][name]) - out.case.theta_true[i]
        out.error[name] = err
        out.ratio[name] = err / float(sigma)
    return out


def _verdict_short(verdict: str) -> str:
    """graphcal's status of a parameter, short: "" (calibrated), "given t_r" (calibrated
    given t_r = prior), "n/o" (not observable), "fixed", "not trusted", else its text."""
    if verdict.startswith("calibrated given"):
        return "given " + verdict.split("given", 1)[1].split("=")[0].strip()
    if verdict.startswith("calibrated"):
        return ""
    if "not observable" in verdict:
        return "n/o"
    if verdict.startswith("fixed"):
        return "fixed"
    return verdict.split(":")[0]


def _verdict_kind(verdict: str) -> str:
    """The verdict as an expectation names it: "calibrated" (also given a prior), "not
    observable", "fixed", "not trusted", ..."""
    short = _verdict_short(verdict)
    return {"": "calibrated", "n/o": "not observable"}.get(
        short, "calibrated" if short.startswith("given") else short
    )


def _cell(out: Outcome, name: str) -> str:
    if out.verdict is None:
        return "—"
    short = _verdict_short(out.verdict[name])
    if name in (out.ratio or {}):
        value = f"{out.ratio[name]:+.2f}"
        return f"{value} ({short})" if short else value
    return short or out.verdict[name]


def within(out: Outcome, limit: float = 3.0) -> bool:
    """Every calibrated parameter within ``limit`` σ (a run without results is not)."""
    if out.ratio is None:
        return False
    return all(abs(r) <= limit for r in out.ratio.values())


def deviations(out: Outcome) -> list[str]:
    """How ``out`` departs from what its case expects (empty: as expected)."""
    found = []
    if out.exit_code != 0:
        found.append(f"exit {out.exit_code}")
    if out.trusted is False:
        found.append("not trusted")
    for name, ratio in (out.ratio or {}).items():
        if abs(ratio) > 3.0:
            found.append(f"{name} {ratio:+.1f}σ")
    for name, want in out.case.expect.items():
        if out.verdict is not None and _verdict_kind(out.verdict[name]) != want:
            found.append(f"{name} {_verdict_kind(out.verdict[name])} (expected {want})")
    if out.case.expect_line is not None:
        line = out.findings.get("wheel rotations are counts", "")
        if out.case.expect_line not in line:
            found.append(f"no '{out.case.expect_line}' ({line or 'no tick count found'})")
    return found


def _findings_text(out: Outcome) -> str:
    """The time offset, lever arm and model-check lines, shortened."""
    parts = []
    for kind, line in out.findings.items():
        if kind == "wheel rotations are counts":
            continue
        text = line.replace("GNSS antenna ", "").replace(" of the centre of gravity", "")
        text = text.replace("wheels late against the pose: ", "")
        if kind == "model check: ":
            text = "model check: " + text.rsplit(";", 1)[-1].strip().split(" (")[0]
        parts.append(text)
    return "; ".join(parts)


def _stats(values: list[float]) -> str:
    if not values:
        return "—"
    r = np.asarray(values)
    return f"{np.max(np.abs(r)):.2f} / {np.mean(r**2):.2f}"


def report(outcomes: list[Outcome]) -> str:
    rows = [
        "| case | seed | exit | trusted | " + " | ".join(f"{n} err/σ" for n in NAMES)
        + " | as expected | s |",
        "|---|---|---|---|" + "---|" * len(NAMES) + "---|---|",
    ]  # fmt: skip
    for out in outcomes:
        cells = [_cell(out, n) for n in NAMES]
        trusted = "—" if out.trusted is None else ("yes" if out.trusted else "NO")
        found = deviations(out)
        rows.append(
            f"| {out.case.shape} | {out.case.seed} | {out.exit_code} | {trusted} | "
            + " | ".join(cells) + f" | {'yes' if not found else 'NO: ' + ', '.join(found)} | "
            f"{out.seconds:.0f} |"
        )  # fmt: skip
    n = len(outcomes)
    ok = sum(within(o) for o in outcomes)
    trusted = sum(bool(o.trusted) for o in outcomes)
    expected = sum(not deviations(o) for o in outcomes)
    lines = [*rows, ""]
    summary = [f"runs within 3σ: {ok}/{n}; trusted: {trusted}/{n}; as expected: {expected}/{n}"]
    for name in NAMES:
        r = [o.ratio[name] for o in outcomes if o.ratio and name in o.ratio]
        e = [o.error[name] for o in outcomes if o.error and name in o.error]
        if r:
            summary.append(
                f"{name}: mean (err/σ)² {np.mean(np.square(r)):.2f}, worst |err/σ| "
                f"{np.max(np.abs(r)):.2f}, mean error {np.mean(e) * DISPLAY[name]:+.3f} "
                f"(mm{'·s²/m' if name == 'd' else ''}), with a σ in {len(r)}/{n}"
            )
        else:
            summary.append(f"{name}: calibrated in no run")
    lines += ["**Summary.** " + "; ".join(summary[:1]), ""]
    lines += [f"- {s}" for s in summary[1:]]
    # per recording shape, over the seeds
    lines += [
        "",
        "Per case over its seeds: worst |err/σ| / mean (err/σ)² of the parameters with a σ.",
        "",
        "| case | runs | exit 0 | trusted | within 3σ | as expected | "
        + " | ".join(NAMES) + " |",
        "|---|---|---|---|---|---|" + "---|" * len(NAMES),
    ]  # fmt: skip
    shapes: dict[str, list[Outcome]] = {}
    for out in outcomes:
        shapes.setdefault(out.case.shape, []).append(out)
    for shape, group in shapes.items():
        cells = [
            _stats([o.ratio[name] for o in group if o.ratio and name in o.ratio]) for name in NAMES
        ]
        lines.append(
            f"| {shape} | {len(group)} | {sum(o.exit_code == 0 for o in group)} | "
            f"{sum(bool(o.trusted) for o in group)} | {sum(within(o) for o in group)} | "
            f"{sum(not deviations(o) for o in group)} | " + " | ".join(cells) + " |"
        )
    found = [o for o in outcomes if o.findings]
    if found:
        lines += ["", "Time offset, lever arm, model check, tick count (graphcal's lines):", ""]
        for o in found:
            ticks = o.findings.get("wheel rotations are counts")
            extra = f"; {ticks}" if ticks else ""
            lines.append(f"- {o.case.shape}, seed {o.case.seed}: {_findings_text(o)}{extra}")
    notes = [o for o in outcomes if o.message or o.doubts]
    if notes:
        lines += ["", "Messages:", ""]
        for o in notes:
            doubts = f" doubts: {o.doubts}" if o.doubts else ""
            lines.append(f"- {o.case.shape}, seed {o.case.seed}: {o.message}{doubts}")
    return "\n".join(lines)


ROUTES = ("town", "straight", "skid-steer", "ticks-csv")


def _route_cases(args, route: str, base: Path) -> list[Case]:
    """Simulate and write every recording of ``route``; its cases."""
    cases: list[Case] = []
    if route == "skid-steer":
        models = args.defect_model or ["yes", "no"]
        for seed in args.seeds:
            robot = simulate_robot(args.robot_length_m, seed)
            print(
                f"skid-steer seed {seed}: {robot.length:.0f} m in {robot.t[-1]:.0f} s, "
                f"|v| <= {np.abs(robot.v).max():.2f} m/s, |yaw rate| <= "
                f"{np.abs(robot.yaw_rate).max():.2f} rad/s, {robot.kinds}",
                file=sys.stderr,
            )
            tau = args.robot_gnss_tau
            where = f"skid-steer-{args.robot_length_m:g}m" + (f"-tau{tau:g}s" if tau else "")
            streams = base / where / f"seed{seed}"
            write_robot_streams(robot, streams, seed, tau)
            for model in models:
                directory = streams / f"defect-model-{model}"
                directory.mkdir(parents=True, exist_ok=True)
                extra = ("--vehicle", str(args.robot_profile))
                extra += () if model == "yes" else ("--no-defect-model",)
                label = f", GNSS noise correlated over {tau:g} s" if tau else ""
                label += "" if model == "yes" else ", --no-defect-model"
                cases.append(
                    Case(
                        seed, directory, f"skid-steer {args.robot_length_m:g} m{label}",
                        source="../manifest.toml", extra=extra,
                        theta_true=ROBOT_THETA_TRUE.copy(),
                        expect={"c_e": "calibrated", "t_r": "calibrated"},
                    )
                )  # fmt: skip
        return cases
    lengths = args.lengths or [{"town": 12.0, "straight": None, "ticks-csv": 24.0}[route]]
    if route == "straight" and lengths == [None]:
        lengths = [1.0, 2.0, 6.0, 24.0]
    for length_km in lengths:
        for seed in args.seeds:
            drive = simulate_drive(
                length_km * 1e3, seed, args.slip_k, route="town" if route == "ticks-csv" else route,
                max_curvature=args.highway_curvature,
            )  # fmt: skip
            print(
                f"{route} {length_km:g} km seed {seed}: {drive.length / 1e3:.1f} km in "
                f"{drive.t[-1]:.0f} s, |a_y| <= {np.abs(drive.ay).max():.2f} m/s², |slip| <= "
                f"{np.degrees(np.abs(drive.slip).max()):.2f}°",
                file=sys.stderr,
            )
            where = base / f"{route}-{length_km:g}km" / f"seed{seed}"
            if route == "ticks-csv":
                write_tick_log(drive, where / "drive.csv", seed)
                for config in args.tick_config or ["no", "yes"]:
                    directory = where / f"config-{config}"
                    directory.mkdir(parents=True, exist_ok=True)
                    extra: tuple[str, ...] = ()
                    label = f"ticks-csv {length_km:g} km"
                    expect_line = "96 ticks per revolution (found in the rotations)"
                    if config == "yes":
                        (directory / "config.toml").write_text(
                            f"[vehicle]\nticks_per_revolution = {TICKS_PER_REV}\n"
                        )
                        extra = ("--config", str(directory / "config.toml"))
                        label += ", --config ticks_per_revolution = 96"
                        expect_line = None
                    cases.append(
                        Case(seed, directory, label, source="../drive.csv", extra=extra,
                             expect_line=expect_line)
                    )  # fmt: skip
                continue
            rates = args.rates or ([10.0] if route == "straight" else [1.0, 5.0, 10.0])
            wheel_kinds = args.wheels or (["speeds"] if route == "straight" else WHEEL_KINDS)
            headings = args.heading or (["no"] if route == "straight" else ["yes", "no"])
            imus = args.imu or (["no"] if route == "straight" else ["yes", "no"])
            for rate in rates:
                for wheels in wheel_kinds:
                    streams = where / f"{rate:g}hz_{wheels}"
                    write_streams(drive, streams, rate, wheels, seed, args.geodesy == "flat")
                    for heading in headings:
                        for imu in imus:
                            directory = streams / f"heading-{heading}_imu-{imu}"
                            directory.mkdir(parents=True, exist_ok=True)
                            (directory / "manifest.toml").write_text(
                                manifest_text(wheels, heading == "yes", imu == "yes")
                            )
                            cases.append(
                                town_case(seed, rate, heading == "yes", imu == "yes", wheels,
                                          directory, length_km, route)
                            )  # fmt: skip
    return cases


WHEEL_KINDS = ["speeds", "ticks"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--route", nargs="+", choices=ROUTES, default=["town"],
        help="what to simulate (several in one run): town (random town routes, the default), "
        "straight (a highway: 10 Hz GNSS without heading, CAN wheel speeds, no IMU, 1, 2, 6 "
        "and 24 km), skid-steer (a skid-steer robot, ~360 m, with --vehicle "
        "data/vehicles/skid_steer_robot.toml, with and without --no-defect-model), ticks-csv "
        "(a 24 km town drive as a drive-log CSV of 96-tick counter differences, with and "
        "without ticks_per_revolution in --config)",
    )  # fmt: skip
    parser.add_argument("--rates", type=float, nargs="+", help="GNSS Hz (town: 1 5 10)")
    parser.add_argument("--heading", nargs="+", choices=["yes", "no"], help="(town: yes no)")
    parser.add_argument("--imu", nargs="+", choices=["yes", "no"], help="(town: yes no)")
    parser.add_argument("--wheels", nargs="+", choices=WHEEL_KINDS, help="(town: both)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument(
        "--lengths", "--length-km", type=float, nargs="+", dest="lengths",
        help="drive lengths [km], each a case (town 12, straight 1 2 6 24, ticks-csv 24)",
    )  # fmt: skip
    parser.add_argument(
        "--highway-curvature", type=float, default=HIGHWAY_CURVATURE,
        help=f"straight: largest |curvature| of the wide bends [1/m] ({HIGHWAY_CURVATURE:g}; "
        "0: dead straight)",
    )  # fmt: skip
    parser.add_argument("--robot-length-m", type=float, default=360.0, help="skid-steer (360)")
    parser.add_argument("--robot-profile", type=Path, default=ROBOT_PROFILE)
    parser.add_argument(
        "--robot-gnss-tau", type=float, default=0.0,
        help="skid-steer: correlation time [s] of the GNSS error (0: white, the default)",
    )  # fmt: skip
    parser.add_argument(
        "--defect-model", nargs="+", choices=["yes", "no"],
        help="skid-steer: with the defect model, without (--no-defect-model); default both",
    )  # fmt: skip
    parser.add_argument(
        "--tick-config", nargs="+", choices=["no", "yes"],
        help="ticks-csv: defaults (no), ticks_per_revolution = 96 in --config (yes); both",
    )  # fmt: skip
    parser.add_argument("--slip-k", type=float, default=0.004, help="tyre slip [s²/m] (0.004)")
    parser.add_argument("--geodesy", choices=["wgs84", "flat"], default="wgs84")
    parser.add_argument("--method", choices=["whole", "joint"], default="whole")
    parser.add_argument("--jobs", type=int, default=2, help="calibrations at once (2)")
    parser.add_argument("--keep", type=Path, help="write the recordings here and keep them")
    parser.add_argument("--graphcal", default=shutil.which("graphcal") or "graphcal")
    args = parser.parse_args(argv)

    base = args.keep or Path(tempfile.mkdtemp(prefix="independent_twin_"))
    cases: list[Case] = []
    started = time.perf_counter()
    for route in dict.fromkeys(args.route):
        cases += _route_cases(args, route, base)

    def run(case: Case) -> Outcome:
        out = calibrate(case, args.graphcal, args.method)
        print(
            f"[{time.perf_counter() - started:6.0f} s] {case.shape}, seed {case.seed}: exit "
            f"{out.exit_code} ({out.seconds:.0f} s)",
            file=sys.stderr,
        )
        return out

    try:
        with ThreadPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
            outcomes = list(pool.map(run, cases))
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    command = " ".join(["python scripts/independent_twin.py", *(argv or sys.argv[1:])])
    print(f"`{command}` (slip k = {args.slip_k} s²/m, geodesy {args.geodesy}, "
          f"--method {args.method})\n")  # fmt: skip
    print(report(outcomes))
    return 0


if __name__ == "__main__":
    sys.exit(main())
