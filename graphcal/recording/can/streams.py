"""The wheel and IMU streams of a manifest's CAN sections: the frames of each section's message
(on its bus), their signals decoded (:mod:`graphcal.recording.can.decode`), in the units the
manifest or the DBC gives, sorted, repeats dropped, the time checked and offset.
"""

from __future__ import annotations

import re

import numpy as np

from graphcal.recording.can.dbc import listing
from graphcal.recording.can.decode import decode_signals
from graphcal.recording.can.frames import EXTENDED_FLAG, Frames, frame_key, id_text
from graphcal.recording.can.source import CanSource
from graphcal.recording.streams import (
    Field,
    ImuStream,
    Provenance,
    StreamError,
    WheelStream,
    check_time,
    unique_samples,
)
from graphcal.recording.vocabulary import SPEED_UNITS, WHEEL_KINDS, YAW_RATE_UNITS
from graphcal.recording.wheel_scale import unwrap_counter, wheel_scale

#: How DBCs spell the units graphcal knows, by the manifest's unit name.
SPEED_UNIT_SPELLINGS = {
    "km/h": ("km/h", "kph", "kmh", "km/hr", "kmph", "kilometers per hour"),
    "m/s": ("m/s", "mps", "m/sec"),
    "mph": ("mph", "mi/h", "miles per hour"),
}
RPM_SPELLINGS = ("rpm", "1/min", "u/min", "rev/min", "r/min")
YAW_RATE_UNIT_SPELLINGS = {
    "deg/s": ("deg/s", "°/s", "dps", "deg/sec", "degree/s", "degrees/s", "grad/s"),
    "rad/s": ("rad/s", "rad/sec", "radians/s"),
}


def _bus_matches(name: str, bus: int | str) -> bool:
    """A log's bus name (``"can0"``, ``"1"``) is the manifest's ``bus`` (``"can0"``; or a
    number: ``0`` is ``"0"``, ``"can0"``, ``"vcan0"``)."""
    if isinstance(bus, str):
        return name == bus or (bus.isdigit() and _bus_matches(name, int(bus)))
    digits = re.search(r"(\d+)$", name)
    return digits is not None and int(digits.group(1)) == bus


def _message_frames(source: CanSource, frames: Frames) -> Frames:
    """The frames of the source's message (on its bus); one line if the log has none."""
    mine = frames.key == source.key
    if not mine.any():
        ids = sorted(frames.counts, key=lambda k: -frames.counts[k])
        known = {
            frame_key(m.frame_id, m.is_extended_frame): m.name for m in source.database.messages
        }
        named = [k for k in ids if k in known] + [k for k in ids if k not in known]
        listed = [f"{id_text(k)}" + (f" {known[k]}" if k in known else "") for k in named]
        other = ""
        flipped = source.key ^ EXTENDED_FLAG
        if flipped in frames.counts:
            other = (
                f" (it has {id_text(flipped)}: the DBC's message is "
                f"{'extended' if source.key & EXTENDED_FLAG else 'an 11-bit id'})"
            )
        raise StreamError(
            f"{frames.path}: no frame of {source.message_text()} ([{source.section}] "
            f"message){other} among its {frames.total} frames; the "
            f"log has {len(ids)} id(s): {listing(listed)}; check [{source.section}] message, "
            "dbc and can"
        )
    if source.bus is not None:
        buses = [i for i, name in enumerate(frames.channels) if _bus_matches(name, source.bus)]
        on_bus = mine & np.isin(frames.channel, buses)
        if not on_bus.any():
            found = sorted({frames.channels[c] for c in np.unique(frames.channel[mine])})
            raise StreamError(
                f"{frames.path}: no frame of {source.message_text()} on bus {source.bus!r} "
                f"({source.bus_key}); its frames are on {', '.join(found) or 'an unnamed bus'}; "
                "set bus to one of those or leave it out"
            )
        mine = on_bus
    return frames.take(mine)


def _decoded_samples(
    source: CanSource, frames: Frames, notes: list[str], wraps: dict[str, float]
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The time [s], the value of each role's signal and the frame numbers of a section's
    samples: the frames of its message that carry all its signals (a signal of another
    multiplexer page is interpolated at those frames' times, said in a note); counters that
    wrap (``wraps``, by role) are unwrapped first."""
    mine = _message_frames(source, frames)
    names = {role: signal.name for role, signal in source.signals.items()}
    decoded = decode_signals(
        source.message, list(dict.fromkeys(names.values())), mine.data, mine.length
    )
    failed = int(decoded.failed.sum())
    roles = list(names)
    if failed:
        k = int(np.flatnonzero(decoded.failed)[0])
        reason = decoded.reasons.get(k, "")
        what = (
            f"{failed} of the {len(mine.t)} frames of {source.message_text()} "
            f"([{source.section}] message) do not decode (first: {mine.unit} "
            f"{int(mine.number[k])}{': ' + reason if reason else ''})"
        )
        if failed == len(mine.t):
            raise StreamError(f"{frames.path}: {what}; check [{source.section}] dbc and message")
        notes.append(f"{frames.path}: {what}; left out")
    present = {role: decoded.present[names[role]] for role in roles}
    lead = roles[0]
    for role in roles:
        if not present[role].any():
            raise StreamError(
                f"{frames.path}: no frame of {source.message_text()} carries signal "
                f"{names[role]} ([{source.section}] {role}; multiplexed: its page never "
                "comes); check the signal"
            )
    keep = np.flatnonzero(present[lead])
    t = mine.t[keep]
    values = {}
    for role in roles:
        own = present[role]
        value = decoded.values[names[role]]
        if np.array_equal(own, present[lead]):
            values[role] = value[keep]
            if role in wraps:
                values[role] = unwrap_counter(values[role], wraps[role])
            continue
        order = np.argsort(mine.t[own], kind="stable")
        own_t, own_v = mine.t[own][order], value[own][order]
        if role in wraps:
            own_v = unwrap_counter(own_v, wraps[role])
        values[role] = np.interp(t, own_t, own_v)
        inside = (t >= own_t[0]) & (t <= own_t[-1])
        t, keep = t[inside], keep[inside]
        values = {r: v[inside] for r, v in values.items()}
        notes.append(
            f"{frames.path}: signals {names[lead]} and {names[role]} of "
            f"{source.message.name} come in different frames (multiplexer pages): "
            f"{names[role]} interpolated at the times of {names[lead]}"
        )
    return t, values, mine.number[keep]


def _unit_of(signal) -> str:
    return (signal.unit or "").strip()


def _known_unit(unit: str, spellings: dict[str, tuple[str, ...]]) -> str | None:
    folded = unit.lower().replace(" ", "")
    for name, options in spellings.items():
        if folded in options:
            return name
    return None


def _dbc_unit(source: CanSource, roles: tuple[str, ...], spellings) -> tuple[str | None, str]:
    """The unit the DBC gives the roles' signals, if one graphcal knows and all agree, and the
    DBC's text of it."""
    units = {_unit_of(source.signals[r]) for r in roles if r in source.signals}
    known = {_known_unit(u, spellings) for u in units}
    if len(known) == 1 and None not in known:
        return known.pop(), ", ".join(sorted(units))
    return None, ", ".join(repr(u) for u in sorted(units)) or "none"


def wheel_stream(source: CanSource, frames: Frames, notes: list[str]) -> WheelStream:
    """The wheel stream of ``[wheels]`` from its CAN message (units as ``_read_wheels``)."""
    table = source.table
    signals = source.signals
    dbc_unit, dbc_text = _dbc_unit(source, ("rear_left", "rear_right"), SPEED_UNIT_SPELLINGS)
    rpm = all(_unit_of(s).lower() in RPM_SPELLINGS for s in signals.values())
    if "kind" not in table:
        suggestion = (
            ' (the DBC\'s unit says kind = "speed")'
            if dbc_unit
            else (' (the DBC\'s unit says kind = "rpm")' if rpm else "")
        )
        raise table.error(f"[wheels] needs kind (one of {', '.join(WHEEL_KINDS)}){suggestion}")
    kind = table.choice("kind", WHEEL_KINDS, None)
    cumulative, wraps = WHEEL_KINDS[kind].cumulative, {}
    declared = [f'kind = "{kind}"']
    keys: dict[str, str] = {"kind": kind}

    def speed_unit() -> str:
        if "speed_unit" in table:
            unit = table.choice("speed_unit", SPEED_UNITS, None)
            declared.append(f'speed_unit = "{unit}"')
            if dbc_unit is not None and dbc_unit != unit:
                notes.append(
                    f"{source.dbc}: {source.message.name}'s wheel signals are in {dbc_text}; "
                    f'[wheels] speed_unit = "{unit}" overrides it'
                )
            return unit
        if dbc_unit is not None:
            declared.append(f'speed_unit = "{dbc_unit}" from the DBC ({dbc_text})')
            return dbc_unit
        hint = ' (the signals are in rpm: set kind = "rpm")' if rpm else ""
        raise table.error(
            f"[wheels] needs speed_unit ({', '.join(SPEED_UNITS)}): {source.dbc} gives "
            f"signals {signals['rear_left'].name}, {signals['rear_right'].name} the unit "
            f"{dbc_text}{hint}"
        )

    scaling = wheel_scale(table, kind, speed_unit)
    scale, resolution, wrap = scaling.scale, scaling.resolution, scaling.wrap
    if kind == "speed":
        declared.append(f"circumference = {scaling.circumference:g} m")
        keys.update(speed_unit=str(scaling.speed_unit), circumference=repr(scaling.circumference))
    elif kind == "ticks":
        declared.append(f"ticks_per_revolution = {scaling.ticks:g}")
        keys["ticks_per_revolution"] = repr(scaling.ticks)
        for role, signal in signals.items():
            counter_wrap = wrap if wrap is not None else _counter_range(signal)
            if counter_wrap is not None:
                wraps[role] = counter_wrap
    units = ", ".join(declared)
    t, values, numbers = _decoded_samples(source, frames, notes, wraps)
    fields = {
        "time": Field("timestamp", source.log_key.split(" in ")[0], "s (the log's)"),
        **{
            role: Field(source.field_name(role), f"[wheels] {role}", units, tuple(keys.items()))
            for role in ("rear_left", "rear_right")
        },
    }
    t, values, provenance = _checked(source, frames, t, values, numbers, fields, notes)
    return WheelStream(
        t=t,
        left=values["rear_left"] * scale,
        right=values["rear_right"] * scale,
        cumulative=cumulative,
        source=str(frames.path),
        resolution=resolution,
        provenance=provenance,
    )


def _counter_range(signal) -> float | None:
    """Where an unsigned integer counter signal wraps: its raw range × scale (offset 0)."""
    if signal.is_signed or signal.is_float or signal.offset != 0 or signal.scale <= 0:
        return None
    return float(2 ** int(signal.length)) * float(signal.scale)


def imu_stream(source: CanSource, frames: Frames, notes: list[str]) -> ImuStream:
    """The IMU stream of ``[imu]`` from its CAN message."""
    table = source.table
    declared: dict[str, dict[str, str]] = {}
    units = {"lateral_acceleration": "m/s², positive to the left"}
    factor = 1.0
    if "yaw_rate" in source.signals:
        dbc_unit, dbc_text = _dbc_unit(source, ("yaw_rate",), YAW_RATE_UNIT_SPELLINGS)
        if "yaw_rate_unit" in table:
            unit = table.choice("yaw_rate_unit", YAW_RATE_UNITS, None)
            units["yaw_rate"] = f'yaw_rate_unit = "{unit}"'
        elif dbc_unit is not None:
            unit = dbc_unit
            units["yaw_rate"] = f'yaw_rate_unit = "{unit}" from the DBC ({dbc_text})'
        else:
            raise table.error(
                f"[imu] needs yaw_rate_unit ({', '.join(YAW_RATE_UNITS)}): {source.dbc} gives "
                f"signal {source.signals['yaw_rate'].name} the unit {dbc_text}"
            )
        declared["yaw_rate"] = {"yaw_rate_unit": unit}
        factor = YAW_RATE_UNITS[unit]
    t, values, numbers = _decoded_samples(source, frames, notes, {})
    fields = {
        "time": Field("timestamp", source.log_key.split(" in ")[0], "s (the log's)"),
        **{
            role: Field(
                source.field_name(role),
                f"[imu] {role}",
                units.get(role),
                tuple(declared.get(role, {}).items()),
            )
            for role in source.signals
        },
    }
    t, values, provenance = _checked(source, frames, t, values, numbers, fields, notes)
    yaw_rate = values.get("yaw_rate")
    return ImuStream(
        t=t,
        lateral_acceleration=values.get("lateral_acceleration"),
        yaw_rate=None if yaw_rate is None else yaw_rate * factor,
        source=str(frames.path),
        provenance=provenance,
    )


def _checked(
    source: CanSource,
    frames: Frames,
    t: np.ndarray,
    values: dict[str, np.ndarray],
    numbers: np.ndarray,
    fields: dict[str, Field],
    notes: list[str],
) -> tuple[np.ndarray, dict[str, np.ndarray], Provenance]:
    """Sort the samples by time, drop repeats (:func:`unique_samples`), check the time and
    add the section's ``time_offset``."""
    provenance = Provenance(str(frames.path), fields, numbers, frames.unit, quantity="signal")
    keep = unique_samples(t, values, provenance, notes, sort=True)
    if len(keep) < len(t) or not np.array_equal(keep, np.arange(len(t))):
        t, provenance = t[keep], provenance.take(keep)
        values = {role: v[keep] for role, v in values.items()}
    check_time(t, str(frames.path), provenance)
    table = source.table
    if "time_offset" not in table and source.inherits:  # the wheels' log: the same clock
        table = source.inherits
    offset = table.number("time_offset", 0.0)
    return t + offset, values, provenance
