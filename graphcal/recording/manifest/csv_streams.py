"""The pose, wheel and IMU streams of a manifest's CSV sections (``[gnss]``/``[pose]``,
``[wheels]``, ``[imu]``), each read from its :class:`~graphcal.recording.section.Section`, in
the units of :mod:`graphcal.recording.streams`; a section naming an NMEA log, a CAN log or a
3-axis IMU goes to that source instead (:mod:`graphcal.recording.manifest_recording`)."""

from __future__ import annotations

import numpy as np

from graphcal.recording.geodesy import geodetic_to_local
from graphcal.recording.manifest.columns import read_columns
from graphcal.recording.section import Section
from graphcal.recording.streams import ImuStream, PoseStream, Provenance, StreamError, WheelStream
from graphcal.recording.vocabulary import (
    ANGLE_UNITS,
    HEADING_CONVENTIONS,
    SPEED_UNITS,
    WHEEL_KINDS,
    YAW_RATE_UNITS,
)
from graphcal.recording.wheel_scale import unwrap_counter, wheel_scale


def read_pose(table: Section, notes: list[str]) -> PoseStream:
    """The pose stream of a ``[gnss]`` or ``[pose]`` section's CSV file: positions in degrees
    or metres, an optional heading and sideslip, in the units its keys declare."""
    section = table.name
    geodetic = "latitude" in table or "longitude" in table
    metric = "x" in table or "y" in table
    if geodetic == metric:
        raise table.error(
            f"[{section}] needs latitude and longitude (degrees WGS-84) or x and y (metres), "
            "one pair"
        )
    names = ("latitude", "longitude") if geodetic else ("x", "y")
    columns = {key: table.text(key) for key in names}
    heading = table.text("heading", required=False)
    if heading is not None:
        columns["heading"] = heading
        heading_unit = table.choice("heading_unit", ANGLE_UNITS, None)
        convention = table.choice("heading_convention", HEADING_CONVENTIONS, None)
    sideslip = table.text("sideslip", required=False)
    if sideslip is not None:
        columns["sideslip"] = sideslip
        sideslip_unit = table.choice("sideslip_unit", ANGLE_UNITS, "rad")
    units = {"latitude": "degrees", "longitude": "degrees", "x": "m", "y": "m"}
    declared = {}
    if heading is not None:
        units["heading"] = (
            f"{table.declaration('heading_unit')}, {table.declaration('heading_convention')}"
        )
        declared["heading"] = {"heading_unit": heading_unit, "heading_convention": convention}
    if sideslip is not None:
        units["sideslip"] = table.declaration("sideslip_unit", "rad")
        declared["sideslip"] = {"sideslip_unit": sideslip_unit}
    source, t, values, provenance = read_columns(table, columns, notes, units, declared)
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


def read_wheels(table: Section, notes: list[str]) -> WheelStream:
    """The wheel stream of a ``[wheels]`` section's CSV file, in revolutions (per sample for
    a cumulative kind), converted by its ``kind``
    (:data:`~graphcal.recording.vocabulary.WHEEL_KINDS`)."""
    kind = table.choice("kind", WHEEL_KINDS, None)
    columns = {key: table.text(key) for key in ("rear_left", "rear_right")}
    if columns["rear_left"] == columns["rear_right"]:
        raise table.error(
            f"[wheels] rear_left and rear_right are both {columns['rear_left']!r}; name the two "
            "wheels' columns"
        )
    cumulative = WHEEL_KINDS[kind].cumulative
    scaling = wheel_scale(table, kind, lambda: table.choice("speed_unit", SPEED_UNITS, "m/s"))
    scale, resolution, wrap = scaling.scale, scaling.resolution, scaling.wrap
    circumference, ticks, unit = scaling.circumference, scaling.ticks, scaling.speed_unit
    declared = [f"kind = {kind!r}".replace("'", '"')]
    if kind == "speed":
        declared += [
            table.declaration("speed_unit", "m/s"),
            f"circumference = {circumference:g} m",
        ]
    elif kind == "ticks":
        declared.append(f"ticks_per_revolution = {ticks:g}")
    wheel_units = ", ".join(declared)
    keys = {"kind": kind}
    if kind == "speed":
        keys.update(speed_unit=unit, circumference=repr(circumference))
    elif kind == "ticks":
        keys["ticks_per_revolution"] = repr(ticks)
    source, t, values, provenance = read_columns(
        table,
        columns,
        notes,
        {"rear_left": wheel_units, "rear_right": wheel_units},
        {"rear_left": keys, "rear_right": keys},
    )
    left, right = values["rear_left"], values["rear_right"]
    if wrap is not None:
        left, right = unwrap_counter(left, wrap), unwrap_counter(right, wrap)
    return WheelStream(
        t=t,
        left=left * scale,
        right=right * scale,
        cumulative=cumulative,
        source=source,
        resolution=resolution,
        provenance=provenance,
    )


def read_imu(table: Section, notes: list[str]) -> ImuStream:
    """The IMU stream of an ``[imu]`` section's CSV file in the vehicle frame: its lateral
    acceleration [m/s²] and yaw rate [rad/s] (a 3-axis IMU in its own frame is
    :func:`graphcal.recording.imu.mounting.mounted_imu`'s)."""
    columns = {key: table.text(key, required=False) for key in ("lateral_acceleration", "yaw_rate")}
    columns = {key: value for key, value in columns.items() if value is not None}
    if not columns:
        raise table.error(
            "[imu] needs lateral_acceleration or yaw_rate (a column name), or acceleration "
            "or angular_velocity (3 columns) with mounting"
        )
    unit = table.choice("yaw_rate_unit", YAW_RATE_UNITS, "rad/s")
    units = {
        "lateral_acceleration": "m/s², positive to the left",
        "yaw_rate": table.declaration("yaw_rate_unit", "rad/s"),
    }
    source, t, values, provenance = read_columns(
        table, columns, notes, units, {"yaw_rate": {"yaw_rate_unit": unit}}
    )
    yaw_rate = values.get("yaw_rate")
    return ImuStream(
        t=t,
        lateral_acceleration=values.get("lateral_acceleration"),
        yaw_rate=None if yaw_rate is None else yaw_rate * YAW_RATE_UNITS[unit],
        source=source,
        provenance=provenance,
    )
