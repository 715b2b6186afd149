"""Settings and vehicle files: TOML read into
:class:`~graphcal.pipeline.configuration.settings.Settings` and
:class:`~graphcal.vehicle.VehicleProfile`, key by key and type by type, with one-line errors naming
the file and the key (the schema: :mod:`graphcal.pipeline.configuration.settings`)."""

from __future__ import annotations

import dataclasses
import os
import re
import tomllib
import types
import typing
from typing import Any, Literal

import numpy as np

from graphcal.errors import GraphcalError, is_number
from graphcal.pipeline.configuration.settings import Settings, setting_fields
from graphcal.pipeline.configuration.vehicle_settings import DERIVED_SECTIONS, follow_vehicle
from graphcal.vehicle import VehicleProfile

#: Keys of older settings files, with where they went; loading one is a one-line error.
_MOVED = {
    "input_estimation": (
        "[input_estimation] is now [staged] with sub-tables [staged.step2] and [staged.step4]: "
        "step2_tracking_weights -> staged.step2.tracking_weights, step4_tracking_weights -> "
        "staged.step4.tracking_weights, smoothness_weight, input_bound, chunk_steps, "
        "continuity_sigmas and max_iterations -> both staged.step2.<key> and "
        "staged.step4.<key>, heading_correction_step, heading_correction, estimations, "
        "trim_fraction and estimate_start_poses -> staged.<key>"
    ),
    "calibration.theta_nominal": "[calibration] theta_nominal is now theta_initial",
    "joint.theta_nominal": "[joint] theta_nominal is now theta_initial",
    "joint.slip_detection": (
        "[joint] slip_detection (a χ² drop per chunk) is now slip_alpha: slip is modelled "
        "when the drop exceeds what the log's own noise gives at this false-alarm rate "
        "(default 0.001)"
    ),
    "time_offset": (
        "[time_offset] is gone: the joint solve estimates the wheels' time offset with theta "
        "([joint] time_offset_sigma, 0 = off)"
    ),
    **{
        f"lever_arm.{key}": (
            f"[lever_arm] {key} is gone: the joint solve estimates the lever arm with theta "
            "([joint] lever_arm_sigma, 0 = off)"
        )
        for key in ("estimate", "search_longitudinal", "search_lateral", "step")
    },
}


def settings_from_dict(data: dict[str, Any], source: str = "<settings>") -> Settings:
    """Build :class:`Settings` from a nested dict like a TOML file's (unknown keys rejected).

    With a ``vehicle`` table, the settings that depend on the vehicle follow it
    (:func:`~graphcal.pipeline.configuration.vehicle_settings.apply_vehicle`) except those the dict
    gives itself.
    """
    settings = _load(Settings(), data, "", source)
    if "vehicle" not in data:
        return settings
    given = {
        f"{section}.{key}" for section, _ in DERIVED_SECTIONS for key in (data.get(section) or {})
    }
    return follow_vehicle(settings, VehicleProfile(), settings.vehicle, given)


def load_settings(path: str | os.PathLike[str]) -> Settings:
    """Read :class:`Settings` from a TOML file (missing keys keep the paper's defaults)."""
    return settings_from_dict(_read_toml(path, "settings"), str(path))


def load_vehicle(path: str | os.PathLike[str]) -> VehicleProfile:
    """Read a :class:`~graphcal.vehicle.VehicleProfile` from a TOML file.

    The file's top level holds the vehicle's keys (``data/vehicles/car.toml``), or the file
    has a ``[vehicle]`` table and nothing else. Missing keys keep the paper's car values.

    Raises:
        GraphcalError: one line naming the file and the key.
    """
    source = str(path)
    data = _read_toml(path, "vehicle")
    if isinstance(data.get("vehicle"), dict):
        others = sorted(key for key in data if key != "vehicle")
        if others:
            raise GraphcalError(
                f"{source}: a vehicle file holds only the vehicle's keys or a [vehicle] table, "
                f"also found {others}; give a settings file with --config"
            )
        data = data["vehicle"]
    return _load(VehicleProfile(), data, "vehicle", source)


def vehicle_settings_in(path: str | os.PathLike[str]) -> set[str]:
    """The settings a TOML settings file sets that a vehicle profile would otherwise set
    (``"joint.wheel_noise"``, ...): what
    :func:`~graphcal.pipeline.configuration.vehicle_settings.apply_vehicle` must ``keep`` when a
    vehicle is given on top of the file."""
    data = _read_toml(path, "settings")
    return {
        f"{section}.{key}"
        for section, derived in DERIVED_SECTIONS
        if isinstance(data.get(section), dict)
        for key in data[section]
        if key in derived
    }


def _read_toml(path: str | os.PathLike[str], kind: str) -> dict[str, Any]:
    """The table of TOML file ``path`` (a ``kind`` file), with one-line errors."""
    source = str(path)
    try:
        with open(path, "rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise GraphcalError(f"{source}: no such {kind} file; check the path") from None
    except IsADirectoryError:
        raise GraphcalError(f"{source}: is a directory, not a {kind} file") from None
    except tomllib.TOMLDecodeError as exc:
        raise GraphcalError(f"{source}: not valid TOML ({exc})") from exc


def _load(default: Any, data: Any, section: str, source: str) -> Any:
    """``default`` with the values of ``data`` (table ``section``) replaced, checked by type."""
    where = f"[{section}]" if section else "the file"
    if not isinstance(data, dict):
        raise GraphcalError(f"{source}: {where} must be a table, got {data!r}")
    names = [f.name for f in setting_fields(default)]
    unknown = [key for key in data if key not in names]
    for key in unknown:
        moved = _MOVED.get(f"{section}.{key}" if section else key)
        if moved:
            raise GraphcalError(f"{source}: {moved}")
    if unknown:
        what = f"key(s) {sorted(unknown)} in [{section}]" if section else f"section(s) {unknown}"
        raise GraphcalError(f"{source}: unknown {what}; known: {names}")
    hints = typing.get_type_hints(type(default))
    changes = {}
    for key, value in data.items():
        current = getattr(default, key)
        if dataclasses.is_dataclass(current):
            path = f"{section}.{key}" if section else key
            changes[key] = _load(current, value, path, source)
        else:
            changes[key] = _convert(value, hints[key], current, f"[{section}] {key}", source)
    try:
        return dataclasses.replace(default, **changes)
    except (TypeError, ValueError) as exc:
        message = str(exc)
        if section and not message.startswith(f"{section}."):
            # A dataclass names its own section ("input_estimation.") or none at all.
            named = re.match(r"\w+\.(?=\w)", message)
            message = f"{section}.{message[named.end() :]}" if named else f"[{section}] {message}"
        raise GraphcalError(f"{source}: {message}") from exc


def _convert(value: Any, hint: Any, current: Any, name: str, source: str) -> Any:
    """``value`` as the type ``hint`` of a field whose default is ``current``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType) and type(None) in args:
        if value is None:
            return None
        (hint,) = [a for a in args if a is not type(None)]
        origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is np.ndarray or origin is tuple:
        n = len(current)
        ok = (
            isinstance(value, list | tuple)
            and len(value) == n
            and all(is_number(v) and np.isfinite(v) for v in value)
        )
        if not ok:
            raise GraphcalError(
                f"{source}: {name} must be a list of {n} finite numbers, got {value!r}"
            )
        return (
            np.array(value, dtype=float) if hint is np.ndarray else tuple(float(v) for v in value)
        )
    if origin is Literal:
        ok, kind = value in args, "one of " + ", ".join(repr(a) for a in args)
    elif hint is bool:
        ok, kind = isinstance(value, bool), "true or false"
    elif hint is int:
        ok, kind = isinstance(value, int) and not isinstance(value, bool), "a whole number"
    elif hint is float:
        ok, kind = is_number(value), "a number"
        value = float(value) if ok else value
    elif hint is str:
        ok, kind = isinstance(value, str), "text"
    else:
        raise TypeError(f"settings field {name} has a type the loader does not know: {hint}")
    if not ok:
        raise GraphcalError(f"{source}: {name} must be {kind}, got {value!r}")
    return value
