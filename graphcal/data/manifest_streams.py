"""The pose, wheel and IMU streams of a manifest's CSV sections (``[gnss]``/``[pose]``,
``[wheels]``, ``[imu]``), in the units of :mod:`graphcal.data.streams`; an NMEA log, a CAN
log or a 3-axis IMU named in a section is read by its own module."""

from __future__ import annotations

import numpy as np

from graphcal.data.geodesy import geodetic_to_local
from graphcal.data.manifest import (
    ANGLE_UNITS,
    HEADING_CONVENTIONS,
    SPEED_UNITS,
    WHEEL_KINDS,
    YAW_RATE_UNITS,
    Manifest,
)
from graphcal.data.manifest_columns import declaration, read_columns
from graphcal.data.streams import ImuStream, PoseStream, Provenance, StreamError, WheelStream
from graphcal.data.wheel_scale import unwrap_counter, wheel_scale


def read_pose(manifest: Manifest, notes: list[str]) -> PoseStream:
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
            f"{declaration(table, 'heading_unit')}, {declaration(table, 'heading_convention')}"
        )
        declared["heading"] = {"heading_unit": heading_unit, "heading_convention": convention}
    if sideslip is not None:
        units["sideslip"] = declaration(table, "sideslip_unit", "rad")
        declared["sideslip"] = {"sideslip_unit": sideslip_unit}
    source, t, values, provenance = read_columns(
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


def read_wheels(manifest: Manifest, notes: list[str]) -> WheelStream:
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
        declared += [
            declaration(table, "speed_unit", "m/s"),
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


def read_imu(
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
        "yaw_rate": declaration(table, "yaw_rate_unit", "rad/s"),
    }
    source, t, values, provenance = read_columns(
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
