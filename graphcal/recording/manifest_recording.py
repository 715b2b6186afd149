"""Which source reads each section of a streams manifest, and the :class:`Recording` they make.

The manifest (:mod:`graphcal.recording.manifest`) checks the TOML and hands out its sections
(:class:`~graphcal.recording.section.Section`); here each is given to the one source that
reads it: a bag's topics (:mod:`graphcal.recording.bag`, by a plain
:class:`~graphcal.recording.bag.request.BagRequest`), a CSV file's columns
(:mod:`graphcal.recording.manifest.csv_streams`), a receiver's NMEA log
(:mod:`graphcal.recording.nmea`), a raw CAN log (:mod:`graphcal.recording.can`, each log read
once for all its sections) or a 3-axis IMU's columns rotated by its mounting
(:mod:`graphcal.recording.imu`). The sources never import each other; this module is the only
one that knows them all.
"""

from __future__ import annotations

import dataclasses
import os

from graphcal.recording.bag.read import read_bag
from graphcal.recording.bag.request import BagRequest
from graphcal.recording.can.log import read_can_sections, reads_can
from graphcal.recording.imu.mounting import mounted_columns, mounted_imu
from graphcal.recording.manifest.columns import read_columns
from graphcal.recording.manifest.csv_streams import read_imu, read_pose, read_wheels
from graphcal.recording.manifest.manifest import Manifest, load_manifest
from graphcal.recording.manifest.time_spans import check_time_spans
from graphcal.recording.nmea.read import read_nmea_pose
from graphcal.recording.streams import ImuStream, PoseStream, Recording, WheelStream

#: Keys a section may hold when the manifest reads a bag (the wheels' also name the joints).
BAG_KEYS = {"topic", "time_offset"}
BAG_WHEEL_KEYS = BAG_KEYS | {"rear_left", "rear_right", "kind"}
#: ``[imu]`` keys that make it a 3-axis IMU in its own frame.
MOUNTED_IMU_KEYS = ("acceleration", "angular_velocity", "mounting")


def read_manifest(path: str | os.PathLike[str] | Manifest) -> Recording:
    """The :class:`Recording` a manifest (path, or loaded) describes: its CSV files, NMEA and
    CAN logs, or its bag's topics."""
    manifest = path if isinstance(path, Manifest) else load_manifest(path)
    if manifest.bag is not None:
        return read_bag_manifest(manifest)
    notes: list[str] = []
    pose = _pose(manifest, notes)
    can = read_can_sections(manifest.wheels, manifest.imu, notes) if _can(manifest) else {}
    wheels = can["wheels"] if "wheels" in can else read_wheels(manifest.wheels, notes)
    imu = None if manifest.imu is None else _imu(manifest, can, notes, (pose, wheels))
    sections = (manifest.pose, manifest.wheels, manifest.imu)
    streams = (pose, wheels, imu)
    check_time_spans(
        [
            (section, stream.source, stream.t)
            for section, stream in zip(sections, streams, strict=True)
            if stream is not None and _csv_times(section, can)
        ]
    )
    return Recording(pose=pose, wheels=wheels, imu=imu, source=manifest.source, notes=tuple(notes))


def _csv_times(section, can: dict) -> bool:
    """Whether ``section``'s times came from a CSV column in a declared ``time_unit``."""
    return section.get("time") is not None and "nmea" not in section and section.name not in can


def _can(manifest: Manifest) -> bool:
    return reads_can(manifest.wheels, manifest.wheels)


def _pose(manifest: Manifest, notes: list[str]) -> PoseStream:
    if "nmea" in manifest.pose:
        return read_nmea_pose(manifest.pose, notes)
    return read_pose(manifest.pose, notes)


def _imu(
    manifest: Manifest, can: dict, notes: list[str], drive: tuple[PoseStream, WheelStream]
) -> ImuStream:
    """The ``[imu]`` stream from its source: a CAN log (read with the wheels' if they share
    one), a 3-axis IMU's columns, or the vehicle frame's columns."""
    table = manifest.imu
    if reads_can(table, manifest.wheels):
        if "imu" not in can:
            can = read_can_sections(manifest.wheels, table, notes)
        return can["imu"]
    if table.has_any(MOUNTED_IMU_KEYS):
        asked = mounted_columns(table)
        read = read_columns(table, asked.columns, notes, asked.units)
        return mounted_imu(table, asked, read, drive, notes)
    return read_imu(table, notes)


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
    request = BagRequest(
        pose_topic=manifest.pose.get("topic"),
        wheel_topic=wheels.get("topic"),
        imu_topic=None if manifest.imu is None else manifest.imu.get("topic"),
        rear_left=wheels.get("rear_left"),
        rear_right=wheels.get("rear_right"),
        wheel_kind=kind,
    )
    recording = read_bag(manifest.bag, request, source=manifest.source)
    shifted = {}
    for role, table in (("pose", manifest.pose), ("wheels", wheels), ("imu", manifest.imu)):
        offset = 0.0 if table is None else table.number("time_offset", 0.0)
        stream = getattr(recording, role)
        if offset and stream is not None:
            shifted[role] = dataclasses.replace(stream, t=stream.t + offset)
    return dataclasses.replace(recording, **shifted) if shifted else recording
