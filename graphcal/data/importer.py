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

from graphcal.data.bags import BagRequest
from graphcal.data.drive_log import DriveLog, write_drive_log
from graphcal.data.drive_log_checks import ColumnOrigin
from graphcal.data.drive_log_validation import validate_frame
from graphcal.data.imu_mounting import mounted_fix
from graphcal.data.manifest import SPEED_UNITS
from graphcal.data.resampling import Resampled, resample
from graphcal.data.stream_grid import (
    DEFAULT_RATE,
    FIX_TIME_TOLERANCE,
    MAX_GAP_S,
    grid_rate,
    interval_means,
)
from graphcal.data.streams import Provenance, Recording, StreamError, provenance_of
from graphcal.data.track import COURSE_MIN_REVS, course
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


#: Which topics, joints and fields of a ROS bag to read (``None``: detect): the keywords of
#: :func:`graphcal.data.bags.read_bag`, the CLI's bag flags by the same names.
BagOptions = BagRequest


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
    reverses: bool = False,
) -> ImportedLog:
    """Import a streams manifest or a ROS bag into a validated :class:`DriveLog`.

    Args:
        source: a manifest (``.toml``), a ROS 1 bag, a ROS 2 bag directory or an MCAP file.
        rate: drive-log rate [Hz] (default: the manifest's ``rate``, else 40, or just
            faster than a pose stream faster than that: :func:`~graphcal.data.streams.grid_rate`).
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
    truth = None
    if path.suffix.lower() in MANIFEST_SUFFIXES:
        from graphcal.data.manifest import load_manifest, read_manifest

        manifest = load_manifest(path)
        recording = read_manifest(manifest)
        if rate is None and "rate" in manifest.data:
            rate = manifest.rate
        max_gap = max_gap if max_gap is not None else manifest.max_gap
        truth = _read_truth(manifest)
    else:
        recording = read_recording(path, bag)
    followed = None
    if rate is None:
        rate = grid_rate(recording.pose)
        if rate != DEFAULT_RATE:
            followed = (
                f"drive log at {rate:g} Hz, just faster than the pose stream, so that each "
                f"pose sample has its own row (none given; --rate or the manifest's rate "
                f"chooses another)"
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
    track = _turn_directions(_course(c, dt, nominal), usable, window)
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
            f"{1 - heading:.0%} of the turns; "
            + _advice(
                provenance_of(pose),
                "heading",
                f"check {_convention_key(pose)} (compass: 0 = north, clockwise; enu: 0 = east, "
                "counter-clockwise)",
            )
        )
    if opposite(wheels_track) and (heading is None or agree(wheels_heading)):
        cause = f"{names} swapped" + ("" if heading is not None else " or the wheels swapped")
        cause = _advice(provenance_of(pose), "mirrored", cause)
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
    check_units(resampled, recording, nominal)
    check_turning(resampled, recording, nominal)
    warnings = []
    offset = _heading_offset(c, usable, dt, nominal)
    if offset is not None and recording.pose.heading is not None:
        where = provenance_of(recording.pose).at(("heading",))
        if abs(offset) > HEADING_OFFSET_ERROR:
            raise StreamError(
                f"{where}: the heading differs from the direction of travel by "
                f"{np.degrees(offset):+.0f}° on average; "
                + _advice(
                    provenance_of(recording.pose),
                    "heading",
                    f"check {_convention_key(recording.pose)} and the heading's zero (an IMU's "
                    "yaw has an arbitrary one), or leave the heading out to use the GNSS course",
                )
            )
        if abs(offset) > HEADING_OFFSET_WARNING:
            warnings.append(
                f"the heading differs from the direction of travel by {np.degrees(offset):+.1f}° "
                "on average (more than a sideslip explains): a mounting offset biases t_r and d"
            )
    _check_imu_signs(c, usable, dt, resampled, recording, nominal)
    longest = max(s.end - s.start for s in resampled.streams)
    covered = resampled.overlap[1] - resampled.overlap[0]
    if covered < MIN_OVERLAP_OF_LONGEST * longest:
        warnings.append(
            f"the streams overlap for {covered:.0f} s of the {longest:.0f} s the longest covers; "
            "the rest is left out (check the clocks)"
        )
    return warnings


#: Accepted range of the wheels' distance (nominal c_e) over the GNSS track's, and the
#: distance the comparison needs, in wheel revolutions (nominal c_e: 50 m for the paper's
#: car, 6.7 m for a robot's 0.27 m wheels), in windows of :data:`TURN_WINDOW_S` that each
#: travel :data:`SCALE_WINDOW_REVS` (5 m for the car) on the wheels and the track (as the
#: drive log's own check of positions against the wheels, which would otherwise speak of
#: drive-log columns).
WHEEL_SCALE_RANGE = (0.8, 1.25)
MIN_SCALE_REVS = 25.0
SCALE_WINDOW_REVS = 2.5
#: Where too few windows are long enough (a vehicle far smaller than the nominal one), the
#: whole log's wheel distance over its track [m, at least this long] must lie in this range:
#: wide, since stops and turns on the spot are in it too.
COARSE_SCALE_RANGE = (0.5, 2.0)
COARSE_SCALE_MIN_TRACK = 10.0
#: Mean heading offset from the direction of travel [rad] that warns (3°) or is refused (15°).
HEADING_OFFSET_WARNING = np.radians(3.0)
HEADING_OFFSET_ERROR = np.radians(15.0)
#: Share of the longest stream the overlap should cover.
MIN_OVERLAP_OF_LONGEST = 0.5
#: Speed, in wheel revolutions per second (nominal c_e: 3 m/s for the paper's car, 0.4 m/s
#: for a robot's 0.27 m wheels), above which the direction of travel is compared with the
#: heading (forwards only: reversing travels against it).
HEADING_CHECK_REVS_PER_S = 1.5


def _course(c: dict, dt: float, nominal) -> np.ndarray:
    """The grid track's direction of travel (:func:`~graphcal.data.track.course`), defined
    where its 1 s chord spans half a wheel revolution (1 m for the paper's car)."""
    return course(c["px"], c["py"], dt, min_distance=COURSE_MIN_REVS * float(nominal[0]))


def _check_wheel_scale(c: dict, usable: np.ndarray, dt: float, recording, nominal) -> None:
    window = max(1, round(TURN_WINDOW_S / dt))
    wheel = np.concatenate([[0.0], np.cumsum(0.5 * (c["n_rl"] + c["n_rr"])[:-1] * nominal[0])])
    ends = np.arange(0, len(wheel), window)
    rolled = np.abs(np.diff(wheel[ends]))  # net: a robot reversing rolls as far backwards
    chords = np.hypot(np.diff(c["px"][ends]), np.diff(c["py"][ends]))
    clean = np.add.reduceat((~usable).astype(int), ends)[: len(rolled)] == 0
    least = SCALE_WINDOW_REVS * nominal[0]
    moving = clean & (rolled > least) & (chords > least)
    low, high = WHEEL_SCALE_RANGE
    if chords[moving].sum() < MIN_SCALE_REVS * nominal[0]:
        if chords[clean].sum() < COARSE_SCALE_MIN_TRACK:
            return
        moving, (low, high) = clean, COARSE_SCALE_RANGE
    ratio = rolled[moving].sum() / chords[moving].sum()
    if not low <= ratio <= high:
        wheels = provenance_of(recording.wheels)
        raise StreamError(
            f"{wheels.at(('rear_left', 'rear_right'))}: the wheels travel {ratio:.3g}x the "
            f"distance of the GNSS track (with the nominal c_e = {nominal[0]:g} m); "
            f"{_speed_unit_hint(wheels, ratio)}"
        )


def _is_flag(field) -> bool:
    """Whether ``field`` was named by a command-line flag (a bag's field path, ``--rear-left``),
    not by a manifest key."""
    return field is not None and bool(field.key) and field.key.startswith("--")


def _key_name(field, key: str) -> str:
    """How the user names the unit key ``key`` of ``field``: ``[wheels] speed_unit`` (a
    manifest) or ``--speed-unit`` (a bag's field named on the command line)."""
    if _is_flag(field):
        return "--" + key.replace("_", "-")
    return f"{field.section} {key}" if field is not None and field.section else key


def _convention_key(pose) -> str:
    """``heading_convention``, or ``--heading-convention`` for a heading named by a flag."""
    field = provenance_of(pose).fields.get("heading")
    return "--heading-convention" if _is_flag(field) else "heading_convention"


def _set_key(field, key: str, value: str) -> str:
    """``set [wheels] speed_unit = "km/h"`` or ``pass --speed-unit km/h``."""
    if _is_flag(field):
        return f"pass {_key_name(field, key)} {value}"
    return f'set {_key_name(field, key)} = "{value}"'


def _speed_unit_hint(wheels: Provenance, ratio: float) -> str:
    """How to fix wheels that travel ``ratio`` times the GNSS track's distance: the speed
    unit that explains it, if one does, else every key that scales the wheels."""
    field = wheels.fields.get("rear_left")
    declared = None if field is None else field.declares("speed_unit")
    if declared is not None:
        for unit, factor in SPEED_UNITS.items():
            implied = SPEED_UNITS[declared] / factor  # the ratio if the column were in `unit`
            if unit != declared and abs(ratio / implied - 1.0) < 0.1:
                return (
                    f"the speeds are apparently in {unit}: {_set_key(field, 'speed_unit', unit)} "
                    f'(now "{declared}")'
                )
    scaled = {"circumference": "m", "ticks_per_revolution": ""}
    for key, unit in scaled.items():
        value = None if field is None else field.declares(key)
        if value is not None:  # the wheels' distance is inversely proportional to it
            others = "--wheel-kind, --speed-unit" if _is_flag(field) else "kind, speed_unit"
            return (
                f"check {_key_name(field, key)} ({float(value) * ratio:.4g}"
                f"{unit and ' ' + unit} would match the GNSS track with the nominal c_e), "
                f"{others}, the time units and the vehicle's c_e (--vehicle)"
            )
    kind = None if field is None else field.declares("kind")
    if wheels.unit == "message" and kind is not None:  # a bag's fields (or a vendor message)
        return f'check --wheel-kind (now "{kind}"), the fields and the vehicle\'s c_e (--vehicle)'
    if wheels.unit == "message":
        return (
            "check --wheel-kind (angle: positions [rad]; angular_speed: velocities [rad/s]), the "
            "joints and the vehicle's c_e (--vehicle)"
        )
    return (
        "check [wheels] kind, speed_unit, circumference (the ECU's) or ticks_per_revolution, "
        "the time units, and the vehicle's c_e (--vehicle)"
    )


def _heading_offset(c: dict, usable: np.ndarray, dt: float, nominal) -> float | None:
    """Median of heading + sideslip − direction of travel [rad] while moving forwards, or
    None."""
    track = _course(c, dt, nominal)
    speed = 0.5 * (c["n_rl"] + c["n_rr"]) * nominal[0] / dt
    forwards = (c["n_rl"] > 0) & (c["n_rr"] > 0)  # not a spin on the spot
    moving = usable & forwards & (speed > HEADING_CHECK_REVS_PER_S * nominal[0])
    if moving.sum() < 10.0 / dt:
        return None
    difference = np.angle(np.exp(1j * (c["psi"] + c["beta"] - track)))[moving]
    return float(np.median(difference))


def _check_imu_signs(
    c: dict, usable: np.ndarray, dt: float, resampled, recording, nominal=THETA_NOMINAL
) -> None:
    """One line if the IMU's lateral acceleration or yaw rate turns against the GNSS track."""
    imu = recording.imu
    if imu is None:
        return
    window = max(1, round(TURN_WINDOW_S / dt))
    track = _turn_directions(_course(c, dt, nominal), usable, window)
    grid = c["t"] + resampled.overlap[0]  # the streams' time base
    for quantity, signal, hint in (
        ("lateral_acceleration", imu.lateral_acceleration, "positive to the left"),
        ("yaw_rate", imu.yaw_rate, "positive counter-clockwise"),
    ):
        name = quantity.replace("_", " ")
        if signal is None:
            continue
        values = interval_means(imu.t, signal, grid)
        integral = np.concatenate([[0.0], np.cumsum(values[:-1] * dt)])
        agreement = _agreement(_turn_directions(integral, usable, window), track)
        if agreement is not None and agreement < TURN_MIN_AGREEMENT:
            fix = mounted_fix(provenance_of(imu).fields.get(quantity))
            raise StreamError(
                f"{provenance_of(imu).at((quantity,))}: the IMU's {name} has the opposite sign "
                f"to the turns of the GNSS track in {1 - agreement:.0%} of them; it must be "
                f"{hint} (ROS REP 103: x forward, y left, z up): "
                + (fix or "negate the column or fix the IMU's frame")
            )


#: A heading or IMU yaw rate turning more than this many times as much as the GNSS track
#: (or less than its inverse) is in the wrong unit (degrees for radians is 57.3x).
ANGLE_SCALE_LIMIT = 8.0
#: The same for the IMU's lateral acceleration against speed × the track's yaw rate (an
#: acceleration in g is 1/9.81 of it).
ACCELERATION_SCALE_LIMIT = 3.0
#: Shortest chord of a window whose turn counts (the course of a slower one is noise), in
#: wheel revolutions (nominal c_e: 10 m for the paper's car).
TURN_MIN_CHORD_REVS = 5.0


@dataclass(frozen=True)
class _Turns:
    """The GNSS track's clear turns in consecutive windows of the grid."""

    window: int
    ends: np.ndarray  # first grid row of each window, and the last window's end
    track: np.ndarray  # the track's turn [rad] in each window (NaN where masked)
    chords: np.ndarray  # [m]
    turning: np.ndarray  # windows that turn clearly while moving

    def scale(self, turns: np.ndarray) -> tuple[float, int] | None:
        """Median of |turns| / |the track's turns| over the clear turns, and the window of
        the sharpest one; ``None`` if there are too few turns."""
        if self.turning.sum() < TURN_MIN_COUNT:
            return None
        ratio = np.abs(turns[self.turning]) / np.abs(self.track[self.turning])
        sharpest = int(np.flatnonzero(self.turning)[np.argmax(np.abs(self.track[self.turning]))])
        return float(np.median(ratio)), sharpest


def _turns(resampled: Resampled, nominal=THETA_NOMINAL) -> _Turns:
    c = resampled.columns
    dt = float(c["t"][1] - c["t"][0])
    window = max(1, round(TURN_WINDOW_S / dt))
    ends = np.arange(0, len(c["t"]), window)
    track = _turn_directions(_course(c, dt, nominal), ~resampled.masked, window)
    chords = np.hypot(np.diff(c["px"][ends]), np.diff(c["py"][ends]))
    least = TURN_MIN_CHORD_REVS * nominal[0]
    turning = np.isfinite(track) & (np.abs(track) > TURN_MIN_YAW) & (chords > least)
    return _Turns(window, ends, track, chords, turning)


def _span(provenance: Provenance, t: np.ndarray, grid: np.ndarray, turns: _Turns, k: int) -> str:
    """``from line 2301 to line 2381``: the stream's samples at window ``k``'s ends."""
    a, b = turns.ends[k], turns.ends[k + 1]
    first, last = _sample_before(t, grid[a]), _sample_before(t, grid[b])
    return f"from {provenance.line(first)} to {provenance.line(last)}"


def _unit_advice(field, key: str, ratio: float, limit: float, units: tuple[str, str]) -> str:
    """``set heading_unit = "deg"`` when the declared unit is the other of ``units`` (radians
    first, degrees second) and the ratio says so; else which key to check."""
    declared = None if field is None else field.declares(key)
    radians, degrees = units
    if declared == radians and ratio > limit:
        return f"it is apparently in {degrees}: {_set_key(field, key, degrees)}"
    if declared == degrees and ratio < 1.0 / limit:
        return f"it is apparently in {radians}: {_set_key(field, key, radians)}"
    if declared is not None:
        return f'check {_key_name(field, key)} (now "{declared}"; {radians} or {degrees})'
    return f"it must be in {radians} (REP 103)"


#: Manifest key and its units, per quantity whose turns are compared with the track's.
_ANGLE_UNIT_KEYS = {
    "heading": ("heading_unit", ("rad", "deg")),
    "yaw_rate": ("yaw_rate_unit", ("rad/s", "deg/s")),
}


def _check_angle_scale(angle, quantity: str, stream, times, turns, usable, grid) -> None:
    """One line if ``angle`` [rad as declared: the heading, or the yaw rate's integral] turns
    far more or less than the GNSS track in its clear turns (a unit mistake)."""
    found = turns.scale(_turn_directions(angle, usable, turns.window))
    if found is None or 1 / ANGLE_SCALE_LIMIT <= found[0] <= ANGLE_SCALE_LIMIT:
        return
    ratio, k = found
    where = provenance_of(stream)
    key, units = _ANGLE_UNIT_KEYS[quantity]
    if mounted_fix(where.fields.get(quantity)):  # a mounted IMU's angular_velocity
        key = "angular_velocity_unit"
    advice = _unit_advice(where.fields.get(quantity), key, ratio, ANGLE_SCALE_LIMIT, units)
    advice = _advice(where, quantity, advice)
    raise StreamError(
        f"{where.at((quantity,))}: the {quantity.replace('_', ' ')} turns {ratio:.3g}x as much "
        f"as the GNSS track in its turns (e.g. {_span(where, times, grid, turns, k)}: "
        f"{_turn_of(angle, turns, k):.3g} rad as declared where the track turns "
        f"{turns.track[k]:.3g} rad); {advice}"
    )


def check_units(
    resampled: Resampled, recording: Recording, nominal: np.ndarray = THETA_NOMINAL
) -> None:
    """One line if the heading, the IMU's yaw rate or its lateral acceleration is in another
    unit than the manifest declares, in the stream's own terms (its file, column, manifest
    key and lines, and the key to change).

    Each is compared with the GNSS track in its clear turns (2 s windows turning more than
    0.1 rad over more than 5 wheel revolutions, 10 m for the paper's car; ``nominal``: the
    vehicle's theta): the heading's turn and the yaw rate's integral with the
    track's turn (degrees declared radians turn 57x as much), the lateral acceleration with
    speed × the track's yaw rate (an acceleration in g is 1/9.81 of it).
    """
    turns = _turns(resampled, nominal)
    if turns.turning.sum() < TURN_MIN_COUNT:
        return
    c = resampled.columns
    dt = float(c["t"][1] - c["t"][0])
    grid = c["t"] + resampled.overlap[0]
    usable = ~resampled.masked
    pose, imu = recording.pose, recording.imu
    if pose.heading is not None:
        _check_angle_scale(c["psi"], "heading", pose, pose.t, turns, usable, grid)
    if imu is None:
        return
    where = provenance_of(imu)
    if imu.yaw_rate is not None:
        rate = interval_means(imu.t, imu.yaw_rate, grid)
        yaw = np.concatenate([[0.0], np.cumsum(rate[:-1] * dt)])
        _check_angle_scale(yaw, "yaw_rate", imu, imu.t, turns, usable, grid)
    if imu.lateral_acceleration is not None:
        mean = interval_means(imu.t, imu.lateral_acceleration, grid)
        sums = np.add.reduceat(mean, turns.ends)[: len(turns.track)]
        counts = np.diff(np.append(turns.ends, len(mean)))[: len(turns.track)]
        seconds = turns.window * dt
        expected = turns.chords / seconds * np.nan_to_num(turns.track) / seconds
        found = turns.scale(sums / counts / np.where(expected == 0, 1.0, expected) * turns.track)
        if found is not None and not (
            1 / ACCELERATION_SCALE_LIMIT <= found[0] <= ACCELERATION_SCALE_LIMIT
        ):
            ratio, k = found
            in_g = abs(ratio * 9.80665 - 1.0) < 0.3
            advice = (
                "it is apparently in g: multiply the column by 9.81"
                if in_g
                else "give it in m/s², positive to the left"
            )
            raise StreamError(
                f"{where.at(('lateral_acceleration',))}: the lateral acceleration is "
                f"{ratio:.3g}x the speed × yaw rate of the GNSS track in its turns (e.g. "
                f"{_span(where, imu.t, grid, turns, k)}: {sums[k] / counts[k]:.3g} m/s² where "
                f"the track's is {expected[k]:.3g} m/s²); {advice}"
            )


def _turn_of(yaw: np.ndarray, turns: _Turns, k: int) -> float:
    return float(yaw[turns.ends[k + 1]] - yaw[turns.ends[k]])


def _sample_before(t: np.ndarray, time: float) -> int:
    """The last sample of a stream at or before ``time`` (the first if none is)."""
    return max(int(np.searchsorted(t, time + FIX_TIME_TOLERANCE, side="right")) - 1, 0)


def _sample_within(t: np.ndarray, lo: float, hi: float, values: np.ndarray | None) -> int:
    """The sample of a stream in ``[lo, hi]`` or next to it with the largest ``|values|``
    (the first one if ``values`` is None), else the last one before ``lo``."""
    # with the samples just outside: the trapezoid rule spreads each over its neighbours'
    a = max(int(np.searchsorted(t, lo - FIX_TIME_TOLERANCE, side="left")) - 1, 0)
    b = int(np.searchsorted(t, hi + FIX_TIME_TOLERANCE, side="right")) + 1
    if b <= a:
        return _sample_before(t, lo)
    if values is None:
        return a
    return a + int(np.argmax(np.abs(values[a:b])))


def column_origins(resampled: Resampled, recording: Recording) -> dict[str, ColumnOrigin]:
    """Where each drive-log column of an import came from (:class:`ColumnOrigin`), so that
    the drive log's checks name the user's file, column, manifest key and line, and the key
    to change; a derived column (``ay`` from speed × yaw rate) names every stream behind it."""
    grid = resampled.columns["t"] + resampled.overlap[0]
    last = len(grid) - 1
    pose, wheels, imu = recording.pose, recording.wheels, recording.imu
    at_pose, at_wheels = provenance_of(pose), provenance_of(wheels)
    csv = at_wheels.unit == "line"

    def at_fix(provenance: Provenance, quantities: tuple[str, ...], stream):
        def where(row: int | None) -> str:
            k = None if row is None else _sample_before(stream.t, grid[row])
            return provenance.at(quantities, k)

        return where

    def within(provenance: Provenance, quantities: tuple[str, ...], stream, values=None):
        def where(row: int | None) -> str:
            if row is None:
                return provenance.at(quantities)
            k = _sample_within(stream.t, grid[row], grid[min(row + 1, last)], values)
            return provenance.at(quantities, k)

        return where

    def joined(first, second):
        return lambda row: f"{first(row)}, times the speed of {second(row)}"

    position = ("latitude", "longitude") if pose.origin is not None else ("x", "y")
    section = next((f.section for f in at_pose.fields.values() if f.section), "[gnss]")
    position_fix = _advice(
        at_pose,
        "position",
        f"check {section} {' and '.join(position)}"
        + (" (degrees WGS-84)" if pose.origin is not None else " (metres, east and north)")
        if at_pose.unit == "line"
        else "check the pose topic (--pose-topic)",
    )
    heading_field = at_pose.fields.get("heading")
    heading_fix = _advice(
        at_pose,
        "heading",
        f"check {_key_name(heading_field, 'heading_unit')} (deg | rad) and "
        f"{_key_name(heading_field, 'heading_convention')} "
        "(enu | compass)"
        if heading_field is not None and heading_field.declares("heading_unit")
        else "check the pose's orientation (ENU, REP 103)",
    )
    wheel_fix = (
        "check [wheels] kind, speed_unit, circumference (the ECU's) or ticks_per_revolution, "
        "and the vehicle's c_e (--vehicle)"
        if csv
        else "check --wheel-kind, --speed-unit, --circumference or --ticks-per-revolution and "
        "the vehicle's c_e (--vehicle)"
        if _is_flag(at_wheels.fields.get("rear_left"))
        else "check --wheel-kind (angle or angular_speed) and the vehicle's c_e (--vehicle)"
    )
    both = ("rear_left", "rear_right")
    speeds = None if wheels.cumulative else np.abs(wheels.left) + np.abs(wheels.right)
    wheel_speed = within(at_wheels, both, wheels, speeds)
    origins = {
        "px": ColumnOrigin("position", at_fix(at_pose, position, pose), position_fix),
        "py": ColumnOrigin("position", at_fix(at_pose, position, pose), position_fix),
    }
    for column, side, signal in (
        ("n_rl", "rear_left", wheels.left),
        ("n_rr", "rear_right", wheels.right),
    ):
        values = None if wheels.cumulative else signal
        origins[column] = ColumnOrigin(
            f"{side.replace('_', '-')} wheel speed",
            within(at_wheels, (side,), wheels, values),
            wheel_fix,
        )
    if pose.heading is not None:
        origins["psi"] = ColumnOrigin("heading", at_fix(at_pose, ("heading",), pose), heading_fix)
    else:
        origins["psi"] = ColumnOrigin(
            "course of the GNSS track (no heading logged)",
            lambda row: f"{at_pose.at(position)} against {at_wheels.at(both)}",
            f"{position_fix}; {wheel_fix}",
        )
    if pose.sideslip is not None:
        field = at_pose.fields.get("sideslip")
        fix = (
            f"check {field.section} sideslip_unit (rad | deg)"
            if field is not None and field.declares("sideslip_unit")
            else "check the Odometry twist (body frame, REP 103)"
        )
        origins["beta"] = ColumnOrigin("sideslip", at_fix(at_pose, ("sideslip",), pose), fix)
    if imu is not None and imu.lateral_acceleration is not None:
        at_imu = provenance_of(imu)
        fix = (
            "it must be in m/s², positive to the left (a column in g: multiply it by 9.81); "
            "drop or fill a lone spike's line"
            if at_imu.unit == "line"
            else "linear_acceleration.y must be in m/s² (REP 103)"
        )
        mounted = mounted_fix(at_imu.fields.get("lateral_acceleration"))
        fix = f"{mounted}; drop or fill a lone spike's line" if mounted else fix
        where = within(at_imu, ("lateral_acceleration",), imu, imu.lateral_acceleration)
        origins["ay"] = ColumnOrigin("lateral acceleration", where, fix)
    elif imu is not None and imu.yaw_rate is not None:
        at_imu = provenance_of(imu)
        field = at_imu.fields.get("yaw_rate")
        fix = (
            f"check {_key_name(field, 'yaw_rate_unit')} (rad/s | deg/s)"
            if field is not None and field.declares("yaw_rate_unit")
            else mounted_fix(field) or "angular_velocity.z must be in rad/s (REP 103)"
        )
        origins["ay"] = ColumnOrigin(
            "lateral acceleration (speed × yaw rate, none logged)",
            joined(within(at_imu, ("yaw_rate",), imu, imu.yaw_rate), wheel_speed),
            f"{fix}; {wheel_fix}",
        )
    elif pose.heading is not None:
        origins["ay"] = ColumnOrigin(
            "lateral acceleration (the wheel speed × the heading's rate of turn; none is logged)",
            joined(at_fix(at_pose, ("heading",), pose), wheel_speed),
            f"{heading_fix}; {wheel_fix}",
        )
    else:
        origins["ay"] = ColumnOrigin(
            "lateral acceleration (from the two wheels' speeds, none logged)",
            wheel_speed,
            wheel_fix,
        )
    return origins


def _pose_names(geodetic: bool) -> str:
    return "latitude and longitude" if geodetic else "x and y"


def _advice(provenance: Provenance, topic: str, default: str) -> str:
    """``default``, or the stream's own advice on ``topic`` (``"position"``, ``"heading"``,
    ``"mirrored"``) where its reader gives one: an NMEA log's has no columns or units to
    check (:class:`graphcal.data.nmea.SentenceProvenance`)."""
    return getattr(provenance, "advice", {}).get(topic, default)


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
            for key in ("file", "nmea", "can", "dbc"):  # a CSV, an NMEA log, a CAN log + DBC
                if table and isinstance(table.get(key), str):
                    files.add(manifest.resolve(table[key]))
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
