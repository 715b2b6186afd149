"""What a bag holds, and which of its topics and joints to read (pure Python, no rosbags).

:class:`BagContents` is a bag's table of contents: its topics and their message types,
their message counts and the message definitions it carries. :func:`pick_topic` chooses the
topic of a stream by its message type (the one named, else the only one of that type), and
:func:`resolve_joints` the rear-left and rear-right joints of a ``sensor_msgs/JointState``
(the ones named, else the two joint names saying ``left`` and ``right``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from graphcal.recording.streams import StreamError

NAVSATFIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_COVARIANCE = "geometry_msgs/msg/PoseWithCovarianceStamped"
IMU = "sensor_msgs/msg/Imu"
JOINT_STATE = "sensor_msgs/msg/JointState"
HEADER = "std_msgs/msg/Header"
#: Message types usable as the pose stream.
POSE_TYPES = (NAVSATFIX, ODOMETRY, POSE_STAMPED, POSE_COVARIANCE)


@dataclass(frozen=True)
class BagContents:
    """A bag's table of contents.

    Attributes:
        source: the bag's name in messages.
        topics: each topic's message type (``{"/fix": "sensor_msgs/msg/NavSatFix"}``).
        counts: each topic's number of messages (all zero when the bag does not say).
        fielddefs: the message definitions, as rosbags' typestore holds them
            (``{type: (constants, [(field, (node type, description)), ...])}``).
    """

    source: str
    topics: dict[str, str]
    counts: dict[str, int] = field(default_factory=dict)
    fielddefs: dict = field(default_factory=dict)

    def topic_list(self) -> str:
        """``/a (type), /b (type)`` of every topic in the bag."""
        if not self.topics:
            return "the bag has no topics"
        return "topics: " + ", ".join(f"{t} ({self.topics[t]})" for t in sorted(self.topics))


def short(msgtype: str) -> str:
    """``NavSatFix`` of ``sensor_msgs/msg/NavSatFix``."""
    return msgtype.rsplit("/", 1)[-1]


def pick_topic(
    bag: BagContents,
    topic: str | None,
    types: tuple[str, ...],
    role: str,
    flag: str,
    required: bool,
) -> tuple[str | None, str | None]:
    """The topic of ``role`` and a note if it was picked automatically.

    ``topic`` if given (checked to be in the bag and of one of ``types``), else the only
    topic of one of ``types``; ``None`` when there is none and the stream is optional.

    Raises:
        StreamError: the named topic is absent or of another type; several topics of the
            types and none named; none at all of a ``required`` stream.
    """
    wanted = " or ".join(short(t) for t in types)
    if topic is not None:
        if topic not in bag.topics:
            raise StreamError(
                f"{bag.source}: {role} topic {topic} is not in the bag; pass {flag} with one of "
                f"the {bag.topic_list()}"
            )
        if bag.topics[topic] not in types:
            raise StreamError(
                f"{bag.source}: {role} topic {topic} is {bag.topics[topic]}, not {wanted}; pass "
                f"{flag} with a topic of that type ({bag.topic_list()})"
            )
        return topic, None
    candidates = sorted(t for t, msgtype in bag.topics.items() if msgtype in types)
    if len(candidates) == 1:
        picked = candidates[0]
        return picked, f"{role} topic {picked} ({short(bag.topics[picked])}) picked automatically"
    if not candidates:
        if not required:
            return None, None
        raise StreamError(
            f"{bag.source}: no {role} topic ({wanted}) in the bag; {bag.topic_list()}; record "
            f"one, or pass {flag} if it has another type"
        )
    listed = ", ".join(f"{t} ({short(bag.topics[t])})" for t in candidates)
    raise StreamError(
        f"{bag.source}: {len(candidates)} {role} topics ({listed}); pass {flag} with the one to use"
    )


def no_messages(bag: BagContents, topic: str, role: str, flag: str) -> StreamError:
    """The error of a chosen topic without messages."""
    return StreamError(
        f"{bag.source}: {role} topic {topic} has no messages; pass {flag} with a recorded "
        f"topic ({bag.topic_list()})"
    )


def pick_joints(names: Iterable[str]) -> tuple[str, str] | None:
    """The rear-left and rear-right joint among ``names``, or ``None`` if ambiguous.

    The names containing ``left`` / ``right`` (case-insensitive); when there are several, only
    those also containing ``rear``. Exactly one of each must remain.
    """
    names = sorted(set(names))

    def side(word: str) -> list[str]:
        found = [n for n in names if word in n.lower()]
        if len(found) > 1:
            found = [n for n in found if "rear" in n.lower()]
        return found

    left, right = side("left"), side("right")
    if len(left) == 1 and len(right) == 1 and left[0] != right[0]:
        return left[0], right[0]
    return None


def resolve_joints(
    source: str,
    rear_left: str | None,
    rear_right: str | None,
    joint_names: Callable[[], list[str]],
    notes: list[str],
) -> tuple[str, str]:
    """The rear-left and rear-right joint names: given, or picked (:func:`pick_joints`) from
    ``joint_names()``, the sorted joint names of the topic's first messages (asked for only
    when a joint is not given).

    Raises:
        StreamError: both given as one joint; only one given; none given and the names do
            not tell them.
    """
    if rear_left is not None and rear_right is not None:
        if rear_left == rear_right:
            raise StreamError(
                f"{source}: rear-left and rear-right joint are both {rear_left!r}; pass "
                "--rear-left/--rear-right with two different joints"
            )
        return rear_left, rear_right
    names = joint_names()
    listed = ", ".join(names) or "none"
    if rear_left is None and rear_right is None:
        picked = pick_joints(names)
        if picked is None:
            raise StreamError(
                f"{source}: cannot tell the rear wheel joints from the joint names ({listed}); "
                "pass --rear-left/--rear-right"
            )
        notes.append(f"{source}: rear wheel joints {picked[0]}, {picked[1]} picked automatically")
        return picked
    given, flag = (rear_left, "--rear-right") if rear_right is None else (rear_right, "--rear-left")
    raise StreamError(
        f"{source}: only one rear wheel joint given ({given}); pass {flag} too (joint names: "
        f"{listed})"
    )
