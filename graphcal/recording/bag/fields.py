"""Field paths: any numeric field of a bag's messages, named ``TOPIC:FIELD`` (pure Python).

A wheel, the heading or an IMU signal may be any numeric field of any topic
(``/car/wheels:wheels[2].speed``: the field dotted into nested fields, with array indices).
:func:`field_ref` parses such a name and :func:`resolve_field` checks it against the message
definition the bag carries (:attr:`graphcal.recording.bag.topics.BagContents.fielddefs`), saying
in one line what exists where the path fails.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from graphcal.recording.bag.layout import ARRAY, BASE, NAME, PRIMITIVES, SEQUENCE, Steps
from graphcal.recording.bag.topics import BagContents
from graphcal.recording.streams import StreamError

_PATH = re.compile(r"[A-Za-z_]\w*(\[\d+\])*(\.[A-Za-z_]\w*(\[\d+\])*)*")
_STEP = re.compile(r"([A-Za-z_]\w*)|\[(\d+)\]")
#: Numeric fields listed at most in a message about a field that is not a number.
LISTED_FIELDS = 24


@dataclass(frozen=True)
class FieldRef:
    """One numeric field of a topic's messages, as the user named it.

    Attributes:
        topic: the topic (``/vehicle/wheel_speeds``).
        path: the field path, dotted into nested fields, with array indices
            (``wheels[2].speed``).
        steps: the path's field names and indices (``("wheels", 2, "speed")``).
        flag: the option that named it (``--rear-left``), or ``None`` when picked by type.
    """

    topic: str
    path: str
    steps: Steps
    flag: str | None = None

    @property
    def written(self) -> str:
        """``/vehicle/wheel_speeds:rear_left``, as on the command line."""
        return f"{self.topic}:{self.path}"

    def get(self, msg: Any) -> float | None:
        """The field's value in a deserialized message; ``None`` if an index is beyond a
        sequence's end."""
        value = msg
        try:
            for step in self.steps:
                value = value[step] if isinstance(step, int) else getattr(value, step)
        except IndexError:
            return None
        return float(value)


def parse_steps(path: str) -> Steps:
    """``"wheels[2].speed"`` → ``("wheels", 2, "speed")``; :class:`ValueError` if malformed."""
    if not _PATH.fullmatch(path):
        raise ValueError(path)
    return tuple(name or int(index) for name, index in _STEP.findall(path))


def is_field_ref(text: str | None, bag_topics: dict[str, str]) -> bool:
    """Whether an option's value is ``TOPIC:FIELD`` (a topic — absolute, or one in the bag —
    then a colon), not a joint name."""
    if text is None or ":" not in text:
        return False
    topic = text.split(":", 1)[0]
    return topic.startswith("/") or topic in bag_topics


def describe(nodetype: int, desc: Any) -> str:
    """``float32``, ``std_msgs/msg/Header``, ``float64[9]``, ``Wheel[]`` of a definition node."""
    if nodetype == BASE:
        return desc[0]
    if nodetype == NAME:
        return desc
    (subtype, subdesc), bound = desc
    inner = describe(subtype, subdesc)
    return f"{inner}[{bound}]" if nodetype == ARRAY else f"{inner}[]"


def listing(fielddefs: dict, msgtype: str) -> str:
    """``header (std_msgs/msg/Header), front_left (float32), ...``: a message's fields."""
    fields = fielddefs[msgtype][1]
    return ", ".join(f"{name} ({describe(*node)})" for name, node in fields) or "none"


def numeric_paths(fielddefs: dict, msgtype: str, prefix: str = "", depth: int = 0) -> list[str]:
    """The message's numeric field paths (arrays as ``name[i]``), nested up to 4 levels."""
    found: list[str] = []
    for name, (nodetype, desc) in fielddefs[msgtype][1]:
        path = f"{prefix}{name}"
        while nodetype in (ARRAY, SEQUENCE):
            (nodetype, desc), _ = desc
            path += "[i]"
        if nodetype == BASE and desc[0] in PRIMITIVES:
            found.append(path)
        elif nodetype == NAME and depth < 4 and desc in fielddefs:
            found.extend(numeric_paths(fielddefs, desc, f"{path}.", depth + 1))
    return found


def resolve_field(bag: BagContents, ref: FieldRef) -> str:
    """The primitive type (``float32``) of ``ref``, checked against the topic's message
    definition; :class:`StreamError` naming the option, topic, type and path and listing what
    exists (the bag's topics, the fields at the level where the path fails)."""
    flag = f"{ref.flag} {ref.written}" if ref.flag else ref.written
    where = f"{bag.source}: {flag}"
    if ref.topic not in bag.topics:
        raise StreamError(f"{where}: no topic {ref.topic} in the bag; {bag.topic_list()}")
    msgtype = bag.topics[ref.topic]
    fielddefs = bag.fielddefs
    if msgtype not in fielddefs:
        raise StreamError(
            f"{where}: the bag carries no definition of {msgtype} (a ROS 2 bag recorded before "
            "Iron stores none), so its fields cannot be read; record with a newer ROS 2"
        )
    nodetype, desc, walked = _walk(where, fielddefs, msgtype, ref.steps)
    if nodetype == BASE and desc[0] in PRIMITIVES:
        return desc[0]
    what = f"{walked} ({describe(nodetype, desc)})"
    if nodetype == NAME:
        exists = f"its fields: {listing(fielddefs, desc)}"
    elif nodetype in (ARRAY, SEQUENCE):
        exists = f"index it: {walked}[0]"
    else:
        numeric = numeric_paths(fielddefs, msgtype)
        shown = ", ".join(numeric[:LISTED_FIELDS]) + (
            ", ..." if len(numeric) > LISTED_FIELDS else ""
        )
        exists = f"the numeric fields of {msgtype}: {shown or 'none'}"
    raise StreamError(f"{where}: {what} is not a number; {exists}")


def _walk(where: str, fielddefs: dict, msgtype: str, steps: Steps) -> tuple[int, Any, str]:
    """The definition node ``(node type, description)`` at the end of ``steps`` in
    ``msgtype``, and the path walked; :class:`StreamError` where a step does not exist."""
    nodetype, desc = NAME, msgtype
    walked = ""
    for step in steps:
        what = f"{walked} ({describe(nodetype, desc)})" if walked else msgtype
        if isinstance(step, str):
            if nodetype != NAME:
                hint = f"; index it: {walked}[0]" if nodetype in (ARRAY, SEQUENCE) else ""
                raise StreamError(f"{where}: {what} has no fields{hint}")
            fields = dict(fielddefs[desc][1])
            if step not in fields:
                raise StreamError(
                    f"{where}: {what} has no field {step!r}; its fields: {listing(fielddefs, desc)}"
                )
            nodetype, desc = fields[step]
            walked = f"{walked}.{step}" if walked else step
            continue
        if nodetype not in (ARRAY, SEQUENCE):
            raise StreamError(f"{where}: {what} is not an array; drop the index [{step}]")
        (subtype, subdesc), bound = desc
        if nodetype == ARRAY and step >= bound:
            raise StreamError(
                f"{where}: {what} has {bound} elements; index 0 to {bound - 1}, not {step}"
            )
        nodetype, desc = subtype, subdesc
        walked += f"[{step}]"
    return nodetype, desc, walked


def field_ref(bag: BagContents, flag: str, text: str, topic: str | None = None) -> FieldRef:
    """``TOPIC:FIELD`` (or a bare field path on ``topic``) as a checked :class:`FieldRef`."""
    if topic is None:
        topic, path = text.split(":", 1)
    else:
        path = text
    try:
        steps = parse_steps(path)
    except ValueError:
        raise StreamError(
            f"{bag.source}: {flag} {text}: {path!r} is not a field path; write TOPIC:FIELD, "
            "the field dotted into nested fields with array indices (/vehicle/wheels:"
            "wheels[2].speed)"
        ) from None
    ref = FieldRef(topic, path, steps, flag)
    resolve_field(bag, ref)
    return ref
