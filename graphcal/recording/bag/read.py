"""ROS 1 bags, ROS 2 bags (sqlite3 or mcap storage) and bare MCAP files, read with ``rosbags``.

``rosbags`` is pure Python (no ROS installation); it is the optional extra ``graphcal[ros]``,
imported only by :mod:`graphcal.recording.bag.reader`. :func:`read_bag` turns the bag's topics
into the streams of :mod:`graphcal.recording.streams`:

* pose: ``sensor_msgs/NavSatFix`` (latitude/longitude → east/north [m] from the first fix,
  no heading), ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped`` or
  ``geometry_msgs/PoseWithCovarianceStamped`` (x, y [m]; heading = yaw of the orientation);
* wheels: ``sensor_msgs/JointState`` of the two rear wheel joints, ``position`` [rad,
  cumulative] → revolutions, or ``velocity`` [rad/s] → revolutions per second; or a vendor
  wheel-speed message recognised by its type
  (:data:`~graphcal.recording.bag.vendors.VENDOR_WHEELS`: Dataspeed
  ``dbw_mkz_msgs/WheelSpeedReport``, PACMod ``WheelSpeedRpt``, rad/s);
* IMU (optional): ``sensor_msgs/Imu``, ``linear_acceleration.y`` [m/s²] and
  ``angular_velocity.z`` [rad/s] in the vehicle frame (x forward, y left; REP 103).

Any numeric field of any topic can stand for a wheel, the heading or an IMU signal, named
``TOPIC:FIELD`` (:class:`~graphcal.recording.bag.fields.FieldRef`: ``/car/wheels:wheels[2].speed``),
checked against and read through the message definitions the bag carries (rosbags'
typestore of the bag); a wheel field's kind and unit convert it as ``[wheels] kind`` does a
CSV column.

Time is each message's ``header.stamp``; when every stamp of a topic is zero, or its messages
have no header, the time the bag recorded the message. Every topic is read in one pass over
the bag; each message is deserialized once (or its numbers gathered from the raw bytes of a
topic of one layout, :mod:`graphcal.recording.bag.layout`) and only its few numbers are kept,
converted to arrays at the end.

The steps are modules of their own: which topics, joints and fields to read
(:mod:`~graphcal.recording.bag.topics`, :mod:`~graphcal.recording.bag.fields`,
:mod:`~graphcal.recording.bag.selection`: pure Python, no rosbags), reading the messages
(:mod:`~graphcal.recording.bag.reader`, :mod:`~graphcal.recording.bag.rows`) and making streams of
them (:mod:`~graphcal.recording.bag.streams`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from graphcal.recording.bag.reader import BagReader
from graphcal.recording.bag.request import BagRequest, check_request
from graphcal.recording.bag.rows import EXTRACT, TopicRows, imu_row, joint_extractor
from graphcal.recording.bag.selection import BagSelection, select_streams
from graphcal.recording.bag.streams import (
    field_heading,
    field_imu_stream,
    field_wheel_stream,
    imu_heading,
    imu_stream,
    joint_wheel_stream,
    pose_stream,
)
from graphcal.recording.bag.topics import IMU, JOINT_STATE, BagContents, no_messages, resolve_joints
from graphcal.recording.streams import Recording


def read_bag(
    path: str | Path, request: BagRequest | None = None, *, source: str | None = None
) -> Recording:
    """Read the pose, rear-wheel and (optional) IMU streams of a ROS 1/ROS 2 bag or MCAP file.

    A wheel, the heading or an IMU signal may be any numeric field of any topic, named
    ``TOPIC:FIELD`` (``/vehicle/wheels:wheels[2].speed``: the field dotted into nested fields,
    with array indices) and read through the bag's own message definitions; a vendor
    wheel-speed message (:data:`~graphcal.recording.bag.vendors.VENDOR_WHEELS`) is recognised by
    its type.

    Args:
        path: a ``.bag`` file, a ``.mcap`` file or a ROS 2 bag directory.
        request: what to read (:class:`~graphcal.recording.bag.request.BagRequest`, each
            field documented there; ``None`` or a field left ``None``: detect): the topics,
            the rear wheels' joints or fields and their kind and units, the heading and IMU
            fields and their units.
        source: name of the recording in messages (default: the path).

    Returns:
        The :class:`Recording`: time [s] from the header stamps (the bag's receive times for
        messages without a header), positions [m] (east/north of the first fix for
        NavSatFix), heading [rad, ENU], wheels [rev] or [rev/s], lateral acceleration [m/s²]
        and yaw rate [rad/s]; ``notes`` say what was picked or skipped.

    Raises:
        StreamError: a missing or unreadable bag, a topic, joint or field that is absent, of
            the wrong type, not a number, ambiguous or empty; the message is one line and
            names the option, topic, message type and field path, and lists what exists.
    """
    path = Path(path)
    source = source or str(path)
    request = request if request is not None else BagRequest()
    check_request(source, request)
    bag = BagReader(path, source)
    try:
        return _read(bag, request)
    finally:
        bag.close()


@dataclass
class _Rows:
    """The rows of each stream's topic, filled in one pass over the bag."""

    pose: TopicRows
    wheels: TopicRows
    imu: TopicRows | None = None
    heading: TopicRows | None = None
    #: The rear wheel joints of a JointState, and every joint name its messages had.
    joints: tuple[str, str] | None = None
    seen: set[str] | None = None

    def in_order(self) -> list[TopicRows]:
        """The rows in the order of :attr:`BagSelection.streams`."""
        optional = [rows for rows in (self.imu, self.heading) if rows is not None]
        return [self.pose, self.wheels, *optional]


def _read(bag: BagReader, r: BagRequest) -> Recording:
    notes: list[str] = []
    bag.register_vendor_types(notes)
    contents = bag.contents()
    selection = select_streams(contents, r, notes)
    rows = _topic_rows(bag, contents, selection, r, notes)
    _read_messages(bag, contents, selection, rows)
    return _streams(contents, selection, rows, r, notes)


def _topic_rows(
    bag: BagReader, contents: BagContents, s: BagSelection, r: BagRequest, notes: list[str]
) -> _Rows:
    """Empty rows for each stream's topic (the joints of a JointState resolved first)."""
    topics = contents.topics
    pose = TopicRows(EXTRACT[topics[s.pose]])
    if s.wheels is not None:
        rows = _Rows(pose, bag.field_topic(topics[s.wheels.topic], [s.wheels.left, s.wheels.right]))
    else:
        assert s.joint_topic is not None
        topic = s.joint_topic
        joints = resolve_joints(
            f"{contents.source}:{topic}",
            r.rear_left,
            r.rear_right,
            lambda: bag.joint_names(topic),
            notes,
        )
        joint_extract, seen = joint_extractor(*joints)
        wheels = bag.raw_topic(joint_extract, JOINT_STATE, joints)
        rows = _Rows(pose, wheels, joints=joints, seen=seen)
    if s.imu is not None:
        rows.imu = bag.raw_topic(imu_row, IMU)
    elif s.imu_fields:
        rows.imu = bag.field_topic(topics[s.imu_fields[0].topic], s.imu_fields)
    if s.heading is not None:
        rows.heading = bag.field_topic(topics[s.heading.topic], [s.heading])
    return rows


def _read_messages(bag: BagReader, contents: BagContents, s: BagSelection, rows: _Rows) -> None:
    """Fill the rows in one pass over the bag; one line if a stream's topic had no message."""
    consumers: dict[str, list[TopicRows]] = {}
    for (topic, _, _), topic_rows in zip(s.streams, rows.in_order(), strict=True):
        consumers.setdefault(topic, []).append(topic_rows)
    with bag.guard():
        for topic, timestamp, raw, msgtype in bag.raw_messages(consumers):
            for topic_rows in consumers[topic]:
                if topic_rows.decode is not None:
                    topic_rows.add_raw(timestamp, raw)
                else:
                    topic_rows.add(timestamp, bag.reader.deserialize(raw, msgtype))
        for topic_rows in rows.in_order():
            topic_rows.flush()
    for (topic, role, flag), topic_rows in zip(s.streams, rows.in_order(), strict=True):
        if not len(topic_rows) and not topic_rows.skipped:
            raise no_messages(contents, topic, role, flag)


def _streams(
    bag: BagContents, s: BagSelection, rows: _Rows, r: BagRequest, notes: list[str]
) -> Recording:
    """The recording of the rows: pose, wheels, IMU, and the heading of a field or an INS."""
    pose = pose_stream(f"{bag.source}:{s.pose}", bag.topics[s.pose], rows.pose, notes)
    if s.wheels is not None:
        source = f"{bag.source}:{s.wheels.topic}"
        wheels = field_wheel_stream(source, s.wheels, rows.wheels, r, notes)
    else:
        assert s.joint_topic is not None and rows.joints is not None and rows.seen is not None
        source = f"{bag.source}:{s.joint_topic}"
        wheels = joint_wheel_stream(
            source, rows.wheels, rows.joints, rows.seen, r.wheel_kind, notes
        )
    imu = None
    if s.imu is not None:
        assert rows.imu is not None
        imu = imu_stream(f"{bag.source}:{s.imu}", rows.imu, notes)
    elif s.imu_fields:
        assert rows.imu is not None
        source = f"{bag.source}:{s.imu_fields[0].topic}"
        imu = field_imu_stream(source, s.imu_fields, rows.imu, r, notes)
    if s.heading is not None:
        assert rows.heading is not None
        source = f"{bag.source}:{s.heading.topic}"
        pose = field_heading(source, s.heading, rows.heading, pose, r, notes)
    elif pose.heading is None and s.imu is not None and imu is not None:
        assert rows.imu is not None
        pose = imu_heading(rows.imu, imu, pose, notes)
    return Recording(pose, wheels, imu, bag.source, tuple(notes))
