"""The streams of a :class:`~campaign.shape.Shape`: the independent twin's vehicles
(``scripts/independent_twin.py``: numpy and pandas, nothing of ``graphcal.simulate``) driven
as the shape says, written as CSV streams with a manifest and a vehicle profile."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from campaign.shape import Shape

ROOT = Path(__file__).resolve().parents[2]
_TWIN_PATH = ROOT / "scripts" / "independent_twin.py"


def _load_twin():
    """``scripts/independent_twin.py`` as a module (``scripts/`` is not a package)."""
    if "independent_twin" in sys.modules:
        return sys.modules["independent_twin"]
    spec = importlib.util.spec_from_file_location("independent_twin", _TWIN_PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_twin"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


twin = _load_twin()

#: The TRUE theta [c_e, c_d, t_r, d] (SI) of each vehicle: the twin's car and skid-steer
#: robot, and a differential-drive robot (the delivery robot's datasheet 0.5 m / 0.2 m off
#: by +0.6 % and +5 mm).
THETA_TRUE = {
    "car": twin.THETA_TRUE,
    "skid-steer": twin.ROBOT_THETA_TRUE,
    "differential": np.array([0.503, 0.0004, 0.205, 0.0]),
}
_PROFILES = {
    "car": ROOT / "data" / "vehicles" / "car.toml",
    "skid-steer": ROOT / "data" / "vehicles" / "skid_steer_robot.toml",
    "differential": ROOT / "data" / "vehicles" / "delivery_robot.toml",
}
#: The ECU's circumference [m] a wheel speed [m/s] is reported at.
ECU_CIRCUMFERENCE = {"car": 2.0, "skid-steer": 0.8, "differential": 0.5}
WHEEL_RATE = 100.0  # Hz, wheels and IMU
SPEED_NOISE = 0.02  # m/s of a wheel speed; angular speeds: the same over the radius
HEADING_NOISE = 0.3  # deg, a fused heading
IMU_NOISE = (0.05, 0.1 * math.pi / 180.0)  # m/s², rad/s
LOG_RATE = 40.0  # Hz, the manifest's drive-log rate
GRAVITY = 9.80665  # m/s², the specific force of a vehicle at rest (up)


@dataclass
class Motion:
    """The reference point's motion on one clock [s] (several drives, gaps removed from
    no array: ``drive`` is the drive index of each sample) and the wheels' cumulative
    rotations [rev] and rates [rev/s]."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    yaw_rate: np.ndarray
    ay: np.ndarray
    rev_l: np.ndarray
    rev_r: np.ndarray
    rate_l: np.ndarray
    rate_r: np.ndarray
    slip: np.ndarray  # rad, the reference point's sideslip (a car's tyre slip angle)
    spans: list[tuple[float, float]]  # (start, end) [s] of each drive, parked ends included


def _one_drive(shape: Shape, index: int) -> dict[str, np.ndarray]:
    """Drive ``index`` of ``shape`` from the twin, from t = 0 and rotations 0."""
    seed = shape.seed * 10 + index
    if shape.vehicle == "car":
        drive = twin.simulate_drive(
            shape.length_m, seed, 0.004, route=shape.route,
            max_curvature=twin.HIGHWAY_CURVATURE,
        )  # fmt: skip
        fields = ("t", "x", "y", "yaw", "yaw_rate", "ay", "rev_l", "rev_r", "rate_l", "rate_r")
        return _from_rest(
            {name: np.asarray(getattr(drive, name), float) for name in (*fields, "slip")}
        )
    robot = twin.simulate_robot(shape.length_m, seed, THETA_TRUE[shape.vehicle])
    rate_l, rate_r = robot.omega_l / (2 * np.pi), robot.omega_r / (2 * np.pi)
    return {
        "t": robot.t, "x": robot.x, "y": robot.y, "yaw": robot.yaw,
        "yaw_rate": robot.yaw_rate, "ay": robot.ay,
        "rev_l": twin._cumtrapz(rate_l, twin.ROBOT_DT),
        "rev_r": twin._cumtrapz(rate_r, twin.ROBOT_DT),
        "rate_l": rate_l, "rate_r": rate_r, "slip": np.zeros(len(robot.t)),
    }  # fmt: skip


#: Acceleration [m/s²] of a car from rest to its drive's first speed, and braking from its
#: last speed to rest (the twin's drives start and end at speed).
START_STOP_ACCELERATION = 1.5


def _ramp(drive: dict[str, np.ndarray], end: bool) -> dict[str, np.ndarray]:
    """A straight run from rest to the drive's first sample (``end``: from its last sample
    to rest) at :data:`START_STOP_ACCELERATION`, times from 0 at its first sample."""
    k, step = (-1, -2) if end else (0, 1)
    speed = float(
        np.hypot(drive["x"][k] - drive["x"][step], drive["y"][k] - drive["y"][step])
        / abs(drive["t"][k] - drive["t"][step])
    )
    duration = speed / START_STOP_ACCELERATION
    tau = np.linspace(0.0, duration, max(3, int(duration * WHEEL_RATE)))[1:]
    if end:  # distance from the last sample, and speed
        along, v = (
            speed * tau - 0.5 * START_STOP_ACCELERATION * tau**2,
            speed - START_STOP_ACCELERATION * tau,
        )
    else:  # distance to the first sample (negative), and speed
        tau = tau[::-1]
        along, v = (
            -(speed * tau - 0.5 * START_STOP_ACCELERATION * tau**2),
            speed - START_STOP_ACCELERATION * tau,
        )
        tau = -tau
    yaw = drive["yaw"][k]
    zero = np.zeros(len(tau))
    out = {
        "t": drive["t"][k] + tau,
        "x": drive["x"][k] + along * np.cos(yaw),
        "y": drive["y"][k] + along * np.sin(yaw),
        "yaw": np.full(len(tau), yaw), "yaw_rate": zero, "ay": zero, "slip": zero,
    }  # fmt: skip
    for side in ("l", "r"):
        per_metre = drive[f"rate_{side}"][k] / speed
        out[f"rev_{side}"] = drive[f"rev_{side}"][k] + along * per_metre
        out[f"rate_{side}"] = v * per_metre
    return out


def _from_rest(drive: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A car's ``drive`` with :func:`_ramp` from rest before it and to rest after it, its
    times from 0 and its rotations from 0."""
    first, last = _ramp(drive, end=False), _ramp(drive, end=True)
    out = {name: np.concatenate([first[name], drive[name], last[name]]) for name in drive}
    out["t"] = out["t"] - out["t"][0]
    for side in ("l", "r"):
        out[f"rev_{side}"] = out[f"rev_{side}"] - out[f"rev_{side}"][0]
    return out


def _parked(drive: dict[str, np.ndarray], park: float) -> dict[str, np.ndarray]:
    """``drive`` standing still ``park`` s before and after it (rates 0, state held)."""
    if park <= 0:
        return drive
    eps = 1e-3
    out = {}
    for name, values in drive.items():
        if name == "t":
            end = values[-1] + park
            out[name] = np.concatenate([[0.0, park - eps], values + park, [end + eps, end + park]])
        elif name in ("yaw_rate", "ay", "rate_l", "rate_r", "slip"):
            out[name] = np.concatenate([[0.0, 0.0], values, [0.0, 0.0]])
        else:
            out[name] = np.concatenate([values[:1], values[:1], values, values[-1:], values[-1:]])
    return out


def motion(shape: Shape) -> Motion:
    """``shape``'s drives on one clock: each starts where the previous one was parked (its
    route turned onto the previous end's heading), ``gap_s`` later, its counters going on."""
    parts: list[dict[str, np.ndarray]] = []
    spans = []
    t0 = 0.0
    for index in range(shape.drives):
        drive = _parked(_one_drive(shape, index), shape.park_s)
        if parts:
            last = parts[-1]
            turn = last["yaw"][-1] - drive["yaw"][0]
            c, s = math.cos(turn), math.sin(turn)
            dx, dy = drive["x"] - drive["x"][0], drive["y"] - drive["y"][0]
            drive["x"] = last["x"][-1] + c * dx - s * dy
            drive["y"] = last["y"][-1] + s * dx + c * dy
            drive["yaw"] = drive["yaw"] + turn
            drive["rev_l"] = drive["rev_l"] + last["rev_l"][-1]
            drive["rev_r"] = drive["rev_r"] + last["rev_r"][-1]
        drive["t"] = drive["t"] + t0
        spans.append((float(drive["t"][0]), float(drive["t"][-1])))
        t0 = drive["t"][-1] + shape.gap_s
        parts.append(drive)
    joined = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
    return Motion(**joined, spans=spans)


def _slipping(m: Motion, shape: Shape, rng: np.random.Generator) -> Motion:
    """``m`` with the wheels slipping slowly: their rates scaled by ``1 + slip · sin(2π t /
    P + φ)``, P 60–300 s, less its mean over the distance driven where fixes see the
    vehicle (theta stays the truth), rotations integrated."""
    if not shape.slip:
        return m
    period, phase = rng.uniform(60.0, 300.0), rng.uniform(0.0, 2.0 * np.pi)
    slip = shape.slip * np.sin(2.0 * np.pi * m.t / period + phase)
    dt = np.diff(m.t)
    dt[dt > 1.0] = 0.0  # across a gap between drives the wheels are not turning
    # None on average over the distance driven: a minute's drive on a five-minute sine
    # slips by up to its amplitude throughout, which no log tells from c_e. Nor the slip of
    # an outage, where no fix sees the distance: 0.17 % over a 56 s outage moved the mean of
    # the rest by 0.09 %, c_e by 1.8 mm (seed 45's shape 58, its σ 0.54 mm).
    rate = 0.5 * (m.rate_l + m.rate_r)
    weight = np.concatenate([[0.0], dt]) * rate * _fixes_kept(m.t, m, shape)
    scale = 1.0 + slip - np.sum(weight * slip) / max(np.sum(weight), 1e-12)

    def extra(rate: np.ndarray) -> np.ndarray:
        return twin._cumtrapz(rate * (scale - 1.0), dt)

    return dataclasses.replace(
        m, rate_l=m.rate_l * scale, rate_r=m.rate_r * scale,
        rev_l=m.rev_l + extra(m.rate_l), rev_r=m.rev_r + extra(m.rate_r),
    )  # fmt: skip


def _fixes_kept(tg: np.ndarray, m: Motion, shape: Shape) -> np.ndarray:
    """Which fix instants ``tg`` are outside the outage amid the first drive (the fixes stop
    ``outage_s``, at most half the drive; the wheels go on)."""
    if not shape.outage_s:
        return np.ones(len(tg), bool)
    start, end = m.spans[0]
    length = min(shape.outage_s, 0.5 * (end - start))
    middle = 0.5 * (start + end)
    return (tg < middle - 0.5 * length) | (tg > middle + 0.5 * length)


def _with_outliers(
    east: np.ndarray, north: np.ndarray, share: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """A ``share`` of the fixes (at least one if any) moved 10–50 m in random directions."""
    if not share:
        return east, north
    count = max(1, round(share * len(east)))
    rows = rng.choice(len(east), size=min(count, len(east)), replace=False)
    distance = rng.uniform(10.0, 50.0, len(rows))
    angle = rng.uniform(0.0, 2.0 * np.pi, len(rows))
    east, north = east.copy(), north.copy()
    east[rows] += distance * np.cos(angle)
    north[rows] += distance * np.sin(angle)
    return east, north


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) · Ry(pitch) · Rx(roll)`` [angles in deg]: the IMU's frame in the vehicle's."""
    r, p, y = np.radians([roll, pitch, yaw])
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _imu_frame(shape: Shape, m: Motion, ti: np.ndarray, rng: np.random.Generator) -> dict:
    """The IMU's six columns in its own frame, mounted at ``shape.mounting``: the vehicle's
    specific force (the speed's rate forward, the lateral acceleration, gravity up) and turn
    rate, rotated into the IMU's frame, with white noise per axis."""
    speed = 0.5 * (m.rate_l + m.rate_r) * THETA_TRUE[shape.vehicle][0]
    forward = np.gradient(speed, m.t)  # the speed's own rate, as an accelerometer feels it
    force = np.column_stack(
        [np.interp(ti, m.t, forward), np.interp(ti, m.t, m.ay), np.full(len(ti), GRAVITY)]
    )
    turn = np.column_stack([np.zeros(len(ti)), np.zeros(len(ti)), np.interp(ti, m.t, m.yaw_rate)])
    matrix = _rotation(*shape.mounting)
    force = force @ matrix + IMU_NOISE[0] * rng.standard_normal(force.shape)  # Rᵀ v per row
    turn = turn @ matrix + IMU_NOISE[1] * rng.standard_normal(turn.shape)
    names = ("ax", "ay", "az", "wx", "wy", "wz")
    return dict(zip(names, np.column_stack([force, turn]).T, strict=True))


def _clock(m: Motion, rate: float, rng: np.random.Generator, start_delay: float = 0.0):
    """Sample instants at ``rate`` [Hz] within each drive (none in the gaps), each drive's
    stream starting ``start_delay`` s after it."""
    return np.concatenate([twin._clock(a + start_delay, b, rate, rng) for a, b in m.spans])


def write_recording(shape: Shape, directory: Path) -> Path:
    """Write gnss.csv, wheels.csv, imu.csv (if drawn), vehicle.toml and manifest.toml of
    ``shape`` into ``directory``; the manifest's path."""
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([shape.seed, 43])
    m = motion(shape)
    epoch = 1.78e9 + rng.uniform(0.0, 86400.0)
    defects = np.random.default_rng([shape.seed, 45])  # the draws above stay as they were
    m = _slipping(m, shape, defects)

    def at(t: np.ndarray, values: np.ndarray) -> np.ndarray:
        return np.interp(t, m.t, values)

    # GNSS: re-acquires 0-3 s after each drive starts; epochs with ±2 ms jitter
    tg = _clock(m, shape.gnss_rate, rng, rng.uniform(0.0, 3.0))
    yaw = at(tg, m.yaw)
    east, north = twin._antenna(at(tg, m.x), at(tg, m.y), yaw, shape.lever_arm)
    tau = shape.noise_tau_s * shape.gnss_rate  # in fixes
    east = east + twin.gnss_noise(len(tg), shape.noise_sigma, tau, rng)
    north = north + twin.gnss_noise(len(tg), shape.noise_sigma, tau, rng)
    kept = _fixes_kept(tg, m, shape)
    tg, yaw, east, north = tg[kept], yaw[kept], east[kept], north[kept]
    east, north = _with_outliers(east, north, shape.outliers, defects)
    lat, lon = twin.enu_to_geodetic(east, north)
    gnss = {"t": epoch + tg + rng.uniform(-0.002, 0.002, len(tg)), "lat": lat, "lon": lon}
    if shape.heading:
        noisy = np.degrees(yaw) + HEADING_NOISE * rng.standard_normal(len(kept))[kept]
        gnss["heading"] = np.mod(90.0 - noisy, 360.0)
    if shape.sideslip:  # the rear axle's, the wheels' reference point's
        gnss["beta"] = at(tg, m.slip)
    pd.DataFrame(gnss).to_csv(directory / "gnss.csv", index=False, float_format="%.10f")

    # Wheels: stamped time_offset_s late
    tw = _clock(m, WHEEL_RATE, rng)
    wheels = pd.DataFrame({"t": epoch + tw + shape.time_offset_s})
    circumference = ECU_CIRCUMFERENCE[shape.vehicle]
    for col, rev, rate in (("rl", m.rev_l, m.rate_l), ("rr", m.rev_r, m.rate_r)):
        if shape.wheels == "ticks":
            wheels[col] = np.floor(at(tw, rev) * shape.ticks + rng.uniform()).astype(np.int64)
            continue
        speed = at(tw, rate) * circumference + SPEED_NOISE * rng.standard_normal(len(tw))
        scale = 1.0 if shape.wheels == "speed" else 2 * np.pi / circumference
        wheels[col] = speed * scale
    wheels.to_csv(directory / "wheels.csv", index=False, float_format="%.6f")

    if shape.imu:
        ti = _clock(m, WHEEL_RATE, rng)
        imu = pd.DataFrame(
            {
                "t": epoch + ti,
                "ay": at(ti, m.ay) + IMU_NOISE[0] * rng.standard_normal(len(ti)),
                "wz": at(ti, m.yaw_rate) + IMU_NOISE[1] * rng.standard_normal(len(ti)),
            }
        )
        if shape.mounting is not None:
            imu = pd.DataFrame({"t": imu["t"], **_imu_frame(shape, m, ti, defects)})
        imu.to_csv(directory / "imu.csv", index=False, float_format="%.6f")
    (directory / "vehicle.toml").write_text(profile_text(shape))
    path = directory / "manifest.toml"
    path.write_text(manifest_text(shape))
    return path


def profile_text(shape: Shape) -> str:
    """The vehicle profile a user of this vehicle passes with ``--vehicle``: the repository's,
    without a ``ticks_per_revolution`` (the manifest says what the wheels are)."""
    lines = _PROFILES[shape.vehicle].read_text().splitlines()
    return "\n".join(ln for ln in lines if not ln.startswith("ticks_per_revolution")) + "\n"


def manifest_text(shape: Shape) -> str:
    """The streams manifest of ``write_recording``'s files."""
    lines = [
        "# Written by tests/campaign/recording.py: " + shape.label(),
        f"rate = {LOG_RATE}",
        "",
        "[gnss]",
        'file = "gnss.csv"',
        'time = "t"',
        'latitude = "lat"',
        'longitude = "lon"',
    ]
    if shape.heading:
        lines += ['heading = "heading"', 'heading_unit = "deg"', 'heading_convention = "compass"']
    if shape.sideslip:
        lines += ['sideslip = "beta"', 'sideslip_unit = "rad"']
    lines += ["", "[wheels]", 'file = "wheels.csv"', 'time = "t"']
    lines += ['rear_left = "rl"', 'rear_right = "rr"', f'kind = "{shape.wheels}"']
    if shape.wheels == "ticks":
        lines += [f"ticks_per_revolution = {shape.ticks}"]
    elif shape.wheels == "speed":
        lines += ['speed_unit = "m/s"', f"circumference = {ECU_CIRCUMFERENCE[shape.vehicle]}"]
    if shape.imu:
        lines += ["", "[imu]", 'file = "imu.csv"', 'time = "t"']
        if shape.mounting is None:
            lines += ['lateral_acceleration = "ay"', 'yaw_rate = "wz"', 'yaw_rate_unit = "rad/s"']
        else:
            lines += ['acceleration = ["ax", "ay", "az"]', 'angular_velocity = ["wx", "wy", "wz"]']
            angles = ", ".join(f"{a:g}" for a in shape.mounting)
            given = '"estimate"' if shape.mounting_estimated else f"[{angles}]"
            lines += [f"mounting = {given}"]
    return "\n".join(lines) + "\n"
