"""Write a :class:`~graphcal.recording.streams.Recording` as a ROS 1 bag or a ROS 2 bag, with
rosbags.

For tests and demos (``graphcal simulate``): the inverse of
:func:`graphcal.recording.bag.read.read_bag`.
The pose becomes ``sensor_msgs/NavSatFix`` (the heading in the Imu orientation, as from an
INS) or ``nav_msgs/Odometry`` (the heading as orientation, the sideslip as the direction of
the body-frame twist); the wheels a ``sensor_msgs/JointState``
of two joints (position [rad] when cumulative, else velocity [rad/s]); the IMU
``sensor_msgs/Imu``. Each message's header stamp and record time is its sample time.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from graphcal.recording.geodesy import local_to_geodetic
from graphcal.recording.streams import Recording, StreamError

Storage = Literal["ros1", "ros2", "mcap"]
#: A topic's message type, record times [ns] and its k-th message.
_Topic = tuple[str, np.ndarray, Callable[[int], Any]]
_MISSING_ROSBAGS = 'writing ROS bags needs the rosbags package: pip install -e ".[ros]"'


@dataclass(frozen=True)
class BagTopics:
    """The topics a written bag holds its streams in, and the rear wheels' joint names in its
    JointState messages."""

    pose: str = "/gnss/fix"
    wheels: str = "/joint_states"
    imu: str = "/imu/data"
    rear_left: str = "rear_left_wheel_joint"
    rear_right: str = "rear_right_wheel_joint"


def write_bag(
    recording: Recording,
    path: str | Path,
    storage: Storage,
    *,
    topics: BagTopics = BagTopics(),
    pose_message: Literal["navsatfix", "odometry", "posestamped"] | None = None,
) -> Path:
    """Write ``recording`` as a bag at ``path``, atomically (temporary path, then rename).

    Args:
        recording: the streams; times [s] must be >= 0 (ROS 1 time is unsigned).
        path: a ``.bag`` file for ``"ros1"``; a directory for ``"ros2"`` (sqlite3 storage)
            and ``"mcap"`` (ROS 2 bag with mcap storage; its ``<name>.mcap`` file is also
            readable on its own). An existing bag at ``path`` is replaced.
        storage: ``"ros1"``, ``"ros2"`` or ``"mcap"``.
        topics: the topic names and the rear wheels' joint names (:class:`BagTopics`).
        pose_message: ``"navsatfix"`` (latitude/longitude; needs the pose's ``origin``; the
            heading goes into the Imu orientation, as an INS publishes it) or ``"odometry"``
            (local x, y, the heading as orientation and the sideslip as the direction of the
            body-frame twist) or ``"posestamped"`` (local x, y and the heading, as a
            motion-capture system publishes them); default NavSatFix when the pose has an
            origin.

    Returns:
        ``path``.

    Raises:
        StreamError: unknown storage, a ``"ros1"`` path not ending in ``.bag``, negative
            times, or a path that exists and is not a bag.
    """
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise StreamError(_MISSING_ROSBAGS) from None

    path = Path(path)
    _check_request(recording, path, storage, pose_message)
    as_fix = _pose_as_fix(recording, pose_message)
    _check_replaceable(path)
    ros1 = storage == "ros1"
    typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    messages = _Messages(typestore, ros1)
    written = [
        (topics.pose, *messages.pose(recording, as_fix, pose_message == "posestamped")),
        (topics.wheels, *messages.wheels(recording, topics.rear_left, topics.rear_right)),
    ]
    if recording.imu is not None:
        written.append((topics.imu, *messages.imu(recording, as_fix)))

    path.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        target = staging / path.name
        _write(target, storage, typestore, written)
        _replace(target, path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return path


def _check_request(
    recording: Recording, path: Path, storage: str, pose_message: str | None
) -> None:
    """Refuse an unknown storage or pose message, a ROS 1 path not ending in ``.bag`` and
    negative times."""
    if storage not in ("ros1", "ros2", "mcap"):
        raise StreamError(f"{path}: bag storage {storage!r} is unknown; use ros1, ros2 or mcap")
    if storage == "ros1" and path.suffix != ".bag":
        raise StreamError(f"{path}: a ROS 1 bag is a file ending in .bag; name it so")
    for role, stream in recording.streams().items():
        if len(stream.t) and float(np.min(stream.t)) < 0:
            raise StreamError(
                f"{recording.source}: {role} times start at {float(np.min(stream.t)):.3f} s; "
                "bags need times >= 0 s, shift the recording's clock"
            )
    if pose_message not in (None, "navsatfix", "odometry", "posestamped"):
        raise StreamError(
            f"pose_message {pose_message!r} is unknown; use navsatfix, odometry or posestamped"
        )


def _pose_as_fix(recording: Recording, pose_message: str | None) -> bool:
    """Whether the pose is written as NavSatFix (the default when it has a geodetic origin);
    refused without that origin."""
    as_fix = (
        recording.pose.origin is not None if pose_message is None else pose_message == "navsatfix"
    )
    if as_fix and recording.pose.origin is None:
        raise StreamError(f"{recording.source}: a NavSatFix needs the pose's geodetic origin")
    return as_fix


def _check_replaceable(path: Path) -> None:
    """Refuse to replace anything at ``path`` that is not a bag."""
    from graphcal.recording.bag.reader import is_bag

    if path.exists() and not is_bag(path):
        raise StreamError(
            f"{path}: exists and is not a bag; remove it or write the bag to another path"
        )


def _replace(written: Path, path: Path) -> None:
    """Move ``written`` to ``path``, replacing a bag there (a directory is moved aside first)."""
    if path.is_dir():
        old = written.parent / f"{path.name}.old"
        os.replace(path, old)
        os.replace(written, path)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(written, path)


def _stamps(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(nanoseconds, sec, nanosec)`` of times [s]."""
    ns = np.round(np.asarray(t, dtype=float) * 1e9).astype(np.int64)
    return ns, ns // 1_000_000_000, ns % 1_000_000_000


class _Messages:
    """Builds the message objects of one typestore (ROS 1 headers carry a ``seq``)."""

    def __init__(self, typestore: Any, ros1: bool):
        self.types = typestore.types
        self.ros1 = ros1

    def _header(self, sec: int, nanosec: int, frame: str, seq: int) -> Any:
        stamp = self.types["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int(nanosec))
        extra = {"seq": seq} if self.ros1 else {}
        return self.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame, **extra)

    def _vector(self, x: float, y: float, z: float) -> Any:
        return self.types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))

    def _quaternion(self, yaw: float) -> Any:
        return self.types["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=float(np.sin(0.5 * yaw)), w=float(np.cos(0.5 * yaw))
        )

    def pose(self, recording: Recording, as_fix: bool, stamped: bool = False) -> _Topic:
        """NavSatFix (geodetic origin), PoseStamped (``stamped``) or Odometry messages of the
        pose stream."""
        pose = recording.pose
        ns, sec, nanosec = _stamps(pose.t)
        t = self.types
        if as_fix:
            latitude, longitude = local_to_geodetic(pose.x, pose.y, pose.origin)
            status = t["sensor_msgs/msg/NavSatStatus"](status=0, service=1)

            def navsatfix(k: int) -> Any:
                return t["sensor_msgs/msg/NavSatFix"](
                    header=self._header(sec[k], nanosec[k], "gnss", k),
                    status=status,
                    latitude=float(latitude[k]),
                    longitude=float(longitude[k]),
                    altitude=0.0,
                    position_covariance=np.zeros(9),
                    position_covariance_type=0,
                )

            return "sensor_msgs/msg/NavSatFix", ns, navsatfix
        heading = pose.heading if pose.heading is not None else np.zeros(len(ns))
        if stamped:

            def pose_stamped(k: int) -> Any:
                position = t["geometry_msgs/msg/Point"](
                    x=float(pose.x[k]), y=float(pose.y[k]), z=0.0
                )
                return t["geometry_msgs/msg/PoseStamped"](
                    header=self._header(sec[k], nanosec[k], "mocap", k),
                    pose=t["geometry_msgs/msg/Pose"](
                        position=position, orientation=self._quaternion(heading[k])
                    ),
                )

            return "geometry_msgs/msg/PoseStamped", ns, pose_stamped
        zero = self._vector(0.0, 0.0, 0.0)
        # Body-frame velocity: speed from the positions over about 1 s, direction the sideslip.
        half = max(1, round(0.5 / float(np.median(np.diff(pose.t)))))
        ahead = np.minimum(np.arange(len(ns)) + half, len(ns) - 1)
        behind = np.maximum(np.arange(len(ns)) - half, 0)
        speed = np.hypot(pose.x[ahead] - pose.x[behind], pose.y[ahead] - pose.y[behind]) / (
            pose.t[ahead] - pose.t[behind]
        )
        sideslip = pose.sideslip if pose.sideslip is not None else np.zeros(len(ns))

        def twist(k: int) -> Any:
            linear = self._vector(
                float(speed[k] * np.cos(sideslip[k])), float(speed[k] * np.sin(sideslip[k])), 0.0
            )
            return t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=linear, angular=zero),
                covariance=np.zeros(36),
            )

        def odometry(k: int) -> Any:
            position = t["geometry_msgs/msg/Point"](x=float(pose.x[k]), y=float(pose.y[k]), z=0.0)
            return t["nav_msgs/msg/Odometry"](
                header=self._header(sec[k], nanosec[k], "odom", k),
                child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](
                    pose=t["geometry_msgs/msg/Pose"](
                        position=position, orientation=self._quaternion(heading[k])
                    ),
                    covariance=np.zeros(36),
                ),
                twist=twist(k),
            )

        return "nav_msgs/msg/Odometry", ns, odometry

    def wheels(self, recording: Recording, rear_left: str, rear_right: str) -> _Topic:
        """JointState messages: position [rad] when cumulative, else velocity [rad/s]."""
        wheels = recording.wheels
        ns, sec, nanosec = _stamps(wheels.t)
        values = 2.0 * np.pi * np.column_stack([wheels.left, wheels.right])
        empty = np.zeros(0)

        def joint_state(k: int) -> Any:
            return self.types["sensor_msgs/msg/JointState"](
                header=self._header(sec[k], nanosec[k], "base_link", k),
                name=[rear_left, rear_right],
                position=values[k] if wheels.cumulative else empty,
                velocity=empty if wheels.cumulative else values[k],
                effort=empty,
            )

        return "sensor_msgs/msg/JointState", ns, joint_state

    def imu(self, recording: Recording, as_fix: bool) -> _Topic:
        """Imu messages; a missing signal has covariance -1 (REP 145). With a NavSatFix pose
        that has a heading, the orientation carries it, as an INS publishes it."""
        imu = recording.imu
        assert imu is not None
        ns, sec, nanosec = _stamps(imu.t)
        n = len(ns)
        ay = imu.lateral_acceleration if imu.lateral_acceleration is not None else np.zeros(n)
        wz = imu.yaw_rate if imu.yaw_rate is not None else np.zeros(n)
        not_provided = np.zeros(9)
        not_provided[0] = -1.0
        pose = recording.pose
        with_heading = as_fix and pose.heading is not None
        yaw = np.interp(imu.t, pose.t, np.unwrap(pose.heading)) if with_heading else None
        orientation_covariance = np.zeros(9) if with_heading else not_provided
        no_orientation = self.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
        acceleration_covariance = (
            np.zeros(9) if imu.lateral_acceleration is not None else not_provided
        )
        rate_covariance = np.zeros(9) if imu.yaw_rate is not None else not_provided

        def message(k: int) -> Any:
            return self.types["sensor_msgs/msg/Imu"](
                header=self._header(sec[k], nanosec[k], "imu", k),
                orientation=no_orientation if yaw is None else self._quaternion(yaw[k]),
                orientation_covariance=orientation_covariance,
                angular_velocity=self._vector(0.0, 0.0, wz[k]),
                angular_velocity_covariance=rate_covariance,
                linear_acceleration=self._vector(0.0, ay[k], 9.81),
                linear_acceleration_covariance=acceleration_covariance,
            )

        return "sensor_msgs/msg/Imu", ns, message


def _write(
    path: Path,
    storage: Storage,
    typestore: Any,
    topics: list[tuple[str, str, np.ndarray, Callable[[int], Any]]],
) -> None:
    """Write the messages of every topic, merged in time order."""
    if storage == "ros1":
        from rosbags.rosbag1 import Writer as Writer1

        writer: Any = Writer1(path)
        serialize = typestore.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
        serialize = typestore.serialize_cdr
    ns = np.concatenate([stamps for _, _, stamps, _ in topics])
    which = np.concatenate([np.full(len(s), i) for i, (_, _, s, _) in enumerate(topics)])
    index = np.concatenate([np.arange(len(s)) for _, _, s, _ in topics])
    order = np.lexsort((index, which, ns))
    with writer:
        connections = [
            writer.add_connection(topic, msgtype, typestore=typestore)
            for topic, msgtype, _, _ in topics
        ]
        for i, k in zip(which[order].tolist(), index[order].tolist(), strict=True):
            _, msgtype, stamps, messages = topics[i]
            writer.write(connections[i], int(stamps[k]), serialize(messages(k), msgtype))
