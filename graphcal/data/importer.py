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
    interval_means,
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
        warnings: what a user must know before trusting a calibration from this log.
    """

    log: DriveLog
    resampled: Resampled
    origin: tuple[float, float] | None
    truth: np.ndarray | None
    source: str
    warnings: tuple[str, ...] = ()

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
            "ticks_per_revolution": None
            if self.log.tick_resolution is None
            else round(1.0 / self.log.tick_resolution),
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
        track_width=float(nominal[2]),
    )
    warnings = check_recording(resampled, recording, nominal)
    log = validate_frame(
        resampled.frame(),
        str(source),
        min_distance,
        marked=resampled.masked,
        marked_notes=resampled.mask_notes,
        nominal=nominal,
    )
    if recording.wheels.resolution is not None:  # counts interpolated onto the grid
        log = dataclasses.replace(log, tick_resolution=recording.wheels.resolution)
    if resampled.ay_from_wheels:
        log = dataclasses.replace(log, ay_from_wheels=True)
    return ImportedLog(
        log=log,
        resampled=resampled,
        origin=recording.pose.origin,
        truth=truth,
        source=str(source),
        warnings=tuple(warnings),
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


def check_recording(resampled: Resampled, recording: Recording, nominal: np.ndarray) -> list[str]:
    """Check the streams against each other; raise :class:`StreamError` (one line) for what is
    certainly wrong, return warnings for what makes a calibration doubtful.

    In order: the wheels' distance against the GNSS track's (a wrong speed unit,
    circumference or tick count), the direction of turns (:func:`check_turning`), the
    heading against the direction of travel (a constant offset), the IMU's signs and how
    much of the streams overlap. (A slow GNSS needs no warning: each fix enters at its own
    time, and the σ reported says what the fixes determine.)
    """
    c = resampled.columns
    dt = float(c["t"][1] - c["t"][0])
    usable = ~resampled.masked
    _check_wheel_scale(c, usable, dt, recording, nominal)
    check_turning(resampled, recording, nominal)
    warnings = []
    offset = _heading_offset(c, usable, dt, float(nominal[0]))
    if offset is not None and recording.pose.heading is not None:
        where = recording.pose.source
        if abs(offset) > HEADING_OFFSET_ERROR:
            raise StreamError(
                f"{where}: the heading differs from the direction of travel by "
                f"{np.degrees(offset):+.0f}° on average; check heading_convention and the "
                "heading's zero (an IMU's yaw has an arbitrary one), or leave the heading out "
                "to use the GNSS course"
            )
        if abs(offset) > HEADING_OFFSET_WARNING:
            warnings.append(
                f"the heading differs from the direction of travel by {np.degrees(offset):+.1f}° "
                "on average (more than a sideslip explains): a mounting offset biases t_r and d"
            )
    _check_imu_signs(c, usable, dt, resampled, recording)
    longest = max(s.end - s.start for s in resampled.streams)
    covered = resampled.overlap[1] - resampled.overlap[0]
    if covered < MIN_OVERLAP_OF_LONGEST * longest:
        warnings.append(
            f"the streams overlap for {covered:.0f} s of the {longest:.0f} s the longest covers; "
            "the rest is left out (check the clocks)"
        )
    return warnings


#: Accepted range of the wheels' distance (nominal c_e) over the GNSS track's.
WHEEL_SCALE_RANGE = (0.8, 1.25)
#: Mean heading offset from the direction of travel [rad] that warns (3°) or is refused (15°).
HEADING_OFFSET_WARNING = np.radians(3.0)
HEADING_OFFSET_ERROR = np.radians(15.0)
#: Share of the longest stream the overlap should cover.
MIN_OVERLAP_OF_LONGEST = 0.5
#: Speed [m/s] above which the direction of travel is compared with the heading.
HEADING_CHECK_SPEED = 3.0


def _check_wheel_scale(c: dict, usable: np.ndarray, dt: float, recording, nominal) -> None:
    window = max(1, round(TURN_WINDOW_S / dt))
    wheel = np.concatenate([[0.0], np.cumsum(0.5 * (c["n_rl"] + c["n_rr"])[:-1] * nominal[0])])
    ends = np.arange(0, len(wheel), window)
    rolled = np.diff(wheel[ends])
    chords = np.hypot(np.diff(c["px"][ends]), np.diff(c["py"][ends]))
    clean = np.add.reduceat((~usable).astype(int), ends)[: len(rolled)] == 0
    moving = clean & (rolled > 5.0) & (chords > 5.0)
    if chords[moving].sum() < 200.0:
        return
    ratio = rolled[moving].sum() / chords[moving].sum()
    low, high = WHEEL_SCALE_RANGE
    if not low <= ratio <= high:
        raise StreamError(
            f"{recording.wheels.source}: the wheels travel {ratio:.3g}x the distance of the "
            f"GNSS track (with the nominal c_e = {nominal[0]:g} m); check [wheels] kind, "
            "speed_unit, circumference or ticks_per_revolution, the time units, and the "
            "vehicle's c_e (--vehicle)"
        )


def _heading_offset(c: dict, usable: np.ndarray, dt: float, circumference: float) -> float | None:
    """Median of heading + sideslip − direction of travel [rad] while moving, or None."""
    track = course(c["px"], c["py"], dt)
    speed = 0.5 * (c["n_rl"] + c["n_rr"]) * circumference / dt
    moving = usable & (speed > HEADING_CHECK_SPEED)
    if moving.sum() < 10.0 / dt:
        return None
    difference = np.angle(np.exp(1j * (c["psi"] + c["beta"] - track)))[moving]
    return float(np.median(difference))


def _check_imu_signs(c: dict, usable: np.ndarray, dt: float, resampled, recording) -> None:
    """One line if the IMU's lateral acceleration or yaw rate turns against the GNSS track."""
    imu = recording.imu
    if imu is None:
        return
    window = max(1, round(TURN_WINDOW_S / dt))
    track = _turn_directions(course(c["px"], c["py"], dt), usable, window)
    grid = c["t"] + resampled.overlap[0]  # the streams' time base
    for name, signal, hint in (
        ("lateral acceleration", imu.lateral_acceleration, "positive to the left"),
        ("yaw rate", imu.yaw_rate, "positive counter-clockwise"),
    ):
        if signal is None:
            continue
        values = interval_means(imu.t, signal, grid)
        integral = np.concatenate([[0.0], np.cumsum(values[:-1] * dt)])
        agreement = _agreement(_turn_directions(integral, usable, window), track)
        if agreement is not None and agreement < TURN_MIN_AGREEMENT:
            raise StreamError(
                f"{imu.source}: the IMU's {name} has the opposite sign to the turns of the "
                f"GNSS track in {1 - agreement:.0%} of them; it must be {hint} (ROS REP 103: "
                "x forward, y left, z up): negate the column or fix the IMU's frame"
            )


def _pose_names(geodetic: bool) -> str:
    return "latitude and longitude" if geodetic else "x and y"


def sidecar_of(csv_path: str | os.PathLike[str]) -> Path:
    """The ``<stem>.json`` sidecar beside a drive-log CSV (as a synthetic drive's)."""
    path = Path(csv_path)
    return path.with_name(f"{path.stem}.json")


def source_files(source: str | os.PathLike[str]) -> set[Path]:
    """Every file a recording is read from (resolved): the manifest and the files it names,
    or the bag and the files of its directory."""
    path = Path(source)
    files = {path}
    if path.suffix.lower() in MANIFEST_SUFFIXES and path.is_file():
        from graphcal.data.manifest import load_manifest

        try:
            manifest = load_manifest(path)
        except StreamError:
            return {path.resolve()}
        for table in (manifest.pose, manifest.wheels, manifest.imu):
            if table and isinstance(table.get("file"), str):
                files.add(manifest.resolve(table["file"]))
        if isinstance(manifest.data.get("truth"), str):
            files.add(manifest.resolve(manifest.data["truth"]))
        if manifest.bag is not None:
            path = manifest.bag
            files.add(path)
    if path.is_dir():
        files.update(path.iterdir())
    return {f.resolve() for f in files}


def check_import_output(source: str | os.PathLike[str], out: str | os.PathLike[str]) -> None:
    """One line if ``out`` (or its sidecar) is a directory, a JSON name, or a file the
    recording is read from; checked before the import."""
    out = Path(out)
    if out.is_dir():
        raise StreamError(f"--out {out}: is a directory; give the drive-log CSV's path")
    if out.suffix.lower() == ".json":
        raise StreamError(
            f"--out {out}: the drive log is a CSV and its sidecar is <name>.json; give a .csv path"
        )
    protected = source_files(source)
    for path in (out, sidecar_of(out)):
        if path.resolve() in protected:
            raise StreamError(
                f"--out {out}: would overwrite {path}, a file of the recording; choose another path"
            )


def write_import(imported: ImportedLog, csv_path: str | os.PathLike[str]) -> list[Path]:
    """Write the drive-log CSV and its ``<stem>.json`` sidecar (each atomically; the CSV is
    removed again if the sidecar cannot be written, so that nothing is half-written)."""
    csv_path = Path(csv_path)
    sidecar = sidecar_of(csv_path)
    write_drive_log(imported.log, csv_path)
    try:
        atomic_write_text(sidecar, json.dumps(imported.sidecar(), indent=2) + "\n")
    except BaseException:
        csv_path.unlink(missing_ok=True)
        raise
    return [csv_path, sidecar]
