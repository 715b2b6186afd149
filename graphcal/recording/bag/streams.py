"""The streams of a bag's rows: pose, wheels and IMU, in the units of
:mod:`graphcal.recording.streams`.

Each function turns the :class:`~graphcal.recording.bag.rows.TopicRows` of one topic into a
stream: sorted by stamp, a stamp written twice dropped or refused as for a CSV
(:func:`graphcal.recording.streams.unique_samples`), its :class:`Provenance` naming the message
fields; latitude/longitude become east/north [m], quaternions a heading [rad, ENU], joint
angles and fields revolutions [per second]. ``source`` is ``bag:topic`` in messages.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from graphcal.recording.bag.fields import FieldRef
from graphcal.recording.bag.request import BagRequest, WheelFields, wheel_conversion
from graphcal.recording.bag.rows import IMU_FIELDS, POSE_FIELDS, TopicRows
from graphcal.recording.bag.topics import NAVSATFIX, ODOMETRY
from graphcal.recording.geodesy import GeodesyError, geodetic_to_local
from graphcal.recording.streams import (
    Field,
    ImuStream,
    PoseStream,
    Provenance,
    StreamError,
    WheelStream,
    unique_samples,
)
from graphcal.recording.streams import check_time as _check_time
from graphcal.recording.vocabulary import ANGLE_UNITS, YAW_RATE_UNITS

#: Forward body-frame speed [m/s] above which an Odometry twist's direction gives the
#: sideslip.
SIDESLIP_MIN_SPEED = 0.5


def field_values(
    source: str, rows: TopicRows, refs: list[FieldRef], notes: list[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(values, t, numbers)`` of a field topic's messages whose fields are all finite."""
    paths = " and ".join(ref.path for ref in refs)
    if not len(rows):
        raise StreamError(
            f"{source}: no message has {paths} (an index beyond the end of every message's "
            "array); name fields that the messages carry"
        )
    if rows.skipped:
        notes.append(f"{source}: skipped {rows.skipped} message(s) without {paths}")
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    finite = np.isfinite(values).all(axis=1)
    if not finite.any():
        raise StreamError(f"{source}: {paths} is not finite in any message; name another field")
    if not finite.all():
        notes.append(f"{source}: skipped {int((~finite).sum())} message(s) where {paths} is NaN")
        values, t, numbers = values[finite], t[finite], numbers[finite]
    return values, t, numbers


def unique(
    source: str,
    names: tuple[str, ...],
    values: np.ndarray,
    t: np.ndarray,
    numbers: np.ndarray,
    fields: dict[str, Field],
    notes: list[str],
) -> tuple[np.ndarray, np.ndarray, Provenance]:
    """The topic's rows sorted by stamp, a stamp written twice dropped when the messages
    agree and refused when they differ (the rule of CSV streams too:
    :func:`graphcal.recording.streams.unique_samples`); returns ``values``, ``t`` and the
    :class:`Provenance` of the kept rows."""
    provenance = Provenance(source, {**{n: Field(n) for n in names}, **fields}, numbers, "message")
    columns = {name: values[:, j] for j, name in enumerate(names)}
    keep = unique_samples(t, columns, provenance, notes, sort=True)
    return values[keep], t[keep], provenance.take(keep)


def quaternion_yaw(q: np.ndarray) -> np.ndarray:
    """Yaw [rad] (ENU, about z) of quaternions ``(x, y, z, w)``, ``(M, 4)``."""
    x, y, z, w = q.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pose_stream(source: str, msgtype: str, rows: TopicRows, notes: list[str]) -> PoseStream:
    """The pose of a NavSatFix (east/north [m] of the first fix, no heading), Odometry (with
    the sideslip of its twist), PoseStamped or PoseWithCovarianceStamped topic."""
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    names = POSE_FIELDS[msgtype]
    if msgtype == NAVSATFIX:
        fields = {"latitude": Field("latitude", None, "degrees")}
        fields["longitude"] = Field("longitude", None, "degrees")
    else:
        fields = {"x": Field(names[0], None, "m"), "y": Field(names[1], None, "m")}
        fields["heading"] = Field(names[2].rsplit(".", 1)[0], None, "yaw of the quaternion")
    if msgtype == NAVSATFIX:
        fixed = (values[:, 2] >= 0) & np.isfinite(values[:, :2]).all(axis=1)
        if not fixed.any():
            raise StreamError(
                f"{source}: none of the {len(t)} NavSatFix messages has a fix (status >= 0 and "
                "finite latitude/longitude); record the receiver with a fix or pass --pose-topic"
            )
        if not fixed.all():
            notes.append(f"{source}: skipped {int((~fixed).sum())} NavSatFix without a fix")
        values, t, numbers = values[fixed], t[fixed], numbers[fixed]
    values, t, provenance = unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    if msgtype == NAVSATFIX:
        try:
            x, y, origin = geodetic_to_local(
                values[:, 0], values[:, 1], source, provenance=provenance
            )
        except GeodesyError as error:
            raise StreamError(str(error)) from None
        return PoseStream(t, x, y, None, None, source, origin, provenance)
    quaternion = values[:, 2:6]
    if not np.linalg.norm(quaternion, axis=1).any():
        notes.append(f"{source}: orientation all zero (not logged); positions only are measured")
        heading = None
    else:
        heading = quaternion_yaw(quaternion)
    sideslip = None
    if msgtype == ODOMETRY:  # body-frame twist (child frame): its direction is the sideslip
        vx, vy = values[:, 6], values[:, 7]
        forward = vx >= SIDESLIP_MIN_SPEED  # reversing (masked by the wheels) and standstill: 0
        if forward.any() and np.abs(vy).any():
            sideslip = np.where(forward, np.arctan2(vy, np.where(forward, vx, 1.0)), 0.0)
            notes.append(f"{source}: sideslip from the direction of the body-frame twist")
            provenance.fields["sideslip"] = Field("twist.twist.linear", None, "its direction")
    x, y = values[:, 0].copy(), values[:, 1].copy()
    return PoseStream(t, x, y, heading, sideslip, source, provenance=provenance)


def joint_wheel_stream(
    source: str,
    rows: TopicRows,
    joints: tuple[str, str],
    seen: set[str],
    wheel_kind: str | None,
    notes: list[str],
) -> WheelStream:
    """The wheels [rev] or [rev/s] of two joints of a JointState: their positions (angle) or
    velocities (angular_speed; ``None``: positions when every message has them)."""
    names = ", ".join(sorted(seen)) or "none"
    if not len(rows):
        raise StreamError(
            f"{source}: no JointState message has both joints {joints[0]} and {joints[1]} "
            f"(joint names: {names}); pass --rear-left/--rear-right with two of them"
        )
    if rows.skipped:
        notes.append(
            f"{source}: skipped {rows.skipped} JointState message(s) without both {joints[0]} "
            f"and {joints[1]}"
        )
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    has_position = np.isfinite(values[:, :2]).all(axis=1)
    has_velocity = np.isfinite(values[:, 2:]).all(axis=1)
    if wheel_kind is None:
        wheel_kind = "angle" if has_position.all() or not has_velocity.any() else "angular_speed"
    angle = wheel_kind == "angle"
    present = has_position if angle else has_velocity
    field_name, other = ("position", "angular_speed") if angle else ("velocity", "angle")
    if not present.any():
        raise StreamError(
            f"{source}: the JointState messages carry no {field_name} of {joints[0]} and "
            f"{joints[1]}; pass --wheel-kind {other} or record the {field_name}"
        )
    if not present.all():
        notes.append(
            f"{source}: skipped {int((~present).sum())} JointState message(s) without a "
            f"{field_name}"
        )
    values, t, numbers = values[present], t[present], numbers[present]
    names = tuple(f"{kind}[{joint}]" for kind in ("position", "velocity") for joint in joints)
    unit = "rad, cumulative" if angle else "rad/s"
    used = names[:2] if angle else names[2:]
    fields = {"rear_left": Field(used[0], None, unit), "rear_right": Field(used[1], None, unit)}
    values, t, provenance = unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    columns = values[:, :2] if angle else values[:, 2:]
    revolutions = columns / (2.0 * np.pi)
    return WheelStream(
        t,
        revolutions[:, 0].copy(),
        revolutions[:, 1].copy(),
        cumulative=angle,
        source=source,
        provenance=provenance,
    )


def imu_stream(source: str, rows: TopicRows, notes: list[str]) -> ImuStream:
    """The lateral acceleration [m/s²] and yaw rate [rad/s] of an Imu topic (REP 103)."""
    values, t, numbers = rows.values(), rows.times(source, notes), rows.numbers()
    fields = {
        "lateral_acceleration": Field(IMU_FIELDS[0], None, "m/s², REP 103: y to the left"),
        "yaw_rate": Field(IMU_FIELDS[1], None, "rad/s, REP 103: z up"),
    }
    values, t, provenance = unique(source, IMU_FIELDS, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    signals = []
    for column, covariance, what in ((0, 2, "linear acceleration"), (1, 3, "angular velocity")):
        # REP 145: a covariance whose first element is -1 means "this field is not provided".
        if (values[:, covariance] == -1).all():
            notes.append(f"{source}: {what} not provided (covariance -1)")
            signals.append(None)
        else:
            signals.append(values[:, column].copy())
    return ImuStream(t, signals[0], signals[1], source, provenance)


def imu_heading(rows: TopicRows, imu: ImuStream, pose: PoseStream, notes: list[str]) -> PoseStream:
    """``pose`` with the heading of the IMU's orientation (an INS's), if it gives one.

    A NavSatFix has no heading; an INS publishes its orientation in the Imu messages. The
    yaw is unwrapped and interpolated at the fix times.
    """
    values = rows.values()
    t_raw = rows.times(imu.source, [])
    provided = values[:, 4] != -1
    quaternion = values[:, 5:9]
    if not provided.all() or not np.linalg.norm(quaternion, axis=1).all():
        return pose
    order = np.argsort(t_raw, kind="stable")
    t_sorted, yaw = t_raw[order], np.unwrap(quaternion_yaw(quaternion[order]))
    keep = np.concatenate([[True], np.diff(t_sorted) > 0])
    heading = np.interp(pose.t, t_sorted[keep], yaw[keep])
    notes.append(f"heading from the orientation of {imu.source} (an INS), at the fix times")
    return dataclasses.replace(pose, heading=heading)


def field_wheel_stream(
    source: str, fields: WheelFields, rows: TopicRows, r: BagRequest, notes: list[str]
) -> WheelStream:
    """The wheel stream of two fields, converted to revolutions [per second] by their kind."""
    scale, cumulative, resolution, unit, declared = wheel_conversion(source, fields, r)
    refs = [fields.left, fields.right]
    values, t, numbers = field_values(source, rows, refs, notes)
    roles = ("rear_left", "rear_right")
    provenance_fields = {
        role: Field(ref.path, ref.flag, unit, declared)
        for role, ref in zip(roles, refs, strict=True)
    }
    names = (fields.left.path, fields.right.path)
    values, t, provenance = unique(source, names, values, t, numbers, provenance_fields, notes)
    _check_time(t, source, provenance)
    return WheelStream(
        t,
        values[:, 0] * scale,
        values[:, 1] * scale,
        cumulative=cumulative,
        source=source,
        resolution=resolution,
        provenance=provenance,
    )


def field_imu_stream(
    source: str, refs: list[FieldRef], rows: TopicRows, r: BagRequest, notes: list[str]
) -> ImuStream:
    """The IMU stream of ``--lateral-acceleration`` and/or ``--yaw-rate`` fields."""
    values, t, numbers = field_values(source, rows, refs, notes)
    unit = r.yaw_rate_unit or "rad/s"
    fields = {}
    for ref in refs:
        if ref.flag == "--yaw-rate":
            by_default = "" if r.yaw_rate_unit else " by default"
            fields["yaw_rate"] = Field(
                ref.path,
                ref.flag,
                f"--yaw-rate-unit {unit}{by_default}",
                (("yaw_rate_unit", unit),),
            )
        else:
            fields["lateral_acceleration"] = Field(ref.path, ref.flag, "m/s², positive to the left")
    names = tuple(ref.path for ref in refs)
    values, t, provenance = unique(source, names, values, t, numbers, fields, notes)
    _check_time(t, source, provenance)
    signals: dict[str, np.ndarray | None] = {"lateral_acceleration": None, "yaw_rate": None}
    for column, role in enumerate(fields):
        scale = YAW_RATE_UNITS[unit] if role == "yaw_rate" else 1.0
        signals[role] = values[:, column] * scale
    return ImuStream(t, signals["lateral_acceleration"], signals["yaw_rate"], source, provenance)


def field_heading(
    source: str,
    ref: FieldRef,
    rows: TopicRows,
    pose: PoseStream,
    r: BagRequest,
    notes: list[str],
) -> PoseStream:
    """``pose`` with the heading of a field (``--heading``), unwrapped and interpolated at the
    pose's times; ``--heading-unit`` (default rad) and ``--heading-convention`` (default enu,
    REP 103) as ``[gnss] heading_unit`` / ``heading_convention`` for a CSV."""
    values, t, _ = field_values(source, rows, [ref], notes)
    unit, convention = r.heading_unit or "rad", r.heading_convention or "enu"
    angle = values[:, 0] * ANGLE_UNITS[unit]
    if convention == "compass":
        angle = 0.5 * np.pi - angle
    order = np.argsort(t, kind="stable")
    t_sorted, yaw = t[order], np.unwrap(angle[order])
    keep = np.concatenate([[True], np.diff(t_sorted) > 0])
    heading = np.interp(pose.t, t_sorted[keep], yaw[keep])
    replaced = ", replacing the pose's orientation" if pose.heading is not None else ""
    notes.append(f"heading from {ref.written} ({unit}, {convention}) at the pose times{replaced}")
    field = Field(
        ref.written,
        "--heading",
        f"--heading-unit {unit}, --heading-convention {convention}",
        (("heading_unit", unit), ("heading_convention", convention)),
    )
    provenance = pose.provenance
    if provenance is not None:
        provenance = dataclasses.replace(provenance, fields={**provenance.fields, "heading": field})
    return dataclasses.replace(pose, heading=heading, provenance=provenance)
