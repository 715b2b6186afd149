"""The units and kinds every recording source speaks: how a declared unit converts to SI,
and what each kind of wheel signal is. A leaf: the manifest, the bag, CAN and NMEA readers
and the import all read it; it imports nothing of graphcal.

A new wheel-encoder kind is one entry of :data:`WHEEL_KINDS` (and a line of the manifest's
documentation, :mod:`graphcal.recording.manifest.manifest`): every reader converts through it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Standard gravity [m/s²].
GRAVITY = 9.80665

#: ``time_unit``: seconds per unit.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: ``heading_unit``, ``sideslip_unit``: radians per unit.
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180.0}
#: ``speed_unit`` of wheel speeds: m/s per unit.
SPEED_UNITS = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}
#: ``yaw_rate_unit``: rad/s per unit.
YAW_RATE_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
#: ``acceleration_unit`` of a 3-axis IMU: m/s² per unit.
ACCELERATION_UNITS = {"m/s²": 1.0, "m/s^2": 1.0, "m/s2": 1.0, "g": GRAVITY}
#: ``angular_velocity_unit`` of a 3-axis IMU: rad/s per unit.
ANGULAR_VELOCITY_UNITS = {"rad/s": 1.0, "deg/s": np.pi / 180.0}
#: ``heading_convention``: enu (0 = east, counter-clockwise) or compass (0 = north, clockwise).
HEADING_CONVENTIONS = ("enu", "compass")


@dataclass(frozen=True)
class WheelKind:
    """What a wheel signal of one kind holds.

    Attributes:
        revolutions_per_unit: the factor to revolutions (per second for a rate, in total for
            a cumulative signal); ``None`` where further keys give it (``speed``: the ECU's
            circumference and speed unit; ``ticks``: ticks per revolution).
        cumulative: the signal counts up (an angle, a tick counter) rather than being a rate.
        unit: the unit, as the manifest's documentation says it.
    """

    revolutions_per_unit: float | None
    cumulative: bool
    unit: str


#: ``[wheels] kind`` (``--wheel-kind``): every kind of wheel signal graphcal reads.
WHEEL_KINDS = {
    "speed": WheelKind(None, False, "m/s of the ECU's circumference"),
    "angular_speed": WheelKind(1.0 / (2.0 * np.pi), False, "rad/s"),
    "rpm": WheelKind(1.0 / 60.0, False, "rev/min"),
    "ticks": WheelKind(None, True, "counts, cumulative"),
    "angle": WheelKind(1.0 / (2.0 * np.pi), True, "rad, cumulative"),
}

#: ``[imu]`` keys of a 3-axis IMU in its own frame (rotated by :mod:`graphcal.recording.imu`).
MOUNTED_KEYS = (
    "acceleration",
    "acceleration_unit",
    "angular_velocity",
    "angular_velocity_unit",
    "mounting",
)
