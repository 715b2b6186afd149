"""What :func:`graphcal.recording.bag.read.read_bag` is asked to read: its options, checked, and how
the wheel fields they name convert to revolutions (pure Python, no rosbags)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from graphcal.recording.bag.fields import FieldRef
from graphcal.recording.streams import StreamError
from graphcal.recording.vocabulary import (
    ANGLE_UNITS,
    HEADING_CONVENTIONS,
    SPEED_UNITS,
    WHEEL_KINDS,
    YAW_RATE_UNITS,
)


@dataclass(frozen=True)
class BagRequest:
    """What :func:`~graphcal.recording.bag.read.read_bag` is asked to read (a field left
    ``None``: detect).

    Attributes:
        pose_topic: NavSatFix, Odometry, PoseStamped or PoseWithCovarianceStamped topic;
            ``None``: the only topic of one of these types.
        wheel_topic: JointState topic, a vendor wheel-speed topic, or a topic whose fields
            ``rear_left`` / ``rear_right`` name; ``None``: the only vendor wheel-speed topic,
            else the only JointState topic.
        imu_topic: Imu topic (or the topic of bare ``yaw_rate`` / ``lateral_acceleration``
            fields); ``None``: the only one, or no IMU stream if there is none.
        rear_left, rear_right: joint names of the rear wheels, or fields (``TOPIC:FIELD``,
            or a bare field of the other's topic or of ``wheel_topic``); ``None``: the two
            joints named ``*left*`` / ``*right*`` (preferring ``*rear*``), or a vendor
            message's rear wheels.
        wheel_kind: what the wheels hold. A JointState: ``"angle"`` (position [rad],
            cumulative) or ``"angular_speed"`` (velocity [rad/s]); ``None``: positions when
            every message carries them, else velocities. Fields: also ``"speed"`` (needs
            ``circumference`` and ``speed_unit``), ``"rpm"``, ``"ticks"`` (cumulative; needs
            ``ticks_per_revolution``), as ``[wheels] kind`` of a manifest; a vendor message:
            ``angular_speed`` by default.
        speed_unit: ``"m/s"`` (default), ``"km/h"`` or ``"mph"`` of ``kind = "speed"``.
        circumference: [m] the ECU's wheel circumference of ``kind = "speed"``.
        ticks_per_revolution: counts per wheel revolution of ``kind = "ticks"``.
        heading: ``TOPIC:FIELD`` of the heading (replaces the pose's; interpolated at the pose
            times); ``heading_unit`` ``"rad"`` (default) or ``"deg"``, ``heading_convention``
            ``"enu"`` (default, REP 103) or ``"compass"``.
        yaw_rate, lateral_acceleration: fields of the IMU signals (instead of an Imu topic);
            ``yaw_rate_unit`` ``"rad/s"`` (default) or ``"deg/s"``; lateral acceleration in
            m/s², positive to the left.
    """

    pose_topic: str | None = None
    wheel_topic: str | None = None
    imu_topic: str | None = None
    rear_left: str | None = None
    rear_right: str | None = None
    wheel_kind: str | None = None
    speed_unit: str | None = None
    circumference: float | None = None
    ticks_per_revolution: float | None = None
    heading: str | None = None
    heading_unit: str | None = None
    heading_convention: str | None = None
    yaw_rate: str | None = None
    yaw_rate_unit: str | None = None
    lateral_acceleration: str | None = None


def check_request(source: str, r: BagRequest) -> None:
    """One line for an option's value that is unknown or out of range."""
    choices = (
        ("--wheel-kind", r.wheel_kind, WHEEL_KINDS),
        ("--speed-unit", r.speed_unit, tuple(SPEED_UNITS)),
        ("--heading-unit", r.heading_unit, tuple(ANGLE_UNITS)),
        ("--heading-convention", r.heading_convention, HEADING_CONVENTIONS),
        ("--yaw-rate-unit", r.yaw_rate_unit, tuple(YAW_RATE_UNITS)),
    )
    for flag, value, options in choices:
        if value is not None and value not in options:
            raise StreamError(f"{source}: {flag} {value!r} is unknown; use {', '.join(options)}")
    for flag, value in (
        ("--circumference", r.circumference),
        ("--ticks-per-revolution", r.ticks_per_revolution),
    ):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise StreamError(f"{source}: {flag} {value} must be a positive number")


@dataclass(frozen=True)
class WheelFields:
    """The rear wheels as two numeric fields of one topic, and what they hold."""

    topic: str
    left: FieldRef
    right: FieldRef
    kind: str
    vendor: str | None = None


def wheel_conversion(
    source: str, fields: WheelFields | None, r: BagRequest
) -> tuple[float, bool, float | None, str, tuple[tuple[str, str], ...]]:
    """``(scale to revolutions [per second], cumulative, resolution [rev], unit text, declared
    units)`` of the wheel fields' kind, as ``[wheels] kind`` converts a CSV's columns."""
    given = {
        "--speed-unit": r.speed_unit,
        "--circumference": r.circumference,
        "--ticks-per-revolution": r.ticks_per_revolution,
    }
    kind = fields.kind if fields is not None else r.wheel_kind
    needs = {"speed": ("--speed-unit", "--circumference"), "ticks": ("--ticks-per-revolution",)}
    for flag, value in given.items():
        if value is not None and (fields is None or flag not in needs.get(kind or "", ())):
            applies = "speed" if flag != "--ticks-per-revolution" else "ticks"
            raise StreamError(
                f"{source}: {flag} applies to wheels read from fields (--rear-left TOPIC:FIELD) "
                f"with --wheel-kind {applies}; leave it out"
            )
    if fields is None:
        return 1.0, True, None, "", ()
    if kind == "speed":
        if r.circumference is None:
            raise StreamError(
                f"{source}: --wheel-kind speed needs --circumference: the wheel circumference [m] "
                "the ECU used to turn rotations into speed (from its documentation; often 2.0)"
            )
        unit = r.speed_unit or "m/s"
        by_default = "" if r.speed_unit else " by default"
        text = (
            f"--wheel-kind speed, --speed-unit {unit}{by_default}, "
            f"--circumference {r.circumference:g} m"
        )
        declared = (("kind", kind), ("speed_unit", unit), ("circumference", repr(r.circumference)))
        return SPEED_UNITS[unit] / r.circumference, False, None, text, declared
    if kind == "ticks":
        if r.ticks_per_revolution is None:
            raise StreamError(f"{source}: --wheel-kind ticks needs --ticks-per-revolution")
        ticks = r.ticks_per_revolution
        text = f"--wheel-kind ticks, --ticks-per-revolution {ticks:g}"
        declared = (("kind", kind), ("ticks_per_revolution", repr(ticks)))
        return 1.0 / ticks, True, 1.0 / ticks, text, declared
    text = fields.vendor or f"--wheel-kind {kind}"
    wheel = WHEEL_KINDS[kind]
    return wheel.revolutions_per_unit, wheel.cumulative, None, text, (("kind", kind),)
