"""Vendors' wheel-speed messages, read from a bag without flags, and speed-only messages.

:data:`VENDOR_WHEELS` names each known wheel-speed message's rear wheels;
:data:`VENDOR_DEFINITIONS` holds their definitions for bags that carry none (a ROS 2 bag
recorded before Iron); :data:`SPEED_ONLY` lists messages with the vehicle's speed but not
each wheel's, refused as wheels with a message saying so.
"""

from __future__ import annotations

#: Vendor wheel-speed messages read without flags: type → (what it is, the rear-left and
#: rear-right fields, their kind). Both report each wheel's angular speed [rad/s].
VENDOR_WHEELS = {
    "dbw_mkz_msgs/msg/WheelSpeedReport": (
        "Dataspeed wheel speeds, rad/s",
        "rear_left",
        "rear_right",
    ),
    "pacmod_msgs/msg/WheelSpeedRpt": (
        "PACMod wheel speeds, rad/s",
        "rear_left_wheel_speed",
        "rear_right_wheel_speed",
    ),
    "pacmod3_msgs/msg/WheelSpeedRpt": (
        "PACMod wheel speeds, rad/s",
        "rear_left_wheel_speed",
        "rear_right_wheel_speed",
    ),
}
#: Messages with the vehicle's speed but not each wheel's: refused as wheels, saying so.
SPEED_ONLY = (
    "autoware_auto_vehicle_msgs/msg/VelocityReport",
    "autoware_vehicle_msgs/msg/VelocityReport",
)
#: Their definitions, registered when a bag carries none (a ROS 2 bag recorded before Iron).
VENDOR_DEFINITIONS = {
    "dbw_mkz_msgs/msg/WheelSpeedReport": (
        "std_msgs/Header header\nfloat32 front_left\nfloat32 front_right\nfloat32 rear_left\n"
        "float32 rear_right\n"
    ),
    **dict.fromkeys(
        ("pacmod_msgs/msg/WheelSpeedRpt", "pacmod3_msgs/msg/WheelSpeedRpt"),
        "std_msgs/Header header\nfloat64 front_left_wheel_speed\nfloat64 front_right_wheel_speed\n"
        "float64 rear_left_wheel_speed\nfloat64 rear_right_wheel_speed\n",
    ),
}
