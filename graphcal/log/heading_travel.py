"""The heading against the direction of travel: its offset over the whole log
(:func:`heading_offset`, what an import judges its heading by) and the spans where it points
far from where the vehicle goes (:func:`heading_off_span`: a heading source that flips by
180° for a while, a second source with another zero), each named in one line before any
solve (:func:`check_heading_against_travel`).

A span is judged by dead reckoning: the wheels' distance along the heading (plus sideslip)
against the fixes' displacement over windows of travel, whose chords make the fixes' noise
small beside the angle between the two.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from graphcal.log.checks import ColumnOrigin, fail
from graphcal.log.drive_log import COLUMNS, DriveLog
from graphcal.log.track import COURSE_WINDOW_S
from graphcal.log.turns import fix_noise, grid_course

#: Mean heading offset from the direction of travel [rad] that warns (3°) or is refused (15°),
#: when the offset lies beyond it by more than :data:`HEADING_OFFSET_SIGMAS` of its own
#: standard error: the course of noisy fixes is noisy (a robot's 1 Hz fixes of 1.9 m, 1 m
#: apart, give a course of any direction; their median offset, −27°, refused a valid heading).
HEADING_OFFSET_WARNING = np.radians(3.0)
HEADING_OFFSET_ERROR = np.radians(15.0)
HEADING_OFFSET_SIGMAS = 3.0
#: Speed, in wheel revolutions per second (nominal c_e: 3 m/s for the paper's car, 0.4 m/s
#: for a robot's 0.27 m wheels), above which the direction of travel is compared with the
#: heading (forwards only: reversing travels against it).
HEADING_CHECK_REVS_PER_S = 1.5
#: Standard error of a normal sample's median over its mean's: sqrt(π/2).
MEDIAN_EFFICIENCY = float(np.sqrt(np.pi / 2.0))

#: A window of a span is as long in travel as this many of the fixes' noise σ (at least
#: :data:`SPAN_WINDOW_REVS` wheel revolutions): its chord's direction is then known to
#: about 1/50 rad from white noise.
SPAN_WINDOW_SIGMAS = 50.0
SPAN_WINDOW_REVS = 5.0
#: A span's heading points elsewhere when it differs from the log's own offset by more than
#: this [rad] in each of its windows, by more than :data:`SPAN_SCATTER_MULTIPLE` times the
#: robust scatter of the other windows' offsets (fixes that wander together turn short
#: chords), over at least :data:`SPAN_MIN_WINDOWS` consecutive windows.
SPAN_OFFSET_ERROR = np.radians(60.0)
SPAN_SCATTER_MULTIPLE = 5.0
SPAN_MIN_WINDOWS = 3


def heading_offset(
    c: Mapping[str, np.ndarray],
    usable: np.ndarray,
    dt: float,
    nominal,
    measured: np.ndarray | None = None,
) -> tuple[float, float] | None:
    """Median of heading + sideslip − direction of travel [rad] while moving forwards, and
    its standard error [rad] (the differences' circular spread over the independent courses
    among them: one per :data:`~graphcal.log.track.COURSE_WINDOW_S` chord, at most one per
    fix, ``measured`` ``(N, 2)`` marking the samples with one); or None."""
    track = grid_course(c, dt, nominal)
    speed = 0.5 * (c["n_rl"] + c["n_rr"]) * nominal[0] / dt
    forwards = (c["n_rl"] > 0) & (c["n_rr"] > 0)  # not a spin on the spot
    moving = usable & forwards & (speed > HEADING_CHECK_REVS_PER_S * nominal[0])
    if moving.sum() < 10.0 / dt:
        return None
    difference = np.angle(np.exp(1j * (c["psi"] + c["beta"] - track)))[moving]
    independent = moving.sum() * dt / COURSE_WINDOW_S
    if measured is not None:
        independent = min(independent, float(measured[moving, 0].sum()))
    resultant = float(np.abs(np.mean(np.exp(1j * difference))))
    if resultant <= 0.0 or independent < 1.0:
        return circular_median(difference), np.inf
    spread = np.sqrt(-2.0 * np.log(resultant))  # circular standard deviation
    return circular_median(difference), MEDIAN_EFFICIENCY * spread / np.sqrt(independent)


def circular_median(angles: np.ndarray) -> float:
    """The median [rad] of ``angles`` about their circular mean, wrapped to (−π, π]: angles
    around ±π (a heading off by 180°) split between the two ends, whose plain median falls
    anywhere between them."""
    centre = float(np.angle(np.mean(np.exp(1j * angles))))
    return float(
        np.angle(np.exp(1j * (centre + np.median(np.angle(np.exp(1j * (angles - centre)))))))
    )


def window_offsets(
    c: Mapping[str, np.ndarray],
    usable: np.ndarray,
    heading: np.ndarray,
    nominal,
    fixed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The heading's offset [rad] from the direction of travel in consecutive windows of
    travel (:data:`SPAN_WINDOW_SIGMAS` of the fixes' noise): the angle from the wheels'
    displacement along heading + sideslip (nominal c_e; the grid's heading, filled between
    sparse ones) to the fixes' displacement over the window, NaN where a window holds a
    sample not ``usable``, no measured ``heading`` or moves less than half its length; and
    the windows' first rows, with the last window's end."""
    ds = 0.5 * (c["n_rl"] + c["n_rr"]) * float(nominal[0])  # signed: reversing goes back
    travelled = np.concatenate([[0.0], np.cumsum(np.abs(ds))[:-1]])
    length = max(SPAN_WINDOW_REVS * float(nominal[0]), SPAN_WINDOW_SIGMAS * fix_noise(c, fixed))
    n = len(ds)
    marks = np.arange(0.0, max(travelled[-1], length), length)
    ends = np.unique(np.searchsorted(travelled, marks))
    ends = np.append(ends, n - 1) if ends[-1] < n - 1 else ends
    step = ds * np.exp(1j * (c["psi"] + c["beta"]))
    reckoned = np.add.reduceat(step, ends[:-1])[: len(ends) - 1]
    fixes = np.diff(c["px"][ends]) + 1j * np.diff(c["py"][ends])
    clean = np.add.reduceat((~usable).astype(int), ends[:-1])[: len(ends) - 1] == 0
    clean &= np.add.reduceat(heading.astype(int), ends[:-1])[: len(ends) - 1] > 0
    moved = np.abs(reckoned) >= 0.5 * length
    with np.errstate(invalid="ignore", divide="ignore"):
        offsets = np.angle(reckoned / fixes)
    return np.where(clean & moved & (fixes != 0), offsets, np.nan), ends


def heading_off_span(
    c: Mapping[str, np.ndarray],
    usable: np.ndarray,
    heading: np.ndarray,
    nominal,
    fixed: np.ndarray | None = None,
) -> tuple[int, int, float] | None:
    """The first span where the heading points elsewhere than the rest of the log says
    (:data:`SPAN_OFFSET_ERROR`, :data:`SPAN_SCATTER_MULTIPLE`, :data:`SPAN_MIN_WINDOWS`):
    its first and last rows and its offset from the log's own [rad]; ``None`` if there is
    none."""
    offsets, ends = window_offsets(c, usable, heading, nominal, fixed)
    valid = np.flatnonzero(np.isfinite(offsets))
    if len(valid) < 2 * SPAN_MIN_WINDOWS:
        return None
    usual = circular_median(offsets[valid])
    away = np.angle(np.exp(1j * (offsets[valid] - usual)))
    scatter = 1.4826 * float(np.median(np.abs(away)))
    off = np.abs(away) > max(SPAN_OFFSET_ERROR, SPAN_SCATTER_MULTIPLE * scatter)
    # runs of windows off the usual offset, among the judged windows
    starts = np.flatnonzero(off & ~np.concatenate([[False], off[:-1]]))
    for start in starts:
        stop = start
        while stop + 1 < len(off) and off[stop + 1]:
            stop += 1
        if stop - start + 1 >= SPAN_MIN_WINDOWS:
            mean = float(np.angle(np.mean(np.exp(1j * away[start : stop + 1]))))
            return int(ends[valid[start]]), int(ends[valid[stop] + 1]), mean
    return None


def check_heading_against_travel(
    log: DriveLog, nominal: np.ndarray, origins: Mapping[str, ColumnOrigin] | None = None
) -> None:
    """One line if the heading differs from the direction of travel by more than
    :data:`HEADING_OFFSET_ERROR` on average (a drive log's; an import judged its own
    streams), or points elsewhere over a span (:func:`heading_off_span`): the rows, the
    angle and what to check."""
    if int(log.heading_measured.sum()) < 2:
        return
    c = {name: getattr(log, name) for name in COLUMNS}
    usable = np.ones(len(log.t), bool)
    for flags in (log.masked, log.outlying):
        if flags is not None:
            usable &= ~flags
    judged = log.heading_measured & usable
    fixed = None if log.measured is None else log.measured[:, 0]
    dt = float(log.t[1] - log.t[0])
    found = heading_offset(c, judged, dt, nominal, log.measured) if origins is None else None
    if found is not None:
        offset, sigma = found
        if abs(offset) - HEADING_OFFSET_SIGMAS * sigma > HEADING_OFFSET_ERROR:
            shown = np.degrees(offset) if np.degrees(offset) > -179.5 else 180.0  # (−180, 180]
            what = (
                f"the heading differs from the direction of travel (px, py) by "
                f"{shown:+.0f}° on average"
            )
            fix = (
                "check the heading's zero and convention (psi is counter-clockwise from the "
                "x axis; a compass heading, clockwise from north, becomes pi/2 minus it; an "
                "IMU's yaw has an arbitrary zero) or leave it out (psi empty: positions only)"
            )
            raise fail(log.source, "psi", None, what, fix, origins)
    span = heading_off_span(c, usable, log.heading_measured, nominal, fixed)
    if span is None:
        return
    first, last, angle = span
    what = (
        f"from t = {log.t[first]:.1f} s to {log.t[last]:.1f} s the heading points "
        f"{np.degrees(angle):+.0f}° away from the direction of travel (px, py), against the "
        "rest of the log"
    )
    fix = (
        "check the heading's source over that span (a flipped antenna baseline, a second "
        "source with another zero), or mark the span in a 'masked' column"
    )
    raise fail(log.source, "psi", first, what, fix, origins)
