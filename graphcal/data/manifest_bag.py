"""A streams manifest that names a ROS bag (``bag = "drive.bag"``): its sections' topics,
joints and clock offsets, read with :func:`graphcal.data.bags.read_bag`."""

from __future__ import annotations

import dataclasses

from graphcal.data.bags import read_bag
from graphcal.data.manifest import Manifest
from graphcal.data.streams import Recording

#: Keys a section may hold when the manifest reads a bag (the wheels' also name the joints).
BAG_KEYS = {"topic", "time_offset"}
BAG_WHEEL_KEYS = BAG_KEYS | {"rear_left", "rear_right", "kind"}


def read_bag_manifest(manifest: Manifest) -> Recording:
    """The :class:`Recording` of the manifest's bag: the topics its sections name (else
    detected), the wheels' joints and kind, each stream shifted by its ``time_offset``."""
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
