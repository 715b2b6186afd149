"""Which logs a fleet run calibrates: a directory tree or a CSV manifest.

* A directory ``SOURCE`` holding one directory per vehicle, each with one drive log per day:
  ``SOURCE/VEHICLE/DAY.csv`` (a recording — a streams manifest directory or a bag — may stand
  in for a CSV). ``DAY_truth.csv`` files next to ``DAY.csv`` (the noise-free signals of a
  synthetic drive) are not logs. ``SOURCE/VEHICLE/vehicle.toml``, if present, is that
  vehicle's profile (:func:`graphcal.pipeline.configuration.settings_file.load_vehicle`).
* A CSV manifest with the columns ``vehicle, day, path`` and optionally ``profile`` (a
  vehicle profile file); relative paths are relative to the manifest.

Days are ordered as their names sort: name them so (``2026-11-23``, ``day01``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from graphcal.errors import GraphcalError

#: A vehicle directory's own profile.
PROFILE_NAME = "vehicle.toml"
#: Log files of a directory tree (a recording directory counts too).
LOG_SUFFIXES = (".csv", ".bag", ".mcap", ".db3")


@dataclass(frozen=True)
class FleetLog:
    """One log of the fleet.

    Attributes:
        vehicle: the vehicle's name.
        day: the day's name (days sort by it).
        path: the drive log (a CSV or a recording).
        profile: the vehicle's profile file, or ``None`` for the run's settings alone.
    """

    vehicle: str
    day: str
    path: Path
    profile: Path | None = None


def discover_fleet(source: str | os.PathLike[str]) -> list[FleetLog]:
    """The logs of ``source`` (a directory tree or a CSV manifest), sorted by vehicle and day.

    Raises:
        GraphcalError: if ``source`` does not exist, a manifest lacks a column or names a
            missing file, a vehicle has two logs for one day, or there is no log at all.
    """
    source = Path(source).expanduser().resolve()  # workers elsewhere need whole paths
    if source.is_dir():
        logs = _from_tree(source)
    elif source.is_file():
        logs = _from_manifest(source)
    else:
        raise GraphcalError(f"{source}: no such directory or manifest")
    if not logs:
        raise GraphcalError(
            f"{source}: no logs found; expected VEHICLE/DAY.csv files or a manifest with "
            "columns vehicle, day, path"
        )
    seen: set[tuple[str, str]] = set()
    for log in logs:
        if (log.vehicle, log.day) in seen:
            raise GraphcalError(
                f"{source}: vehicle {log.vehicle} has more than one log for day {log.day}"
            )
        seen.add((log.vehicle, log.day))
    return sorted(logs, key=lambda log: (log.vehicle, log.day))


def _from_tree(root: Path) -> list[FleetLog]:
    logs = []
    for vehicle in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        profile = vehicle / PROFILE_NAME
        for path in sorted(vehicle.iterdir()):
            if path.name.startswith(".") or not _is_log(path):
                continue
            logs.append(
                FleetLog(vehicle.name, _day(path), path, profile if profile.is_file() else None)
            )
    return logs


def _is_log(path: Path) -> bool:
    """A drive-log CSV (not a synthetic drive's ``*_truth.csv``), a bag or a recording."""
    if path.is_dir():
        return (path / "manifest.toml").is_file() or (path / "metadata.yaml").is_file()
    if path.suffix.lower() not in LOG_SUFFIXES:
        return False
    if path.name.endswith("_truth.csv"):
        return not path.with_name(path.name[: -len("_truth.csv")] + ".csv").exists()
    return True


def _day(path: Path) -> str:
    return path.name if path.is_dir() else path.stem


def _from_manifest(manifest: Path) -> list[FleetLog]:
    try:
        table = pd.read_csv(manifest, dtype=str, keep_default_na=False)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise GraphcalError(f"{manifest}: not a readable CSV manifest: {exc}") from exc
    table.columns = [c.strip().lower() for c in table.columns]
    missing = [c for c in ("vehicle", "day", "path") if c not in table.columns]
    if missing:
        raise GraphcalError(
            f"{manifest}: missing column(s) {', '.join(missing)}; a fleet manifest has the "
            "columns vehicle, day, path (and optionally profile)"
        )
    logs = []
    for row, entry in enumerate(table.itertuples(index=False), start=2):
        vehicle, day = str(entry.vehicle).strip(), str(entry.day).strip()
        if not vehicle or not day:
            raise GraphcalError(f"{manifest}, line {row}: empty vehicle or day")
        path = _resolve(manifest, str(entry.path).strip())
        if not path.exists():
            raise GraphcalError(f"{manifest}, line {row}: {path} does not exist")
        profile_text = str(getattr(entry, "profile", "") or "").strip()
        profile = _resolve(manifest, profile_text) if profile_text else None
        if profile is not None and not profile.is_file():
            raise GraphcalError(f"{manifest}, line {row}: profile {profile} does not exist")
        logs.append(FleetLog(vehicle, day, path, profile))
    return logs


def _resolve(manifest: Path, text: str) -> Path:
    path = Path(text).expanduser()
    return path if path.is_absolute() else manifest.parent / path
