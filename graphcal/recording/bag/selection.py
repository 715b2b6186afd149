"""Which topics and fields of a bag :func:`~graphcal.recording.bag.read.read_bag` reads (pure
Python).

:func:`select_streams` chooses, from a bag's :class:`~graphcal.recording.bag.topics.BagContents`
and the :class:`~graphcal.recording.bag.request.BagRequest`, the pose topic, the wheels (the
joints of a JointState topic, two fields named ``TOPIC:FIELD``, or a vendor wheel-speed
message picked by its type), the IMU (an Imu topic or fields) and a heading field; every
mistake is one line naming the option, topic, type and field and listing what exists.
"""

from __future__ import annotations

from dataclasses import dataclass

from graphcal.recording.bag.fields import FieldRef, field_ref, is_field_ref, listing, resolve_field
from graphcal.recording.bag.request import BagRequest, WheelFields, wheel_conversion
from graphcal.recording.bag.topics import (
    IMU,
    JOINT_STATE,
    POSE_TYPES,
    BagContents,
    no_messages,
    pick_topic,
    short,
)
from graphcal.recording.bag.vendors import SPEED_ONLY, VENDOR_WHEELS
from graphcal.recording.streams import StreamError

#: Kinds of a wheel field and what each needs, for messages.
WHEEL_FIELD_KINDS = (
    "speed [with --speed-unit and --circumference], angular_speed [rad/s], rpm, "
    "ticks [cumulative, with --ticks-per-revolution], angle [rad, cumulative]"
)


@dataclass(frozen=True)
class BagSelection:
    """The topics and fields to read.

    Attributes:
        pose: the pose topic.
        wheels: the wheels as two fields of a topic, or ``None``: the joints of
            ``joint_topic``.
        joint_topic: the JointState topic of the wheels (when ``wheels`` is ``None``).
        imu: the Imu topic, or ``None`` (no IMU, or IMU fields).
        imu_fields: ``--lateral-acceleration`` / ``--yaw-rate`` fields (of one topic).
        heading: the ``--heading`` field, or ``None``.
    """

    pose: str
    wheels: WheelFields | None
    joint_topic: str | None
    imu: str | None
    imu_fields: list[FieldRef]
    heading: FieldRef | None

    @property
    def streams(self) -> list[tuple[str, str, str]]:
        """``(topic, role, flag)`` of each stream read: pose, wheels, IMU, heading."""
        streams = [(self.pose, "pose", "--pose-topic")]
        if self.wheels is not None:
            streams.append((self.wheels.topic, "wheel", self.wheels.left.flag or "--wheel-topic"))
        else:
            assert self.joint_topic is not None
            streams.append((self.joint_topic, "wheel", "--wheel-topic"))
        if self.imu is not None:
            streams.append((self.imu, "IMU", "--imu-topic"))
        if self.imu_fields:
            first = self.imu_fields[0]
            streams.append((first.topic, "IMU", first.flag or "--imu-topic"))
        if self.heading is not None:
            streams.append((self.heading.topic, "heading", "--heading"))
        return streams


def select_streams(bag: BagContents, r: BagRequest, notes: list[str]) -> BagSelection:
    """The topics and fields of ``bag`` to read for the request ``r``; the notes of what was
    picked automatically go first in ``notes``.

    Raises:
        StreamError: a topic, joint option or field that is absent, of the wrong type, not a
            number, ambiguous or without messages; options that do not go together.
    """
    pose, pose_note = pick_topic(bag, r.pose_topic, POSE_TYPES, "pose", "--pose-topic", True)
    fields = wheel_fields(bag, r, notes)
    wheel = wheel_note = None
    if fields is None:
        if r.wheel_kind not in (None, "angle", "angular_speed"):
            raise StreamError(
                f"{bag.source}: --wheel-kind {r.wheel_kind}: a JointState gives angle (position) "
                "or angular_speed (velocity); the other kinds apply to fields (--rear-left "
                "TOPIC:FIELD)"
            )
        wheel, wheel_note = pick_topic(
            bag, r.wheel_topic, (JOINT_STATE,), "wheel", "--wheel-topic", True
        )
    wheel_conversion(f"{bag.source}:{fields.topic if fields else wheel}", fields, r)
    imu_refs = imu_fields(bag, r)
    imu = imu_note = None
    if not imu_refs:
        imu, imu_note = pick_topic(bag, r.imu_topic, (IMU,), "IMU", "--imu-topic", False)
    heading_ref = heading_field(bag, r)
    notes[:0] = [note for note in (pose_note, wheel_note, imu_note) if note]
    assert pose is not None
    selection = BagSelection(pose, fields, wheel, imu, imu_refs, heading_ref)
    for topic, role, flag in selection.streams:
        if any(bag.counts.values()) and bag.counts.get(topic, 0) == 0:  # counts are known
            raise no_messages(bag, topic, role, flag)
    return selection


def wheel_fields(bag: BagContents, r: BagRequest, notes: list[str]) -> WheelFields | None:
    """The wheels as fields of a topic — named (``--rear-left TOPIC:FIELD``, or fields of a
    ``--wheel-topic`` that is no JointState) or a vendor wheel-speed message picked by its
    type — or ``None`` to read the joints of a JointState."""
    left_ref, right_ref = (
        is_field_ref(r.rear_left, bag.topics),
        is_field_ref(r.rear_right, bag.topics),
    )
    topic_type = bag.topics.get(r.wheel_topic or "")
    on_topic = topic_type is not None and topic_type != JOINT_STATE
    if left_ref or right_ref or (on_topic and (r.rear_left or r.rear_right)):
        return _named_wheel_fields(bag, r, left_ref, right_ref)
    _refuse_speed_only(bag, r, topic_type)
    if on_topic:
        assert r.wheel_topic is not None and topic_type is not None
        if topic_type not in VENDOR_WHEELS:
            raise StreamError(
                f"{bag.source}: wheel topic {r.wheel_topic} is {topic_type}, neither JointState "
                "nor a known wheel-speed message; name its fields with --rear-left FIELD "
                f"--rear-right FIELD and --wheel-kind (its fields: "
                f"{listing(bag.fielddefs, topic_type)})"
                if topic_type in bag.fielddefs
                else f"{bag.source}: wheel topic {r.wheel_topic} is {topic_type}, of which the "
                "bag carries no definition; pass --wheel-topic with a JointState topic"
            )
        return vendor_fields(bag, r.wheel_topic, r.wheel_kind)
    if r.rear_left is not None or r.rear_right is not None or r.wheel_topic is not None:
        return None  # joints of a JointState
    return _picked_vendor(bag, r, notes)


def _named_wheel_fields(
    bag: BagContents, r: BagRequest, left_ref: bool, right_ref: bool
) -> WheelFields:
    """The wheels of ``--rear-left`` and ``--rear-right`` naming fields (``TOPIC:FIELD``, or a
    bare field of the other's topic or of ``--wheel-topic``)."""
    if r.rear_left is None or r.rear_right is None:
        given, other = (
            ("--rear-left", "--rear-right")
            if r.rear_right is None
            else ("--rear-right", "--rear-left")
        )
        raise StreamError(
            f"{bag.source}: {given} {r.rear_left or r.rear_right} names a field; pass {other} "
            "too (TOPIC:FIELD, or a field of the same topic)"
        )
    # A bare field is on the other option's topic, else on --wheel-topic.
    written = r.rear_left if left_ref else r.rear_right if right_ref else None
    anchor = written.split(":", 1)[0] if written is not None else r.wheel_topic
    refs = {}
    for flag, text, is_ref in sorted(
        (("--rear-left", r.rear_left, left_ref), ("--rear-right", r.rear_right, right_ref)),
        key=lambda option: not option[2],  # the TOPIC:FIELD ones first
    ):
        refs[flag] = field_ref(bag, flag, text, None if is_ref else anchor)
    left, right = refs["--rear-left"], refs["--rear-right"]
    if left.topic != right.topic:
        raise StreamError(
            f"{bag.source}: --rear-left {left.written} and --rear-right {right.written} are "
            "on different topics; name two fields of one topic"
        )
    if r.wheel_topic is not None and r.wheel_topic != left.topic:
        raise StreamError(
            f"{bag.source}: --wheel-topic {r.wheel_topic} but --rear-left {left.written}; "
            "leave --wheel-topic out or name fields of it"
        )
    if left.steps == right.steps:
        raise StreamError(
            f"{bag.source}: --rear-left and --rear-right are both {left.written}; name the "
            "two wheels' fields"
        )
    vendor = VENDOR_WHEELS.get(bag.topics[left.topic])
    kind = r.wheel_kind or ("angular_speed" if vendor else None)
    if kind is None:
        raise StreamError(
            f"{bag.source}: --rear-left {left.written}: pass --wheel-kind, what the fields "
            f"hold: {WHEEL_FIELD_KINDS}"
        )
    label = vendor[0] if vendor and r.wheel_kind is None else None
    return WheelFields(left.topic, left, right, kind, label)


def _refuse_speed_only(bag: BagContents, r: BagRequest, topic_type: str | None) -> None:
    """One line when the wheels would be a message with the vehicle's speed only: the
    ``--wheel-topic``, or the only candidate of a bag without wheel speeds."""
    speed_only = [t for t, msgtype in sorted(bag.topics.items()) if msgtype in SPEED_ONLY]
    nothing_else = (r.wheel_topic, r.rear_left, r.rear_right) == (None, None, None) and not any(
        msgtype == JOINT_STATE or msgtype in VENDOR_WHEELS for msgtype in bag.topics.values()
    )
    if speed_only and (topic_type in SPEED_ONLY or nothing_else):
        topic = r.wheel_topic if topic_type in SPEED_ONLY else speed_only[0]
        raise StreamError(
            f"{bag.source}: {topic} ({short(bag.topics[topic])}) has the vehicle's "
            "longitudinal speed only, not each rear wheel's that the calibration needs; record "
            "the wheel speeds (a JointState, the vehicle's wheel-speed report) and name them"
        )


def _picked_vendor(bag: BagContents, r: BagRequest, notes: list[str]) -> WheelFields | None:
    """The only vendor wheel-speed topic of the bag (preferred to a JointState), or ``None``."""
    vendors = sorted(t for t, msgtype in bag.topics.items() if msgtype in VENDOR_WHEELS)
    if len(vendors) > 1:
        listed = ", ".join(f"{t} ({short(bag.topics[t])})" for t in vendors)
        raise StreamError(
            f"{bag.source}: {len(vendors)} wheel-speed topics ({listed}); pass --wheel-topic "
            "with the one to use"
        )
    if not vendors:
        return None
    picked = vendor_fields(bag, vendors[0], r.wheel_kind)
    joint_states = sorted(t for t, msgtype in bag.topics.items() if msgtype == JOINT_STATE)
    rather = (
        f", rather than the JointState {', '.join(joint_states)} (pass --wheel-topic to use it)"
        if joint_states
        else ""
    )
    vendor = VENDOR_WHEELS[bag.topics[picked.topic]][0]
    notes.append(
        f"wheel topic {picked.topic} ({short(bag.topics[picked.topic])}: {vendor}) "
        f"picked automatically{rather}"
    )
    return picked


def vendor_fields(bag: BagContents, topic: str, wheel_kind: str | None) -> WheelFields:
    """The rear wheels of a vendor wheel-speed message (:data:`VENDOR_WHEELS`)."""
    vendor, left, right = VENDOR_WHEELS[bag.topics[topic]]
    refs = [FieldRef(topic, path, (path,)) for path in (left, right)]
    for ref in refs:
        resolve_field(bag, ref)  # the bag's own definition of the type must have them
    label = vendor if wheel_kind is None else None  # the vendor's unit, unless overridden
    return WheelFields(topic, refs[0], refs[1], wheel_kind or "angular_speed", label)


def imu_fields(bag: BagContents, r: BagRequest) -> list[FieldRef]:
    """``--lateral-acceleration`` / ``--yaw-rate`` as fields of one topic (or none given)."""
    refs = []
    for text, flag in (
        (r.lateral_acceleration, "--lateral-acceleration"),
        (r.yaw_rate, "--yaw-rate"),
    ):
        if text is None:
            continue
        if is_field_ref(text, bag.topics):
            refs.append(field_ref(bag, flag, text))
        elif r.imu_topic is not None:
            refs.append(field_ref(bag, flag, text, r.imu_topic))
        else:
            raise StreamError(
                f"{bag.source}: {flag} {text}: name its topic too ({flag} TOPIC:{text}) or pass "
                "--imu-topic"
            )
    topics = sorted({ref.topic for ref in refs})
    if len(topics) > 1:
        raise StreamError(
            f"{bag.source}: --lateral-acceleration and --yaw-rate are on different topics "
            f"({', '.join(topics)}); name two fields of one topic"
        )
    if refs and r.imu_topic is not None and r.imu_topic != topics[0]:
        raise StreamError(
            f"{bag.source}: --imu-topic {r.imu_topic} but {refs[0].flag} {refs[0].written}; "
            "leave --imu-topic out or name fields of it"
        )
    if r.yaw_rate_unit is not None and r.yaw_rate is None:
        raise StreamError(f"{bag.source}: --yaw-rate-unit applies to --yaw-rate TOPIC:FIELD")
    return refs


def heading_field(bag: BagContents, r: BagRequest) -> FieldRef | None:
    """``--heading TOPIC:FIELD``, checked (or ``None``)."""
    if r.heading is None:
        for flag, value in (
            ("--heading-unit", r.heading_unit),
            ("--heading-convention", r.heading_convention),
        ):
            if value is not None:
                raise StreamError(f"{bag.source}: {flag} applies to --heading TOPIC:FIELD")
        return None
    if not is_field_ref(r.heading, bag.topics):
        raise StreamError(
            f"{bag.source}: --heading {r.heading}: write TOPIC:FIELD (a topic of the bag, a "
            f"colon, the field); {bag.topic_list()}"
        )
    return field_ref(bag, "--heading", r.heading)
