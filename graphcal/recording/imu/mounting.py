"""A mounted IMU: its 3-axis signals rotated from its own frame into the vehicle frame
(``[imu] acceleration``, ``angular_velocity``, ``mounting``), by a given mounting
(:mod:`graphcal.recording.imu.frame`: the convention) or one estimated from the drive
(:mod:`graphcal.recording.imu.estimate`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from graphcal.recording.imu.estimate import estimate_mounting
from graphcal.recording.imu.frame import (
    bin_means,
    check_mounting,
    degrees_text,
    rotation,
    to_vehicle,
)
from graphcal.recording.section import Section
from graphcal.recording.streams import (
    Field,
    ImuStream,
    PoseStream,
    Provenance,
    StreamError,
    WheelStream,
)
from graphcal.recording.vocabulary import ACCELERATION_UNITS, ANGULAR_VELOCITY_UNITS

#: The ``mounting`` value that asks for the estimate.
ESTIMATE = "estimate"
#: How far [1] a given matrix may be from a rotation (max |RᵀR − I|).
ROTATION_TOLERANCE = 1e-3


def parse_mounting(value: Any, where: str) -> np.ndarray | str:
    """The ``mounting`` value: :data:`ESTIMATE`, or its rotation ``R`` ``(3, 3)`` from
    ``[roll, pitch, yaw]`` [deg] or a 3×3 matrix (rows); ``where`` prefixes the one-line
    error (``"manifest.toml: [imu] mounting"``)."""
    how = (
        "give [roll, pitch, yaw] in degrees (vehicle = Rz(yaw)·Ry(pitch)·Rx(roll)·IMU), a 3×3 "
        'rotation matrix, or "estimate"'
    )
    if isinstance(value, str):
        if value == ESTIMATE:
            return ESTIMATE
        raise StreamError(f"{where} = {_toml(value)} is not known; {how}")
    if not isinstance(value, list):
        raise StreamError(f"{where} = {_toml(value)}: {how}")
    if value and all(isinstance(row, list) for row in value):
        rows = value
        if len(rows) != 3 or any(len(row) != 3 for row in rows):
            shape = "×".join(map(str, (len(rows), *{len(row) for row in rows})))
            raise StreamError(f"{where} is a {shape} matrix; {how}")
        numbers = [x for row in rows for x in row]
    else:
        numbers = value
        if len(numbers) != 3:
            raise StreamError(f"{where} = {_toml(value)} has {len(numbers)} value(s); {how}")
    if any(isinstance(x, bool) or not isinstance(x, int | float) for x in numbers) or not all(
        np.isfinite(numbers)
    ):
        raise StreamError(f"{where} = {_toml(value)} must hold finite numbers; {how}")
    if numbers is value:
        return rotation(*np.radians(np.asarray(value, dtype=float)))
    matrix = np.asarray(value, dtype=float)
    off = float(np.abs(matrix.T @ matrix - np.eye(3)).max())
    if off > ROTATION_TOLERANCE:
        raise StreamError(
            f"{where}: the matrix is not orthonormal (|RᵀR − I| up to {off:.2g}), not a "
            f"rotation; {how}"
        )
    if np.linalg.det(matrix) < 0:
        raise StreamError(
            f"{where}: the matrix is a reflection (determinant −1), not a rotation: a "
            f"left-handed axis, or one axis negated; {how}"
        )
    return matrix


def _toml(value: Any) -> str:
    """A manifest value as TOML writes it (``["ax", "ay"]``, ``[5.0, 90.0]``, ``"guess"``)."""
    return json.dumps(value, ensure_ascii=False)


def _column_list(table: Section, key: str) -> list[str] | None:
    """The three columns of ``acceleration`` or ``angular_velocity``, or ``None``."""
    value = table.get(key)
    if value is None:
        return None
    example = '["ax", "ay", "az"]' if key == "acceleration" else '["wx", "wy", "wz"]'
    if (
        not isinstance(value, list)
        or len(value) != 3
        or not all(isinstance(c, str) and c for c in value)
    ):
        count = f"{len(value)} column(s) " if isinstance(value, list) else ""
        raise table.error(
            f"[imu] {key} = {_toml(value)} names {count}but needs 3: the x, y and z columns of the "
            f"IMU's own frame, e.g. {key} = {example}"
        )
    if len(set(value)) < 3:
        raise table.error(f"[imu] {key} = {_toml(value)} names a column twice; name x, y and z")
    return value


def _check_keys(table: Section) -> None:
    """One line for a mix of the vehicle-frame keys and the 3-axis ones."""
    for frame, mounted, unit in (
        ("lateral_acceleration", "acceleration", None),
        ("yaw_rate", "angular_velocity", "yaw_rate_unit"),
    ):
        if frame in table and mounted in table:
            raise table.error(
                f"[imu] has both {frame} (vehicle frame) and {mounted} (the IMU's frame, rotated "
                f"by mounting); keep one"
            )
        if unit in table and mounted in table:
            raise table.error(
                f"[imu] {unit} applies to yaw_rate; with {mounted} use angular_velocity_unit"
            )
    for key, needs in (
        ("acceleration_unit", "acceleration"),
        ("angular_velocity_unit", "angular_velocity"),
    ):
        if key in table and needs not in table:
            raise table.error(f"[imu] {key} applies to {needs}, which is not given")
    if "mounting" not in table:
        raise table.error(
            "[imu] acceleration and angular_velocity are in the IMU's frame: add mounting = "
            '[roll, pitch, yaw] (degrees; [0, 0, 0] if its axes are the vehicle\'s) or "estimate"'
        )
    if not table.has_any(("acceleration", "angular_velocity")):
        raise table.error(
            "[imu] mounting rotates acceleration and angular_velocity (3 columns each), and "
            "neither is given; without them, lateral_acceleration and yaw_rate are in the "
            "vehicle frame already"
        )


@dataclass(frozen=True)
class MountedColumns:
    """What an ``[imu]`` section of a 3-axis IMU asks to read and how to rotate it.

    Attributes:
        mounting: the rotation ``(3, 3)`` (vehicle = R · IMU), or :data:`ESTIMATE`.
        accelerations, rates: the x, y, z columns of ``acceleration`` and
            ``angular_velocity`` (``None``: not given).
        acceleration_unit, rate_unit: their units (keys of
            :data:`~graphcal.recording.vocabulary.ACCELERATION_UNITS`, ``ANGULAR_VELOCITY_UNITS``).
        columns: by role (``"acceleration[0]"``), the column to read; ``units`` how each
            role's unit was declared, for messages.
        declared: how ``acceleration_unit`` and ``angular_velocity_unit`` read
            (``'acceleration_unit = "g"'``, ``... by default``), for messages.
        where: ``"manifest.toml: [imu] mounting"``, what messages about the mounting start
            with.
    """

    mounting: np.ndarray | str
    accelerations: list[str] | None
    rates: list[str] | None
    acceleration_unit: str
    rate_unit: str
    columns: dict[str, str]
    units: dict[str, str]
    declared: tuple[str, str]
    where: str


def mounted_columns(table: Section) -> MountedColumns:
    """The ``[imu]`` keys of a 3-axis IMU in its own frame (``acceleration``,
    ``angular_velocity``, their units, ``mounting``), checked (one-line errors): the columns to
    read and how to rotate them (:func:`mounted_imu`)."""
    _check_keys(table)
    where = f"{table.source}: [imu] mounting"
    mounting = parse_mounting(table["mounting"], where)
    accelerations = _column_list(table, "acceleration")
    rates = _column_list(table, "angular_velocity")
    if isinstance(mounting, str) and (accelerations is None or rates is None):
        raise StreamError(
            f'{where} = "estimate" needs both acceleration and angular_velocity (gravity and '
            "the turns); give mounting = [roll, pitch, yaw] in degrees instead"
        )
    acceleration_unit = table.choice("acceleration_unit", ACCELERATION_UNITS, "m/s²")
    rate_unit = table.choice("angular_velocity_unit", ANGULAR_VELOCITY_UNITS, "rad/s")
    columns: dict[str, str] = {}
    for key, names in (("acceleration", accelerations), ("angular_velocity", rates)):
        for axis, name in enumerate(names or ()):
            columns[f"{key}[{axis}]"] = name
    acceleration_declared = table.declaration("acceleration_unit", "m/s²")
    rate_declared = table.declaration("angular_velocity_unit", "rad/s")
    units = {
        role: acceleration_declared if role.startswith("acceleration") else rate_declared
        for role in columns
    }
    return MountedColumns(
        mounting,
        accelerations,
        rates,
        acceleration_unit,
        rate_unit,
        columns,
        units,
        (acceleration_declared, rate_declared),
        where,
    )


def mounted_imu(
    table: Section,
    asked: MountedColumns,
    read: tuple[str, np.ndarray, dict[str, np.ndarray], Provenance],
    drive: tuple[PoseStream, WheelStream],
    notes: list[str],
) -> ImuStream:
    """A 3-axis IMU's columns (``read``: source, time [s], values by role and provenance, as
    :func:`mounted_columns` asked) rotated into the vehicle frame: its lateral acceleration
    [m/s²] and yaw rate [rad/s]. With ``mounting = "estimate"`` the mounting is estimated from
    the ``drive`` (:func:`estimate_mounting`; the pose and the wheels give the vehicle's
    accelerations) and said in a note."""
    source, t, values, provenance = read
    pose, wheels = drive
    accelerations, rates, mounting = asked.accelerations, asked.rates, asked.mounting
    where, (acceleration_declared, rate_declared) = asked.where, asked.declared
    force = rate = None
    if accelerations is not None:
        force = np.column_stack([values[f"acceleration[{i}]"] for i in range(3)])
        force *= ACCELERATION_UNITS[asked.acceleration_unit]
    if rates is not None:
        rate = np.column_stack([values[f"angular_velocity[{i}]"] for i in range(3)])
        rate *= ANGULAR_VELOCITY_UNITS[asked.rate_unit]
    if isinstance(mounting, str):
        estimate = estimate_mounting(t, force, rate, pose, wheels, where)
        matrix = estimate.rotation
        notes.append(f"{source}: {estimate.note()}")
        mounting_value = f'"estimate" = {degrees_text(matrix)}'
    else:
        matrix = mounting
        mounting_value = _toml(table["mounting"])
        binned = None if rate is None else bin_means(t, rate)
        check_mounting(matrix, force, binned, f"{where} = {mounting_value}", acceleration_declared)
    mounting_text = f"mounting = {mounting_value}"
    fields = dict(provenance.fields)
    if accelerations is not None:
        fields["lateral_acceleration"] = Field(
            ", ".join(accelerations),
            "[imu] acceleration",
            f"{acceleration_declared}, {mounting_text}",
            (("acceleration_unit", asked.acceleration_unit), ("mounting", mounting_value)),
        )
    if rates is not None:
        fields["yaw_rate"] = Field(
            ", ".join(rates),
            "[imu] angular_velocity",
            f"{rate_declared}, {mounting_text}",
            (("angular_velocity_unit", asked.rate_unit), ("mounting", mounting_value)),
        )
    return ImuStream(
        t=t,
        lateral_acceleration=None if force is None else to_vehicle(matrix, force)[:, 1],
        yaw_rate=None if rate is None else to_vehicle(matrix, rate)[:, 2],
        source=source,
        provenance=dataclasses.replace(provenance, fields=fields),
    )


def mounted_fix(field: Field | None) -> str | None:
    """For a quantity rotated from a mounted IMU's columns (:func:`mounted_imu`), the
    keys to check, in the manifest's words (``check [imu] angular_velocity_unit (now
    "rad/s") and mounting (now [5, 0, 90])``); ``None`` for any other field."""
    mounting = None if field is None else field.declares("mounting")
    if mounting is None:
        return None
    unit_key, unit = next((k, v) for k, v in field.declared if k.endswith("_unit"))
    return (
        f'check {field.section} {unit_key} (now "{unit}") and mounting (now {mounting}: roll, '
        "pitch, yaw in degrees, vehicle = Rz(yaw)·Ry(pitch)·Rx(roll)·IMU)"
    )
