"""A recording's streams resampled onto the uniform grid of a drive log.

A recording holds a pose stream (GNSS or a fused pose), a rear-wheel stream and optionally
an IMU stream, all with time in seconds on one time base but sampled at their own instants.
Every reader (:mod:`graphcal.recording.manifest` for CSV streams, :mod:`graphcal.recording.bag`
for ROS bags) converts its units into the SI quantities of these classes, so that
:func:`resample` does one job: put them on the drive log's grid ``t_k = t_0 + k / rate``.

* Wheel rotation per interval is **integrated**, never sampled: a cumulative angle is
  interpolated at the grid times and differenced; a rotation rate is first integrated with
  the trapezoid rule.
* **Each fix once, at its own time**: a pose sample is written in the first grid row at or
  after it, with its own time (``t_fix``) when it falls between rows; rows without one leave
  the position (and a heading not logged there) empty. Nothing is interpolated into a
  measurement and no heading is derived as one: a stream without a heading gives positions
  only (:mod:`graphcal.log.drive_log`, sparse measurements). Where two fixes fall in one
  grid interval (a pose stream faster than the grid) the later one is kept, with a note.
* The columns of :attr:`Resampled.columns` are the *track* at every row (positions
  interpolated, the heading on the circle or the GNSS course minus the sideslip): the
  import's cross-checks of the streams read it; :meth:`Resampled.frame` is the drive log.
* The sideslip, an input of the model, is interpolated onto the grid.
* Lateral acceleration and yaw rate are the IMU's means over each interval; without an IMU,
  lateral acceleration is speed × yaw rate (speed from the wheels, yaw rate from the logged
  heading, else from the wheels with the nominal c_e and t_r).
* A gap in any stream longer than :func:`gap_threshold` masks the grid samples around it.
* Wheels turning backwards are motion for a vehicle that reverses (a robot's spins and
  reversing: ``VehicleProfile.reverses``), else masked as reversing and set to 0.
* Without a given rate the grid runs at 40 Hz, or just faster than a faster pose stream
  (:func:`grid_rate`), so that no fix is left out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from graphcal.log.consistency import runs
from graphcal.log.track import COURSE_MIN_REVS, course
from graphcal.model import wheel_lateral_acceleration
from graphcal.recording.stream_grid import (
    MAX_GAP_S,
    RATE_RANGE,
    YAW_RATE_WINDOW_S,
    StreamSummary,
    fixes_on_grid,
    grid_mask,
    interval_means,
    lag_at_rows,
    overlap,
    rate_over_window,
    summarize,
    wheel_rotations,
)
from graphcal.recording.streams import ImuStream, PoseStream, Recording, StreamError

#: Most negative wheel rotation [rev] per grid interval accepted before a sample counts as
#: reversing (masked, its rotation set to 0) on a vehicle that does not reverse (a car).
REVERSING_TOLERANCE = 0.005
#: What a recording whose wheels turn backwards is told to set when it is a robot's.
REVERSES_HINT = (
    "a car's model covers forward driving only; if the vehicle is a robot that spins on the "
    "spot or reverses, set reverses = true in its vehicle profile (--vehicle)"
)


@dataclass(frozen=True)
class Resampled:
    """A recording on the uniform grid: drive-log columns, masked samples and what was done."""

    columns: dict[str, np.ndarray]
    masked: np.ndarray
    mask_notes: tuple[str, ...]
    streams: tuple[StreamSummary, ...]
    overlap: tuple[float, float]
    notes: tuple[str, ...] = field(default=())
    heading_derived: bool = False
    ay_from_wheels: bool = False
    ay_from_heading: bool = False
    measured: np.ndarray | None = None
    fix_lag: np.ndarray | None = None

    def frame(self):
        """The drive log as a DataFrame: the track's position and heading only where measured
        (else empty), each fix's own time in ``t_fix`` where it falls between rows."""
        from graphcal.log.drive_log import measurement_frame

        return measurement_frame(self.columns, self.measured, self.fix_lag)


def resample(
    recording: Recording,
    rate: float = 40.0,
    max_gap: float = MAX_GAP_S,
    wheel_circumference: float = 2.0,
    track_width: float = 1.55,
    *,
    reverses: bool = False,
) -> Resampled:
    """Put a recording on the uniform grid of a drive log (see the module docstring).

    Args:
        recording: the streams, SI units, one time base.
        rate: samples per second of the drive log [Hz] (the paper: 40).
        max_gap: shortest gap [s] in a stream that masks the grid around it (a slower stream
            uses :data:`GAP_INTERVALS` of its own interval if longer).
        wheel_circumference: [m] the vehicle's nominal c_e: for the speed in speed × yaw rate
            when no IMU lateral acceleration is logged, and the travel of a derived course.
        track_width: [m] the vehicle's nominal t_r: for the wheels' yaw rate when neither an
            IMU nor a heading is logged.
        reverses: wheels turning backwards are motion (``VehicleProfile.reverses``: a robot
            spinning on the spot or reversing), kept as they are; else (a car) samples where a
            wheel turns backwards are masked as reversing and their rotations set to 0.

    Raises:
        StreamError: streams whose times do not overlap (enough).
    """
    grid = _grid(recording, rate, max_gap)
    notes: list[str] = [
        f"time of the drive log: seconds since t = {grid.start:.6f} s of the streams"
    ]
    pose = recording.pose
    px = np.interp(grid.t, pose.t, pose.x)
    py = np.interp(grid.t, pose.t, pose.y)
    beta = _sideslip(pose, grid, notes)
    n_rl, n_rr = wheel_rotations(recording.wheels, grid.t)
    reversing = np.zeros(grid.count, dtype=bool)
    if not reverses:
        reversing = (n_rl < -REVERSING_TOLERANCE) | (n_rr < -REVERSING_TOLERANCE)
        n_rl, n_rr = np.maximum(n_rl, 0.0), np.maximum(n_rr, 0.0)
    psi = _track_heading(pose, px, py, beta, grid, wheel_circumference, notes)
    fixes = _fixes(pose, grid, px, py, psi, notes)
    nominal = np.array([wheel_circumference, 0.0, track_width, 0.0])
    ay = _lateral_acceleration(recording.imu, pose, n_rl, n_rr, psi, grid, nominal, notes)
    masked, mask_notes = _mask(grid, reversing)
    imu = recording.imu
    columns = {
        "t": grid.since_start,
        **fixes.columns,
        "n_rl": n_rl,
        "n_rr": n_rr,
        "beta": beta,
        "ay": ay,
    }
    run = _runs(grid, notes)
    if run is not None:
        columns["run"] = run
    return Resampled(
        columns=columns,
        masked=masked,
        mask_notes=tuple(mask_notes),
        streams=tuple(grid.summaries),
        overlap=(grid.start, grid.end),
        notes=(*recording.notes, *notes),
        heading_derived=pose.heading is None,
        ay_from_wheels=(imu is None or imu.lateral_acceleration is None)
        and (imu is None or imu.yaw_rate is None)
        and pose.heading is None,
        ay_from_heading=(imu is None or imu.lateral_acceleration is None)
        and (imu is None or imu.yaw_rate is None)
        and pose.heading is not None,
        measured=fixes.measured,
        fix_lag=fixes.lag,
    )


@dataclass(frozen=True)
class _Grid:
    """The drive log's grid: its times ``t`` [s] on the streams' clock and ``since_start``
    (0 at the overlap's start), ``count`` rows ``dt`` [s] apart, the span ``start`` …
    ``end`` all streams cover, and the streams' summaries."""

    t: np.ndarray
    since_start: np.ndarray
    dt: float
    count: int
    start: float
    end: float
    summaries: list[StreamSummary]


def _grid(recording: Recording, rate: float, max_gap: float) -> _Grid:
    """The grid at ``rate`` [Hz] over the span all streams cover; one line if the rate is
    out of :data:`RATE_RANGE` or the span holds fewer than 3 rows."""
    low, high = RATE_RANGE
    if not (np.isfinite(rate) and low <= rate <= high):
        raise StreamError(
            f"{recording.source}: rate {rate:g} Hz is outside {low:g} … {high:g} Hz; the paper's "
            "drive log runs at 40 Hz"
        )
    summaries = [summarize(role, s, max_gap) for role, s in recording.streams().items()]
    start, end = overlap(summaries, recording.source)
    dt = 1.0 / rate
    count = int(np.floor((end - start) * rate + 1e-9)) + 1
    if count < 3:
        raise StreamError(
            f"{recording.source}: the streams overlap for only {end - start:.3f} s, fewer than "
            f"3 samples at {rate:g} Hz"
        )
    since_start = dt * np.arange(count)  # the drive log's time: 0 at the overlap's start
    return _Grid(start + since_start, since_start, dt, count, start, end, summaries)


def _sideslip(pose: PoseStream, grid: _Grid, notes: list[str]) -> np.ndarray:
    """The sideslip [rad] on the grid, interpolated; 0 (with a note) when not logged."""
    if pose.sideslip is not None:
        return np.interp(grid.t, pose.t, pose.sideslip)
    notes.append(
        "sideslip not logged: set to 0 — right for a pose at the rear axle; a pose at the "
        "centre of gravity moves off its heading in bends, which biases t_r and d "
        "(docs/import.md)"
    )
    return np.zeros(grid.count)


def _track_heading(
    pose: PoseStream,
    px: np.ndarray,
    py: np.ndarray,
    beta: np.ndarray,
    grid: _Grid,
    wheel_circumference: float,
    notes: list[str],
) -> np.ndarray:
    """The track's heading [rad] at every row: the logged one interpolated (unwrapped), else
    the course of the track minus the sideslip (with a note)."""
    if pose.heading is not None:
        return np.interp(grid.t, pose.t, np.unwrap(pose.heading))
    psi = course(px, py, grid.dt, min_distance=COURSE_MIN_REVS * wheel_circumference) - beta
    notes.append(
        "heading not logged: positions only are measured (each segment's start heading is "
        "estimated from its fixes)"
    )
    return psi


@dataclass(frozen=True)
class _Fixes:
    """The pose columns of the drive log (``px``, ``py``, ``psi``: each fix at its row, the
    track elsewhere), which rows measured them ``(N, 2)`` and each row's fix lag [s]."""

    columns: dict[str, np.ndarray]
    measured: np.ndarray
    lag: np.ndarray | None


def _fixes(
    pose: PoseStream,
    grid: _Grid,
    px: np.ndarray,
    py: np.ndarray,
    psi: np.ndarray,
    notes: list[str],
) -> _Fixes:
    """Each fix once, in the first row at or after it (:func:`fixes_on_grid`); a note on
    the fixes left out (two in one grid interval)."""
    kept, rows, lag, dropped = fixes_on_grid(pose.t, grid.t)
    measured = np.zeros((grid.count, 2), dtype=bool)
    measured[rows, 0] = True
    measured[rows, 1] = pose.heading is not None
    fix_px, fix_py, fix_psi = px.copy(), py.copy(), psi.copy()
    fix_px[rows], fix_py[rows] = pose.x[kept], pose.y[kept]
    if pose.heading is not None:
        fix_psi[rows] = np.unwrap(pose.heading)[kept]
    if dropped > 0:
        notes.append(
            f"{dropped} pose sample(s) share a {grid.dt * 1e3:g} ms grid interval with a later "
            "one and are left out (a pose stream faster than the drive log: raise its rate)"
        )
    columns = {"px": fix_px, "py": fix_py, "psi": fix_psi}
    return _Fixes(columns, measured, lag_at_rows(lag, rows, grid.count))


def _lateral_acceleration(
    imu: ImuStream | None,
    pose: PoseStream,
    n_rl: np.ndarray,
    n_rr: np.ndarray,
    psi: np.ndarray,
    grid: _Grid,
    nominal: np.ndarray,
    notes: list[str],
) -> np.ndarray:
    """The lateral acceleration [m/s²] per row: the IMU's mean over each interval, else the
    wheels' speed × a yaw rate (the IMU's, the heading's, else the wheels', with a note),
    the wheels' rotations turned into distance and yaw with the ``nominal`` theta."""
    if imu is not None and imu.lateral_acceleration is not None:
        return interval_means(imu.t, imu.lateral_acceleration, grid.t)
    dt = grid.dt
    speed = 0.5 * (n_rl + n_rr) * nominal[0] / dt
    if imu is not None and imu.yaw_rate is not None:
        yaw_rate = interval_means(imu.t, imu.yaw_rate, grid.t)
        notes.append("lateral acceleration not logged: speed × the IMU's yaw rate")
    elif pose.heading is not None:
        yaw_rate = rate_over_window(psi, dt)
        notes.append(
            "lateral acceleration not logged: speed × yaw rate from the heading over "
            f"{YAW_RATE_WINDOW_S:g} s"
        )
    else:
        notes.append(
            "lateral acceleration not logged: speed × yaw rate of the wheels over "
            f"{YAW_RATE_WINDOW_S:g} s (nominal theta; derived again with the solved one)"
        )
        return wheel_lateral_acceleration(n_rl, n_rr, nominal, dt, YAW_RATE_WINDOW_S)
    return speed * yaw_rate


#: A wheel stream that stops for this long [s] or more starts a new run when it starts again.
RUN_GAP = 5.0


def _runs(grid: _Grid, notes: list[str]) -> np.ndarray | None:
    """The run of each grid row when the wheels' stream stops for :data:`RUN_GAP` or more
    and starts again (a recording of several runs, each with its clocks set apart: its own
    wheel time offset), with a note; ``None`` for one run. A shorter gap (a CAN dropout) is
    masked, within its run."""
    wheels = next(s for s in grid.summaries if s.role == "wheels")
    ends = [b for a, b in wheels.gaps if grid.start < b and a < grid.end and b - a >= RUN_GAP]
    if not ends:
        return None
    notes.append(
        f"the wheels' stream stops and starts again {len(ends)} time(s): {len(ends) + 1} runs, "
        "each with its own wheel time offset (column run)"
    )
    return np.searchsorted(np.asarray(ends), grid.t, side="right").astype(np.int64)


def _mask(grid: _Grid, reversing: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The rows to leave out, with a note per span: around each stream's gaps inside the
    grid, and where the wheels turn backwards (``reversing``)."""
    masked = np.zeros(grid.count, dtype=bool)
    mask_notes: list[str] = []
    start, end = grid.start, grid.end
    for summary in grid.summaries:
        gaps = [g for g in summary.gaps if g[1] > start and g[0] < end]
        gap_mask = grid_mask(grid.t, gaps)
        masked |= gap_mask
        for a, b in gaps:
            mask_notes.append(
                f"t = {a - start:.1f}–{b - start:.1f} s: gap of {b - a:.1f} s in the "
                f"{summary.role} stream ({summary.source})"
            )
    for i, (a, b) in enumerate(runs(reversing)):
        masked[a : b + 1] = True
        mask_notes.append(
            f"t = {grid.since_start[a]:.1f}–{grid.since_start[b]:.1f} s: wheels turning "
            "backwards (reversing), rotations set to 0" + ("" if i else f" ({REVERSES_HINT})")
        )
    return masked, mask_notes
