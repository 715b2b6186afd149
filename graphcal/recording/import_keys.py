"""How a user names what to fix in an import: a manifest key (``[wheels] speed_unit``) or a
command-line flag (``--speed-unit``, for a bag's fields), and a stream's own advice."""

from __future__ import annotations

from graphcal.recording.streams import Provenance, provenance_of


def is_flag(field) -> bool:
    """Whether ``field`` was named by a command-line flag (a bag's field path, ``--rear-left``),
    not by a manifest key."""
    return field is not None and bool(field.key) and field.key.startswith("--")


def key_name(field, key: str) -> str:
    """How the user names the unit key ``key`` of ``field``: ``[wheels] speed_unit`` (a
    manifest) or ``--speed-unit`` (a bag's field named on the command line)."""
    if is_flag(field):
        return "--" + key.replace("_", "-")
    return f"{field.section} {key}" if field is not None and field.section else key


def convention_key(pose) -> str:
    """``heading_convention``, or ``--heading-convention`` for a heading named by a flag."""
    field = provenance_of(pose).fields.get("heading")
    return "--heading-convention" if is_flag(field) else "heading_convention"


def set_key(field, key: str, value: str) -> str:
    """``set [wheels] speed_unit = "km/h"`` or ``pass --speed-unit km/h``."""
    if is_flag(field):
        return f"pass {key_name(field, key)} {value}"
    return f'set {key_name(field, key)} = "{value}"'


def pose_names(geodetic: bool) -> str:
    return "latitude and longitude" if geodetic else "x and y"


def stream_advice(provenance: Provenance, topic: str, default: str) -> str:
    """``default``, or the stream's own advice on ``topic`` (``"position"``, ``"heading"``,
    ``"mirrored"``) where its reader gives one: an NMEA log's has no columns or units to
    check (:class:`graphcal.recording.nmea.read.SentenceProvenance`)."""
    return getattr(provenance, "advice", {}).get(topic, default)
