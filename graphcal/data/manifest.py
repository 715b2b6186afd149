"""The streams manifest: a TOML file naming one CSV per sensor (or a ROS bag's topics).

Every key, with its default (``graphcal import --help-manifest`` prints this)::

    rate = 40.0                      # Hz of the written drive log
    max_gap = 0.5                    # s: a longer gap in any stream masks the log there
    # bag = "drive.bag"              # a ROS 1/2 bag or MCAP file instead of CSV files;
                                     # then a section holds only `topic` and `time_offset`
                                     # ([wheels] also rear_left/rear_right joints and kind)
    [gnss]                           # the pose: GNSS fixes or a fused pose ([pose] works too)
    file = "gnss.csv"                # relative to the manifest
    time = "t"                       # column
    time_unit = "s"                  # s | ms | us | ns
    time_offset = 0.0                # s added to this stream's time (clock offset)
    latitude = "lat"                 # degrees WGS-84 ...
    longitude = "lon"
    # x = "x", y = "y"               # ... or a local metric frame [m] (east, north)
    heading = "heading"              # optional; without it the GNSS course is used
    heading_unit = "deg"             # deg | rad (required with heading)
    heading_convention = "enu"       # enu: 0 = east, counter-clockwise
                                     # compass: 0 = north, clockwise
    # sideslip = "beta"              # optional, sideslip_unit = "rad" (rad | deg); else 0
    # nmea = "receiver.nmea"         # instead of file and columns: a receiver's NMEA 0183
                                     # log (pip install -e ".[nmea]"): GGA and RMC fixes at
                                     # their UTC times, heading from HDT/THS (never VTG's
                                     # course); keys: nmea, date, heading, time_offset
    # date = "2025-11-23"            # with nmea: UTC date of the first fix, for a log
                                     # without RMC (RMC's dates are used where logged)
    # heading = false                # with nmea: ignore HDT/THS, use the GNSS course
    [wheels]
    file = "wheels.csv"
    time = "t"
    rear_left = "rl"                 # columns (joint names for a bag)
    rear_right = "rr"
    kind = "speed"                   # speed [m/s] | angular_speed [rad/s] | rpm
                                     # | ticks (cumulative) | angle [rad, cumulative]
    circumference = 2.0              # m: what the ECU used to turn rotations into speed
    speed_unit = "m/s"               # m/s | km/h | mph (kind = speed)
    ticks_per_revolution = 96        # kind = ticks
    # ticks_wrap = 65536             # a tick counter that wraps at this count
    # can = "drive.log"              # instead of file, time and columns: a raw CAN log
                                     # (pip install -e ".[can]"): candump -l/-L .log or .log.gz,
                                     # Vector .asc or .blf, python-can .csv; time: the log's
    # dbc = "car.dbc"                # with can: the DBC that decodes it (cantools)
    # message = "WHEEL_SPEEDS"       # with can: the DBC message, by name or frame id (0xAA);
                                     # rear_left/rear_right name its signals, speed_unit and
                                     # ticks_wrap default to the DBC's unit and signal range
    # bus = 0                        # with can: only this bus ("can0" or 0; ASC/BLF: 1, 2)
    [imu]                            # optional
    file = "imu.csv"
    time = "t"
    lateral_acceleration = "ay"      # m/s², positive to the left
    yaw_rate = "wz"                  # positive counter-clockwise
    yaw_rate_unit = "rad/s"          # rad/s | deg/s
    # message = "KINEMATICS"         # signals of a CAN message instead of columns: can and
                                     # dbc as [wheels]' unless given (the wheels' log brings
                                     # its bus and time_offset); yaw_rate_unit defaults to
                                     # the DBC's unit (deg/s | rad/s)
    # ... or a 3-axis IMU in its own frame (instead of lateral_acceleration / yaw_rate):
    # acceleration = ["ax", "ay", "az"]     # specific force, gravity included
    # acceleration_unit = "m/s²"            # m/s² (also "m/s^2") | g
    # angular_velocity = ["wx", "wy", "wz"]
    # angular_velocity_unit = "rad/s"       # rad/s | deg/s
    # mounting = [0.0, 0.0, 90.0]           # required: [roll, pitch, yaw] in degrees, the
                                     # IMU's frame in the vehicle's: v = Rz(yaw)·Ry(pitch)
                                     # ·Rx(roll)·v_imu (URDF rpy), a 3×3 matrix (rows), or
                                     # "estimate" (from gravity and the accelerations)

``time_unit`` and ``time_offset`` exist in every section; ``heading_unit`` and
``heading_convention`` are required with ``heading``. Wheel speeds from an ECU were
computed with the ECU's own circumference: ``circumference`` undoes that, so the wheel stream
is in revolutions and the calibrated c_e is the true effective circumference.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from graphcal.data.drive_log import _readable
from graphcal.data.geodesy import geodetic_to_local
from graphcal.data.stream_grid import MAX_GAP_S
from graphcal.data.streams import (
    Field,
    ImuStream,
    PoseStream,
    Provenance,
    Recording,
    StreamError,
    WheelStream,
    check_time,
    unique_samples,
)

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180.0}
SPEED_UNITS = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}
YAW_RATE_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
HEADING_CONVENTIONS = ("enu", "compass")
WHEEL_KINDS = ("speed", "angular_speed", "rpm", "ticks", "angle")
#: Keys each section and the top level may hold (anything else is a one-line error).
TOP_KEYS = ("rate", "max_gap", "bag", "truth", "gnss", "pose", "wheels", "imu")
COMMON_KEYS = ("file", "topic", "time", "time_unit", "time_offset")
POSE_KEYS = (
    *COMMON_KEYS,
    *("latitude", "longitude", "x", "y", "heading", "heading_unit", "heading_convention"),
    *("sideslip", "sideslip_unit"),
    *("nmea", "date"),  # an NMEA log: graphcal.data.nmea
)
WHEEL_KEYS = (
    *COMMON_KEYS,
    *("rear_left", "rear_right", "kind", "circumference", "speed_unit"),
    *("ticks_per_revolution", "ticks_wrap"),
    *("can", "dbc", "message", "bus"),  # a raw CAN log and its DBC: graphcal.data.can_log
)
IMU_KEYS = (
    *(*COMMON_KEYS, "lateral_acceleration", "yaw_rate", "yaw_rate_unit"),
    *("acceleration", "acceleration_unit", "angular_velocity", "angular_velocity_unit"),
    "mounting",  # a 3-axis IMU in its own frame: graphcal.data.imu_mounting
    *("can", "dbc", "message", "bus"),  # signals of a CAN message: graphcal.data.can_log
)


class Manifest:
    """A parsed streams manifest: its sections, checked keys, and where it lives."""

    def __init__(self, data: dict[str, Any], path: Path) -> None:
        self.path = path
        self.source = str(path)
        unknown = sorted(set(data) - set(TOP_KEYS))
        if unknown:
            raise self.error(f"unknown key(s) {unknown}; known: {list(TOP_KEYS)}")
        if "gnss" in data and "pose" in data:
            raise self.error("both [gnss] and [pose]: name the pose stream once")
        self.data = data
        self.rate = self.number(data, "rate", 40.0, "", positive=True)
        self.max_gap = self.number(data, "max_gap", MAX_GAP_S, "", positive=True)
        bag = data.get("bag")
        if bag is not None and not isinstance(bag, str):
            raise self.error(f"bag must be a path (text), got {bag!r}")
        self.bag = self.resolve(bag) if bag else None
        csv = self.bag is None  # a bag's topics are found when the sections do not name them
        self.pose_name = "pose" if "pose" in data else "gnss"
        self.pose = self.section(self.pose_name, POSE_KEYS, required=csv) or {}
        self.wheels = self.section("wheels", WHEEL_KEYS, required=csv) or {}
        self.imu = self.section("imu", IMU_KEYS, required=False)

    def error(self, what: str) -> StreamError:
        """A one-line :class:`StreamError` about this manifest."""
        return StreamError(f"{self.source}: {what}")

    def resolve(self, name: str) -> Path:
        """A path named in the manifest, relative to the manifest's directory."""
        path = Path(name).expanduser()
        return path if path.is_absolute() else self.path.parent / path

    def section(self, name: str, keys: tuple[str, ...], required: bool) -> dict[str, Any] | None:
        """Table ``name`` with its keys checked, or ``None`` if absent and optional."""
        table = self.data.get(name)
        if table is None:
            if required:
                what = "[gnss] (or [pose])" if name == "gnss" else f"[{name}]"
                raise self.error(f"no {what} section; the manifest must name that stream")
            return None
        if not isinstance(table, dict):
            raise self.error(f"{name} must be a table ([{name}]), got {table!r}")
        unknown = sorted(set(table) - set(keys))
        if unknown:
            raise self.error(f"unknown key(s) {unknown} in [{name}]; known: {list(keys)}")
        return table

    def number(
        self, table: dict, key: str, default: float | None, section: str, positive: bool = False
    ) -> float | None:
        """A numeric key (``default`` if absent), checked finite (and positive)."""
        value = table.get(key, default)
        if value is None:
            return None
        where = f"[{section}] {key}" if section else key
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"{where} must be a number, got {value!r}")
        value = float(value)
        if not np.isfinite(value) or (positive and value <= 0):
            raise self.error(f"{where} must be a {'positive ' if positive else ''}number")
        return value

    def choice(self, table: dict, key: str, options, section: str, default: str | None):
        """A key whose value is one of ``options`` (``default`` if absent; required if None)."""
        value = table.get(key, default)
        known = ", ".join(options)
        if value is None:
            raise self.error(f"[{section}] needs {key} (one of {known})")
        if value not in options:
            raise self.error(f"[{section}] {key} = {value!r} is not known; use one of {known}")
        return value

    def text(self, table: dict, key: str, section: str, required: bool = True) -> str | None:
        """A column or topic name."""
        value = table.get(key)
        if value is None:
            if required:
                raise self.error(f"[{section}] needs {key} (the column name)")
            return None
        if not isinstance(value, str) or not value:
            raise self.error(f"[{section}] {key} must be a column name (text), got {value!r}")
        return value


def load_manifest(path: str | os.PathLike[str]) -> Manifest:
    """Read and check a streams manifest (see the module docstring for every key)."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise StreamError(f"{path}: no such manifest; check the path") from None
    except IsADirectoryError:
        raise StreamError(f"{path}: is a directory, not a manifest or bag") from None
    except OSError as exc:
        raise StreamError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise StreamError(f"{path}: not a valid TOML manifest ({exc})") from exc
    return Manifest(data, path)


def read_manifest(path: str | os.PathLike[str] | Manifest) -> Recording:
    """The :class:`Recording` a manifest (path, or loaded) describes: its CSV files, or its
    bag's topics."""
    manifest = path if isinstance(path, Manifest) else load_manifest(path)
    if manifest.bag is not None:
        return _read_bag_manifest(manifest)
    notes: list[str] = []
    pose = _read_pose(manifest, notes)
    wheels = _read_wheels(manifest, notes)
    imu = _read_imu(manifest, notes, pose, wheels) if manifest.imu is not None else None
    return Recording(pose=pose, wheels=wheels, imu=imu, source=manifest.source, notes=tuple(notes))


#: Keys a section may hold when the manifest reads a bag (the wheels' also name the joints).
BAG_KEYS = {"topic", "time_offset"}
BAG_WHEEL_KEYS = BAG_KEYS | {"rear_left", "rear_right", "kind"}


def _read_bag_manifest(manifest: Manifest) -> Recording:
    import dataclasses

    from graphcal.data.bags import read_bag

    sections = {manifest.pose_name: manifest.pose, "wheels": manifest.wheels, "imu": manifest.imu}
    for name, table in sections.items():
        extra = sorted(set(table or {}) - (BAG_WHEEL_KEYS if name == "wheels" else BAG_KEYS))
        if extra:
            raise manifest.error(
                f"[{name}] {', '.join(extra)}: not used with bag = ...; a bag's messages name "
                "their fields and stamp their time (use topic and time_offset)"
            )
    wheels = manifest.wheels
    kind = wheels.get("kind")
    if kind is not None and kind not in ("angle", "angular_speed"):
        raise manifest.error(
            f"[wheels] kind = {kind!r}: a bag's JointState gives angle (position) or "
            "angular_speed (velocity)"
        )
    recording = read_bag(
        manifest.bag,
        pose_topic=manifest.pose.get("topic"),
        wheel_topic=wheels.get("topic"),
        imu_topic=(manifest.imu or {}).get("topic"),
        rear_left=wheels.get("rear_left"),
        rear_right=wheels.get("rear_right"),
        wheel_kind=kind,
        source=manifest.source,
    )
    shifted = {}
    for role, name, table in (
        ("pose", manifest.pose_name, manifest.pose),
        ("wheels", "wheels", manifest.wheels),
        ("imu", "imu", manifest.imu),
    ):
        offset = manifest.number(table or {}, "time_offset", 0.0, name)
        stream = getattr(recording, role)
        if offset and stream is not None:
            shifted[role] = dataclasses.replace(stream, t=stream.t + offset)
    return dataclasses.replace(recording, **shifted) if shifted else recording


def _declared(table: dict, key: str, default: str | None = None) -> str:
    """How a unit key reads in the manifest (``'speed_unit = "m/s"'``), for messages; a key
    left out says its default."""
    value = table.get(key, default)
    text = f"{key} = {value!r}".replace("'", '"') if isinstance(value, str) else f"{key} = {value}"
    return text if key in table else f"{text} by default"


def _read_columns(
    manifest: Manifest,
    section: str,
    table: dict,
    columns: dict[str, str],
    notes: list[str],
    units: dict[str, str] | None = None,
    declared: dict[str, dict[str, str]] | None = None,
) -> tuple[str, np.ndarray, dict[str, np.ndarray], Provenance]:
    """Read the named columns of a section's CSV: ``(source, time [s], {role: values},
    provenance)``, each role's column named as the user wrote it with its manifest key and
    ``units`` (how the role's unit was declared); a time written twice is dropped when the
    rows agree and refused when they differ (:func:`graphcal.data.streams.unique_samples`)."""
    name = table.get("file")
    if not isinstance(name, str) or not name:
        raise manifest.error(f"[{section}] needs file (the stream's CSV, relative to the manifest)")
    path = manifest.resolve(name)
    source = str(path)
    if not path.is_file():
        raise StreamError(
            f"{source}: no such file (named in {manifest.source} [{section}] file); check the path"
        )
    time_column = manifest.text(table, "time", section)
    unit = manifest.choice(table, "time_unit", TIME_UNITS, section, "s")
    offset = manifest.number(table, "time_offset", 0.0, section)
    header = _readable(source, lambda: pd.read_csv(path, nrows=0, skipinitialspace=True))
    available = [str(c).strip() for c in header.columns]
    wanted = {"time": time_column, **columns}
    for role, column in wanted.items():
        if column not in available:
            raise StreamError(
                f"{source}: no column {column!r} (the manifest's [{section}] {role}); the file "
                f"has {', '.join(available[:12])}"
            )
    frame = _readable(
        source,
        lambda: pd.read_csv(
            path,
            usecols=lambda c: str(c).strip() in set(wanted.values()),
            skipinitialspace=True,
            engine="c",
        ),
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    values = {}
    for role, column in wanted.items():
        numeric = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(numeric)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise StreamError(
                f"{source}: column {column!r}, line {row + 2}: value "
                f"{str(frame[column].iloc[row])!r} is not a finite number; fill or drop that row"
            )
        values[role] = numeric
    units = {"time": _declared(table, "time_unit", "s"), **(units or {})}
    declared = {"time": {"time_unit": unit}, **(declared or {})}
    fields = {
        role: Field(
            column, f"[{section}] {role}", units.get(role), tuple(declared.get(role, {}).items())
        )
        for role, column in wanted.items()
    }
    provenance = Provenance(source, fields, np.arange(len(frame)) + 2)  # the header is line 1
    raw = values.pop("time")
    keep = unique_samples(raw, values, provenance, notes, unit=unit)
    if len(keep) < len(raw):
        raw, provenance = raw[keep], provenance.take(keep)
        values = {role: column[keep] for role, column in values.items()}
    check_time(raw, source, provenance, unit)
    t = raw * TIME_UNITS[unit] + offset
    return source, t, values, provenance


def _read_pose(manifest: Manifest, notes: list[str]) -> PoseStream:
    section, table = manifest.pose_name, manifest.pose
    if "nmea" in table:
        from graphcal.data.nmea import read_nmea_pose

        return read_nmea_pose(manifest, section, table, notes)
    geodetic = "latitude" in table or "longitude" in table
    metric = "x" in table or "y" in table
    if geodetic == metric:
        raise manifest.error(
            f"[{section}] needs latitude and longitude (degrees WGS-84) or x and y (metres), "
            "one pair"
        )
    names = ("latitude", "longitude") if geodetic else ("x", "y")
    columns = {key: manifest.text(table, key, section) for key in names}
    heading = manifest.text(table, "heading", section, required=False)
    if heading is not None:
        columns["heading"] = heading
        heading_unit = manifest.choice(table, "heading_unit", ANGLE_UNITS, section, None)
        convention = manifest.choice(
            table, "heading_convention", HEADING_CONVENTIONS, section, None
        )
    sideslip = manifest.text(table, "sideslip", section, required=False)
    if sideslip is not None:
        columns["sideslip"] = sideslip
        sideslip_unit = manifest.choice(table, "sideslip_unit", ANGLE_UNITS, section, "rad")
    units = {"latitude": "degrees", "longitude": "degrees", "x": "m", "y": "m"}
    declared = {}
    if heading is not None:
        units["heading"] = (
            f"{_declared(table, 'heading_unit')}, {_declared(table, 'heading_convention')}"
        )
        declared["heading"] = {"heading_unit": heading_unit, "heading_convention": convention}
    if sideslip is not None:
        units["sideslip"] = _declared(table, "sideslip_unit", "rad")
        declared["sideslip"] = {"sideslip_unit": sideslip_unit}
    source, t, values, provenance = _read_columns(
        manifest, section, table, columns, notes, units, declared
    )
    origin = None
    if geodetic:
        x, y, origin = geodetic_to_local(
            values["latitude"], values["longitude"], source, provenance=provenance
        )
    else:
        x, y = values["x"], values["y"]
        _check_metric(x, y, provenance)
    psi = None
    if heading is not None:
        psi = values["heading"] * ANGLE_UNITS[heading_unit]
        if convention == "compass":
            psi = 0.5 * np.pi - psi
    beta = values["sideslip"] * ANGLE_UNITS[sideslip_unit] if sideslip is not None else None
    return PoseStream(
        t=t,
        x=x,
        y=y,
        heading=psi,
        sideslip=beta,
        source=source,
        origin=origin,
        provenance=provenance,
    )


#: Largest distance [m] of an x/y position from the first one (1000 km): farther, the
#: positions are not metres of a local frame.
MAX_LOCAL_DISTANCE = 1e6


def _check_metric(x: np.ndarray, y: np.ndarray, provenance: Provenance) -> None:
    """One line if x/y positions are not metres of a local frame (degrees give a drive of
    metres, ECEF or kilometres-as-metres are caught by the wheels; this catches the absurd)."""
    radius = np.hypot(x - x[0], y - y[0])
    far = radius > MAX_LOCAL_DISTANCE
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise StreamError(
            f"{provenance.at(('x', 'y'), k)}: position ({x[k]:.6g}, {y[k]:.6g}) is "
            f"{radius[k] / 1e3:.0f} km from the first one; give x and y in metres (east, "
            "north) of a local frame, or latitude and longitude in degrees"
        )


@dataclass(frozen=True)
class WheelScale:
    """How ``[wheels]``'s values become revolutions: multiply by ``scale`` [rev per unit];
    ``resolution`` [rev] of a tick counter, ``wrap`` its wrap count; the keys read (SI)."""

    scale: float
    resolution: float | None = None
    wrap: float | None = None
    circumference: float | None = None
    ticks: float | None = None
    speed_unit: str | None = None


def wheel_scale(manifest: Manifest, kind: str, speed_unit: Callable[[], str]) -> WheelScale:
    """``[wheels]``'s ``circumference``, ``ticks_per_revolution`` and ``ticks_wrap`` for a
    wheel signal of ``kind``, read and checked (one-line errors); ``speed_unit`` gives the
    speed unit of kind "speed" once the circumference is known (a CSV's key, a DBC's unit)."""
    table = manifest.wheels
    circumference = ticks = unit = resolution = None
    if kind == "speed":
        circumference = manifest.number(table, "circumference", None, "wheels", positive=True)
        if circumference is None:
            raise manifest.error(
                "[wheels] kind = 'speed' needs circumference: the wheel circumference [m] the "
                "ECU used to turn rotations into speed (from its documentation; often 2.0)"
            )
        unit = speed_unit()
        scale = SPEED_UNITS[unit] / circumference
    elif kind == "angular_speed" or kind == "angle":
        scale = 1.0 / (2.0 * np.pi)
    elif kind == "rpm":
        scale = 1.0 / 60.0
    else:  # ticks
        ticks = manifest.number(table, "ticks_per_revolution", None, "wheels", positive=True)
        if ticks is None:
            raise manifest.error("[wheels] kind = 'ticks' needs ticks_per_revolution")
        scale = resolution = 1.0 / ticks
    wrap = manifest.number(table, "ticks_wrap", None, "wheels", positive=True)
    if wrap is not None and kind != "ticks":
        raise manifest.error("[wheels] ticks_wrap applies to kind = 'ticks' only")
    return WheelScale(scale, resolution, wrap, circumference, ticks, unit)


def _read_wheels(manifest: Manifest, notes: list[str]) -> WheelStream:
    table = manifest.wheels
    from graphcal.data.can_log import read_can_section, reads_can

    if reads_can(manifest, "wheels"):
        return read_can_section(manifest, "wheels", notes)
    kind = manifest.choice(table, "kind", WHEEL_KINDS, "wheels", None)
    columns = {key: manifest.text(table, key, "wheels") for key in ("rear_left", "rear_right")}
    if columns["rear_left"] == columns["rear_right"]:
        raise manifest.error(
            f"[wheels] rear_left and rear_right are both {columns['rear_left']!r}; name the two "
            "wheels' columns"
        )
    cumulative = kind in ("ticks", "angle")
    scaling = wheel_scale(
        manifest, kind, lambda: manifest.choice(table, "speed_unit", SPEED_UNITS, "wheels", "m/s")
    )
    scale, resolution, wrap = scaling.scale, scaling.resolution, scaling.wrap
    circumference, ticks, unit = scaling.circumference, scaling.ticks, scaling.speed_unit
    declared = [f"kind = {kind!r}".replace("'", '"')]
    if kind == "speed":
        declared += [_declared(table, "speed_unit", "m/s"), f"circumference = {circumference:g} m"]
    elif kind == "ticks":
        declared.append(f"ticks_per_revolution = {ticks:g}")
    wheel_units = ", ".join(declared)
    keys = {"kind": kind}
    if kind == "speed":
        keys.update(speed_unit=unit, circumference=repr(circumference))
    elif kind == "ticks":
        keys["ticks_per_revolution"] = repr(ticks)
    source, t, values, provenance = _read_columns(
        manifest,
        "wheels",
        table,
        columns,
        notes,
        {"rear_left": wheel_units, "rear_right": wheel_units},
        {"rear_left": keys, "rear_right": keys},
    )
    left, right = values["rear_left"], values["rear_right"]
    if wrap is not None:
        left, right = _unwrap_counter(left, wrap), _unwrap_counter(right, wrap)
    return WheelStream(
        t=t,
        left=left * scale,
        right=right * scale,
        cumulative=cumulative,
        source=source,
        resolution=resolution,
        provenance=provenance,
    )


def _unwrap_counter(counts: np.ndarray, modulus: float) -> np.ndarray:
    """A counter that wraps at ``modulus``, made monotonic across its wrap-arounds."""
    step = np.diff(counts)
    wraps = np.concatenate([[0.0], np.cumsum(np.where(step < -0.5 * modulus, modulus, 0.0))])
    return counts + wraps


def _read_imu(
    manifest: Manifest, notes: list[str], pose: PoseStream, wheels: WheelStream
) -> ImuStream:
    table = manifest.imu
    from graphcal.data.can_log import read_can_section, reads_can

    if reads_can(manifest, "imu"):
        return read_can_section(manifest, "imu", notes)
    if {"acceleration", "angular_velocity", "mounting"} & set(table):
        from graphcal.data.imu_mounting import read_mounted_imu

        return read_mounted_imu(manifest, notes, pose, wheels)
    columns = {
        key: manifest.text(table, key, "imu", required=False)
        for key in ("lateral_acceleration", "yaw_rate")
    }
    columns = {key: value for key, value in columns.items() if value is not None}
    if not columns:
        raise manifest.error(
            "[imu] needs lateral_acceleration or yaw_rate (a column name), or acceleration "
            "or angular_velocity (3 columns) with mounting"
        )
    unit = manifest.choice(table, "yaw_rate_unit", YAW_RATE_UNITS, "imu", "rad/s")
    units = {
        "lateral_acceleration": "m/s², positive to the left",
        "yaw_rate": _declared(table, "yaw_rate_unit", "rad/s"),
    }
    source, t, values, provenance = _read_columns(
        manifest, "imu", table, columns, notes, units, {"yaw_rate": {"yaw_rate_unit": unit}}
    )
    yaw_rate = values.get("yaw_rate")
    return ImuStream(
        t=t,
        lateral_acceleration=values.get("lateral_acceleration"),
        yaw_rate=None if yaw_rate is None else yaw_rate * YAW_RATE_UNITS[unit],
        source=source,
        provenance=provenance,
    )
