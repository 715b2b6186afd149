"""Import a recording (streams manifest or ROS bag) into a validated drive log.

:func:`import_recording` reads the streams (:mod:`graphcal.data.manifest`,
:mod:`graphcal.data.bags`), puts them on the uniform grid (:func:`graphcal.data.streams.resample`),
checks that the pose and the wheels turn the same way (swapped latitude/longitude, a
compass heading declared ENU, swapped wheels) and validates the result as any drive-log CSV
(:func:`graphcal.data.drive_log.validate_frame`). :func:`write_import` writes the drive-log
CSV and a JSON sidecar saying where it came from.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.data.drive_log import DriveLog, validate_frame, write_drive_log
from graphcal.data.streams import (
    MAX_GAP_S,
    Recording,
    Resampled,
    StreamError,
    course,
    resample,
)
from graphcal.files import atomic_write_text
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL

#: Suffixes of a streams manifest.
MANIFEST_SUFFIXES = (".toml",)
#: Window [s] over which the pose's and the wheels' turning are compared.
TURN_WINDOW_S = 2.0
#: Yaw [rad] in such a window for it to count as a turn, and turns needed for a verdict.
TURN_MIN_YAW = 0.1
TURN_MIN_COUNT = 5
#: Share of turns in which two signals must agree; below it they turn opposite ways.
TURN_MIN_AGREEMENT = 0.25


@dataclass(frozen=True)
class BagOptions:
    """Which topics and joints of a ROS bag to read (``None``: detect)."""

    pose_topic: str | None = None
    wheel_topic: str | None = None
    imu_topic: str | None = None
    rear_left: str | None = None
    rear_right: str | None = None
    wheel_kind: str | None = None


@dataclass(frozen=True)
class ImportedLog:
    """An imported recording: the validated drive log and how it was made.

    Attributes:
        log: the drive log on the uniform grid (gaps masked).
        resampled: stream summaries, overlap and notes of the resampling.
        origin: ``(latitude, longitude)`` [deg] of the local frame, or ``None``.
        truth: ``theta_true`` [SI] of a synthetic recording (the manifest's ``truth``), or
            ``None``.
        source: the manifest or bag.
    """

    log: DriveLog
    resampled: Resampled
    origin: tuple[float, float] | None
    truth: np.ndarray | None
    source: str

    def sidecar(self) -> dict:
        """The JSON sidecar's content: where the log came from and what was done."""
        from graphcal import __version__

        r = self.resampled
        meta: dict = {
            "generator": f"graphcal {__version__} import",
            "source": self.source,
            "samples": len(self.log),
            "rate_hz": 1.0 / self.log.dt,
            "overlap_s": list(r.overlap),
            "time_origin_s": r.overlap[0],
            "origin_deg": None
            if self.origin is None
            else {"latitude": self.origin[0], "longitude": self.origin[1]},
            "streams": [
                {
                    "role": s.role,
                    "source": s.source,
                    "samples": s.samples,
                    "rate_hz": s.rate,
                    "start_s": s.start,
                    "end_s": s.end,
                    "gaps_s": [list(g) for g in s.gaps],
                }
                for s in r.streams
            ],
            "notes": list(r.notes),
            "masked": list(self.log.mask_notes),
            "heading": "derived from the GNSS course" if r.heading_derived else "logged",
        }
        if self.truth is not None:
            meta["theta_true"] = dict(zip(PARAMETER_NAMES, map(float, self.truth), strict=True))
        return meta

    def lines(self) -> list[str]:
        """What the import found, for the printout."""
        r = self.resampled
        lines = [s.line() for s in r.streams]
        lines.append(
            f"overlap {r.overlap[1] - r.overlap[0]:.1f} s (t = {r.overlap[0]:.3f} … "
            f"{r.overlap[1]:.3f} s) -> {len(self.log)} samples at {1 / self.log.dt:g} Hz"
        )
        lines += [f"note: {note}" for note in r.notes]
        return lines


def is_recording(path: str | os.PathLike[str]) -> bool:
    """True if ``path`` is a streams manifest (``.toml``) or a ROS bag / MCAP file."""
    path = Path(path)
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        return True
    from graphcal.data.bags import is_bag

    return is_bag(path)


def read_recording(source: str | os.PathLike[str], bag: BagOptions | None = None) -> Recording:
    """The streams of a manifest or a bag."""
    path = Path(source)
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        from graphcal.data.manifest import read_manifest

        return read_manifest(path)
    from graphcal.data.bags import is_bag, read_bag

    if not path.exists():
        raise StreamError(f"{source}: no such file or directory; check the path")
    if not is_bag(path):
        raise StreamError(
            f"{source}: neither a streams manifest (.toml) nor a ROS bag (.bag, .mcap, a ROS 2 "
            "bag directory)"
        )
    return read_bag(path, **dataclasses.asdict(bag or BagOptions()))


def import_recording(
    source: str | os.PathLike[str],
    *,
    rate: float | None = None,
    max_gap: float | None = None,
    bag: BagOptions | None = None,
    nominal: np.ndarray = THETA_NOMINAL,
    min_distance: float = 0.0,
) -> ImportedLog:
    """Import a streams manifest or a ROS bag into a validated :class:`DriveLog`.

    Args:
        source: a manifest (``.toml``), a ROS 1 bag, a ROS 2 bag directory or an MCAP file.
        rate: drive-log rate [Hz] (default: the manifest's ``rate``, else 40).
        max_gap: shortest gap [s] that masks the log (default: the manifest's, else 0.5).
        bag: topics and joints of a bag (detected when not given).
        nominal: the vehicle's nominal theta (SI), for the plausibility checks.
        min_distance: shortest acceptable travelled distance [m].

    Raises:
        GraphcalError: one line naming the file, stream or column and how to fix it.
    """
    path = Path(source)
    truth = None
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        from graphcal.data.manifest import load_manifest, read_manifest

        manifest = load_manifest(path)
        recording = read_manifest(manifest)
        rate = rate if rate is not None else manifest.rate
        max_gap = max_gap if max_gap is not None else manifest.max_gap
        truth = _read_truth(manifest)
    else:
        recording = read_recording(path, bag)
    resampled = resample(
        recording,
        rate=rate if rate is not None else 40.0,
        max_gap=max_gap if max_gap is not None else MAX_GAP_S,
        wheel_circumference=float(nominal[0]),
    )
    check_turning(resampled, recording, nominal)
    import pandas as pd

    log = validate_frame(
        pd.DataFrame(resampled.columns),
        str(source),
        min_distance,
        marked=resampled.masked,
        marked_notes=resampled.mask_notes,
        nominal=nominal,
    )
    return ImportedLog(
        log=log,
        resampled=resampled,
        origin=recording.pose.origin,
        truth=truth,
        source=str(source),
    )


def _read_truth(manifest) -> np.ndarray | None:
    """``theta_true`` of the manifest's ``truth`` JSON (synthetic recordings), or ``None``."""
    name = manifest.data.get("truth")
    if name is None:
        return None
    path = manifest.resolve(str(name))
    try:
        meta = json.loads(path.read_text())
        theta = np.array([float(meta["theta_true"][p]) for p in PARAMETER_NAMES])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise manifest.error(
            f"truth = {name!r}: not a JSON file with theta_true ({type(exc).__name__}); "
            "remove the key for a real recording"
        ) from None
    return theta


def _turn_directions(yaw: np.ndarray, usable: np.ndarray, window: int) -> np.ndarray:
    """Signed yaw [rad] over consecutive windows; NaN where a window holds masked samples."""
    ends = np.arange(0, len(yaw), window)
    turns = np.diff(yaw[ends])
    clean = np.add.reduceat((~usable).astype(int), ends)[: len(turns)] == 0
    return np.where(clean, turns, np.nan)


def _agreement(a: np.ndarray, b: np.ndarray) -> float | None:
    """Share of windows turning clearly in both signals where they turn the same way."""
    both = (np.abs(a) > TURN_MIN_YAW) & (np.abs(b) > TURN_MIN_YAW)
    if both.sum() < TURN_MIN_COUNT:
        return None
    return float((np.sign(a[both]) == np.sign(b[both])).mean())


def check_turning(resampled: Resampled, recording: Recording, nominal: np.ndarray) -> None:
    """One line if the GNSS track, the heading and the wheels do not turn the same way.

    A mirrored track (latitude/longitude or x/y swapped), a heading in the other convention
    (compass declared ENU) or swapped wheels (rear_left/rear_right) all show as turns in
    opposite directions.
    """
    c = resampled.columns
    dt = float(c["t"][1] - c["t"][0])
    window = max(1, round(TURN_WINDOW_S / dt))
    usable = ~resampled.masked
    wheel_yaw = np.concatenate(
        [[0.0], np.cumsum((c["n_rr"][:-1] - c["n_rl"][:-1]) * nominal[0] / nominal[2])]
    )
    wheels = _turn_directions(wheel_yaw, usable, window)
    track = _turn_directions(course(c["px"], c["py"], dt), usable, window)
    wheels_track = _agreement(wheels, track)
    pose = recording.pose
    heading = None
    if pose.heading is not None:
        heading = _agreement(_turn_directions(c["psi"], usable, window), track)
    wheels_heading = (
        _agreement(wheels, _turn_directions(c["psi"], usable, window))
        if pose.heading is not None
        else None
    )

    def opposite(value: float | None) -> bool:
        return value is not None and value < TURN_MIN_AGREEMENT

    def agree(value: float | None) -> bool:
        return value is not None and value >= 1 - TURN_MIN_AGREEMENT

    names = _pose_names(pose.origin is not None)
    if opposite(wheels_track) and agree(heading):
        raise StreamError(
            f"{recording.wheels.source}: the wheels turn opposite to the GNSS track and the "
            f"heading in {1 - wheels_track:.0%} of the turns; rear_left and rear_right are "
            "swapped"
        )
    if opposite(heading) and agree(wheels_track):
        raise StreamError(
            f"{pose.source}: the heading turns opposite to the GNSS track and the wheels in "
            f"{1 - heading:.0%} of the turns; check heading_convention (compass: 0 = north, "
            "clockwise; enu: 0 = east, counter-clockwise)"
        )
    if opposite(wheels_track) and (heading is None or agree(wheels_heading)):
        cause = f"{names} swapped" + ("" if heading is not None else " or the wheels swapped")
        raise StreamError(
            f"{pose.source}: the GNSS track turns opposite to the wheels in "
            f"{1 - wheels_track:.0%} of the turns, a mirrored track: {cause}; exchange them"
        )


def _pose_names(geodetic: bool) -> str:
    return "latitude and longitude" if geodetic else "x and y"


def heading_derived(csv_path: str | os.PathLike[str]) -> bool:
    """True if the drive-log CSV at ``csv_path`` was imported with a heading derived from the
    GNSS course (its ``<stem>.json`` sidecar from ``graphcal import`` says so)."""
    path = Path(csv_path)
    try:
        meta = json.loads(path.with_name(f"{path.stem}.json").read_text())
    except (OSError, ValueError):
        return False
    return (
        isinstance(meta, dict)
        and str(meta.get("generator", "")).endswith(" import")
        and str(meta.get("heading", "")).startswith("derived")
    )


def write_import(imported: ImportedLog, csv_path: str | os.PathLike[str]) -> list[Path]:
    """Write the drive-log CSV and its ``<stem>.json`` sidecar (each atomically)."""
    csv_path = Path(csv_path)
    write_drive_log(imported.log, csv_path)
    sidecar = csv_path.with_name(f"{csv_path.stem}.json")  # as a synthetic drive's sidecar
    atomic_write_text(sidecar, json.dumps(imported.sidecar(), indent=2) + "\n")
    return [csv_path, sidecar]
