"""Import a recording (streams manifest or ROS bag) into a validated drive log.

:func:`import_recording` reads the streams (:mod:`graphcal.recording.manifest_recording`,
:mod:`graphcal.recording.bag.read`), puts them on the uniform grid
(:func:`graphcal.recording.resampling.resample`), checks the streams against each other
(:func:`graphcal.recording.import_checks.check_recording`: swapped latitude/longitude, a
compass heading declared ENU, swapped wheels, wrong units) and validates the result as any
drive-log CSV (:func:`graphcal.log.validation.validate_frame`), each column naming where it
came from (:func:`graphcal.recording.column_origins.column_origins`).
:func:`graphcal.recording.import_output.write_import` writes the drive-log CSV and a JSON
sidecar saying where it came from.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.files import graphcal_json
from graphcal.log.drive_log import DriveLog
from graphcal.log.noise import rate_wheel_noise
from graphcal.log.validation import validate_frame
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL
from graphcal.recording.bag.request import BagRequest
from graphcal.recording.column_origins import column_origins
from graphcal.recording.import_checks import check_recording
from graphcal.recording.resampling import Resampled, resample
from graphcal.recording.stream_grid import DEFAULT_RATE, MAX_GAP_S, grid_rate
from graphcal.recording.streams import Recording, StreamError
from graphcal.recording.wheel_speeds import check_wheel_speeds

#: Suffixes of a streams manifest.
MANIFEST_SUFFIXES = (".toml",)


#: Which topics, joints and fields of a ROS bag to read (``None``: detect): the keywords of
#: :func:`graphcal.recording.bag.read.read_bag`, the CLI's bag flags by the same names.
BagOptions = BagRequest


@dataclass(frozen=True)
class ImportedLog:
    """An imported recording: the validated drive log and how it was made.

    Attributes:
        log: the drive log on the uniform grid (gaps masked).
        resampled: stream summaries, overlap and notes of the resampling.
        origin: ``(latitude, longitude)`` [deg] of the local frame, or ``None``.
        truth: ``theta_true`` [SI] of a synthetic recording (the manifest's ``truth``, or the
            ``truth.json`` that ``graphcal simulate --streams DIR --bag`` writes beside a
            bag), or ``None``.
        source: the manifest or bag.
        warnings: what a user must know before trusting a calibration from this log.
        truth_file: the file ``truth`` was read from, or ``None``.
    """

    log: DriveLog
    resampled: Resampled
    origin: tuple[float, float] | None
    truth: np.ndarray | None
    source: str
    warnings: tuple[str, ...] = ()
    truth_file: str | None = None

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
            "heading": "not logged (positions only)" if r.heading_derived else "logged",
            "ay_from_wheels": self.log.ay_from_wheels,
            "ay_from_heading": self.log.ay_from_heading,
            "ticks_per_revolution": None
            if self.log.tick_resolution is None
            else round(1.0 / self.log.tick_resolution),
            "wheel_noise_rev_per_step": self.log.wheel_noise,
            "warnings": list(self.warnings),
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
    from graphcal.recording.bag.reader import is_bag

    return is_bag(path)


def read_recording(source: str | os.PathLike[str], bag: BagOptions | None = None) -> Recording:
    """The streams of a manifest or a bag."""
    path = Path(source)
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        from graphcal.recording.manifest_recording import read_manifest

        return read_manifest(path)
    from graphcal.recording.bag.read import read_bag
    from graphcal.recording.bag.reader import is_bag

    if not path.exists():
        raise StreamError(f"{source}: no such file or directory; check the path")
    if not is_bag(path):
        raise StreamError(
            f"{source}: neither a streams manifest (.toml) nor a ROS bag (.bag, .mcap, a ROS 2 "
            "bag directory)"
        )
    return read_bag(path, bag)


def import_recording(
    source: str | os.PathLike[str],
    *,
    rate: float | None = None,
    max_gap: float | None = None,
    bag: BagOptions | None = None,
    nominal: np.ndarray = THETA_NOMINAL,
    min_distance: float = 0.0,
    reverses: bool = False,
) -> ImportedLog:
    """Import a streams manifest or a ROS bag into a validated :class:`DriveLog`.

    Args:
        source: a manifest (``.toml``), a ROS 1 bag, a ROS 2 bag directory or an MCAP file.
        rate: drive-log rate [Hz] (default: the manifest's ``rate``, else 40, or just
            faster than a pose stream faster than that:
            :func:`~graphcal.recording.stream_grid.grid_rate`).
        max_gap: shortest gap [s] that masks the log (default: the manifest's, else 0.5).
        bag: topics and joints of a bag (detected when not given).
        nominal: the vehicle's nominal theta (SI), for the plausibility checks.
        min_distance: shortest acceptable travelled distance [m].
        reverses: wheels turning backwards are motion (``VehicleProfile.reverses``: a robot
            spinning on the spot or reversing), kept; else (a car) masked as reversing.

    Raises:
        GraphcalError: one line naming the file, stream or column and how to fix it.
    """
    path = Path(source)
    truth, truth_file = None, None
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        from graphcal.recording.manifest.manifest import load_manifest
        from graphcal.recording.manifest_recording import read_manifest

        manifest = load_manifest(path)
        recording = read_manifest(manifest)
        if rate is None and "rate" in manifest.data:
            rate = manifest.rate
        max_gap = max_gap if max_gap is not None else manifest.max_gap
        truth = _read_truth(manifest)
        if truth is not None:
            truth_file = str(manifest.resolve(str(manifest.data["truth"])))
    else:
        recording = read_recording(path, bag)
        truth_file = _truth_beside_bag(path)
        truth = None if truth_file is None else _truth_of_bag(Path(truth_file))
    check_wheel_speeds(recording.wheels, float(nominal[0]))  # before a sample is averaged
    resampled = _resampled(recording, rate, max_gap, nominal, reverses)
    warnings = check_recording(resampled, recording, nominal)
    log = validate_frame(
        resampled.frame(),
        str(source),
        min_distance,
        marked=resampled.masked,
        marked_notes=resampled.mask_notes,
        nominal=nominal,
        origins=column_origins(resampled, recording),
        reverses=reverses,
    )
    if recording.wheels.resolution is not None:  # counts interpolated onto the grid
        log = dataclasses.replace(log, tick_resolution=recording.wheels.resolution)
    if not recording.wheels.cumulative:  # rates at their own times: their white noise
        wheels = recording.wheels
        noise = rate_wheel_noise(wheels.t, wheels.left, wheels.right, log.dt)
        log = dataclasses.replace(log, wheel_noise=noise)
    if resampled.ay_from_wheels:
        log = dataclasses.replace(log, ay_from_wheels=True)
    if resampled.ay_from_heading:
        log = dataclasses.replace(log, ay_from_heading=True)
    if recording.pose.origin is not None:  # geodetic fixes: a GNSS receiver's
        log = dataclasses.replace(log, pose_source="GNSS")
    return ImportedLog(
        log=log,
        resampled=resampled,
        origin=recording.pose.origin,
        truth=truth,
        source=str(source),
        warnings=tuple(warnings),
        truth_file=truth_file,
    )


def _resampled(
    recording: Recording,
    rate: float | None,
    max_gap: float | None,
    nominal: np.ndarray,
    reverses: bool,
) -> Resampled:
    """The recording on the uniform grid of ``rate`` [Hz] (``None``: 40 Hz, or just faster than
    a faster pose stream, said in a note) with gaps longer than ``max_gap`` [s] masked."""
    followed = None
    if rate is None:
        rate = grid_rate(recording.pose, wheels=recording.wheels)
        if rate > DEFAULT_RATE:
            followed = (
                f"drive log at {rate:g} Hz, just faster than the pose stream, so that each "
                f"pose sample has its own row (none given; --rate or the manifest's rate "
                f"chooses another)"
            )
        elif rate < DEFAULT_RATE:
            followed = (
                f"drive log at {rate:g} Hz, the wheels' own rate: each of their samples a row "
                f"(none given; --rate or the manifest's rate chooses another)"
            )
    resampled = resample(
        recording,
        rate=rate,
        max_gap=max_gap if max_gap is not None else MAX_GAP_S,
        wheel_circumference=float(nominal[0]),
        track_width=float(nominal[2]),
        reverses=reverses,
    )
    if followed is not None:
        resampled = dataclasses.replace(resampled, notes=(*resampled.notes, followed))
    return resampled


#: The truth file ``graphcal simulate --streams DIR`` writes in DIR, beside its bag.
SIMULATED_TRUTH = "truth.json"


def _truth_beside_bag(path: Path) -> str | None:
    """The ``truth.json`` of ``graphcal simulate --streams DIR --bag`` beside the bag at
    ``path`` (DIR/drive.bag, DIR/drive_ros2, DIR/drive_mcap, or a file inside the last two),
    if ``graphcal simulate`` wrote it; else ``None`` (a real bag)."""
    from graphcal.recording.bag.reader import is_bag

    folders = [path.resolve().parent]
    if path.is_file() and is_bag(path.resolve().parent):  # a file of a bag directory
        folders.append(path.resolve().parent.parent)
    for folder in folders:
        candidate = folder / SIMULATED_TRUTH
        if graphcal_json(candidate, made_by="simulate") is not None:
            return str(candidate)
    return None


def _truth_of_bag(path: Path) -> np.ndarray:
    """``theta_true`` of a simulated bag's ``truth.json``."""
    try:
        meta = json.loads(path.read_text())
        return np.array([float(meta["theta_true"][p]) for p in PARAMETER_NAMES])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise StreamError(
            f"{path}: not a JSON file with theta_true ({type(exc).__name__}); remove or "
            "rename it for a real recording"
        ) from None


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
