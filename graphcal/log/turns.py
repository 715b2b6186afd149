"""Turns of a drive log's grid in windows of :data:`TURN_WINDOW_S`: the direction of travel,
the signed turn of a signal per window, whether two signals turn the same way
(:func:`turning`: the one of the wheels, the track and the heading that turns against the
other two), the track's clear turns (:func:`track_turns`) and how a lateral acceleration
compares with speed × yaw rate in them. Both an import (:mod:`graphcal.recording.import_turns`,
:mod:`graphcal.recording.import_units`) and a drive-log CSV's checks
(:mod:`graphcal.log.turn_checks`) judge their signals with these."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from graphcal.log.track import COURSE_HALF_REVS, COURSE_MIN_REVS, chord_ends, course
from graphcal.model import THETA_NOMINAL

#: Window [s] over which the pose's and the wheels' turning are compared.
TURN_WINDOW_S = 2.0
#: Yaw [rad] in such a window for it to count as a turn, and turns needed for a verdict.
TURN_MIN_YAW = 0.1
TURN_MIN_COUNT = 5
#: Share of turns in which two signals must agree; below it they turn opposite ways.
TURN_MIN_AGREEMENT = 0.25


def grid_course(c: dict, dt: float, nominal) -> np.ndarray:
    """The grid track's direction of travel (:func:`~graphcal.log.track.course`), defined
    where its 1 s chord spans half a wheel revolution (1 m for the paper's car)."""
    return course(c["px"], c["py"], dt, min_distance=COURSE_MIN_REVS * float(nominal[0]))


def turn_directions(yaw: np.ndarray, usable: np.ndarray, window: int) -> np.ndarray:
    """Signed yaw [rad] over consecutive windows; NaN where a window holds masked samples."""
    ends = np.arange(0, len(yaw), window)
    turns = np.diff(yaw[ends])
    clean = np.add.reduceat((~usable).astype(int), ends)[: len(turns)] == 0
    return np.where(clean, turns, np.nan)


def turn_agreement(a: np.ndarray, b: np.ndarray) -> float | None:
    """Share of windows turning clearly in both signals where they turn the same way."""
    both = (np.abs(a) > TURN_MIN_YAW) & (np.abs(b) > TURN_MIN_YAW)
    if both.sum() < TURN_MIN_COUNT:
        return None
    return float((np.sign(a[both]) == np.sign(b[both])).mean())


@dataclass(frozen=True)
class Turning:
    """How the wheels, the track (the positions' direction of travel) and the heading turn
    against each other: the share of the clear turns in which each pair turns the same way
    (:func:`turn_agreement`; ``None``: too few turns, or no heading logged)."""

    wheels_track: float | None
    heading_track: float | None
    wheels_heading: float | None

    def opposite(self) -> tuple[str, float] | None:
        """The signal that turns against the other two and in what share of the turns:
        ``("wheels", s)`` (the wheels swapped), ``("heading", s)`` (the heading's sign or
        convention) or ``("track", s)`` (a mirrored track: x/y or latitude/longitude
        swapped; without a heading, or the wheels swapped); ``None`` if nothing does."""
        if _opposite(self.wheels_track) and _agree(self.heading_track):
            return "wheels", 1 - self.wheels_track
        if _opposite(self.heading_track) and _agree(self.wheels_track):
            return "heading", 1 - self.heading_track
        if _opposite(self.wheels_track) and (
            self.heading_track is None or _agree(self.wheels_heading)
        ):
            return "track", 1 - self.wheels_track
        return None


def _opposite(value: float | None) -> bool:
    return value is not None and value < TURN_MIN_AGREEMENT


def _agree(value: float | None) -> bool:
    return value is not None and value >= 1 - TURN_MIN_AGREEMENT


def turning(
    columns: dict[str, np.ndarray],
    usable: np.ndarray,
    nominal,
    heading: bool,
    fixed: np.ndarray | None = None,
) -> Turning:
    """The :class:`Turning` of the grid's drive-log ``columns`` (``t``, ``px``, ``py``,
    ``psi`` [rad], ``n_rl``, ``n_rr`` [rev]) over the ``usable`` samples, in windows of
    :data:`TURN_WINDOW_S`: the wheels' yaw with the nominal theta ``nominal``, the track's
    course (:func:`track_directions`; ``fixed``: the rows that hold a fix, ``None``: all)
    and, if a ``heading`` was logged, ``psi``."""
    c = columns
    dt = float(c["t"][1] - c["t"][0])
    window = max(1, round(TURN_WINDOW_S / dt))
    wheel_yaw = np.concatenate(
        [[0.0], np.cumsum((c["n_rr"][:-1] - c["n_rl"][:-1]) * nominal[0] / nominal[2])]
    )
    wheels = turn_directions(wheel_yaw, usable, window)
    track = track_directions(c, usable, window, nominal, fixed)
    if not heading:
        return Turning(turn_agreement(wheels, track), None, None)
    psi = turn_directions(c["psi"], usable, window)
    return Turning(
        turn_agreement(wheels, track), turn_agreement(psi, track), turn_agreement(wheels, psi)
    )


def track_directions(
    columns: dict[str, np.ndarray],
    usable: np.ndarray,
    window: int,
    nominal,
    fixed: np.ndarray | None = None,
) -> np.ndarray:
    """The track's signed turn [rad] over consecutive windows of ``window`` rows, 0 where it
    is within its own noise (NaN where masked): the course is a chord along the wheels'
    travel of :data:`TRACK_HALF_CHORD_SIGMAS` times the fixes' noise (:func:`fix_noise`)
    on each side, at least :data:`~graphcal.log.track.COURSE_HALF_REVS` wheel revolutions,
    and a window's turn counts beyond :data:`TRACK_TURN_SIGMAS` of that course's noise.
    Over a 1 s chord, a slow robot's 10 Hz fixes of 1 m turned both ways at random, and 4
    of 5 such "turns" against the wheels read as a mirrored track (campaign seed 29's shape
    155, refused). Windows whose courses come from chords that bend back on themselves
    (shorter than :data:`STRAIGHT_CHORD_SHARE` of the travel along them) are NaN: a 90 m
    chord of a skid-steer robot's 1.8 m fixes in a yard pointed anywhere (seed 30's shape
    8, refused)."""
    c = columns
    heading, travelled, sigma, half = _noise_proof_course(c, nominal, fixed)
    turns = turn_directions(heading, usable, window)
    # A chord that bends back on itself (a loop in a yard, within ±half) points anywhere:
    # only windows whose two courses come from nearly straight chords are judged.
    n = len(travelled)
    behind, ahead = chord_ends(travelled, half)
    chord = np.hypot(c["px"][ahead] - c["px"][behind], c["py"][ahead] - c["py"][behind])
    straight = chord >= STRAIGHT_CHORD_SHARE * (travelled[ahead] - travelled[behind])
    ends = np.arange(0, n, window)[: len(turns) + 1]
    turns = np.where(straight[ends[:-1]] & straight[ends[1:]], turns, np.nan)
    clear = max(TURN_MIN_YAW, TRACK_TURN_SIGMAS * sigma / half)
    return np.where(np.isnan(turns) | (np.abs(turns) > clear), turns, 0.0)


#: A course's chord counts as straight where it is at least this share of the wheels' travel
#: along it (a turn of up to about 2 rad within it); a chord that bends further is not judged.
STRAIGHT_CHORD_SHARE = 0.8


#: Standard gravity [m/s²], and how far (relative) the ratio × it may be from 1 for an
#: acceleration to be in g.
STANDARD_GRAVITY = 9.80665
G_RATIO_TOLERANCE = 0.3
#: Shortest chord of a window whose turn counts (the course of a slower one is noise), in
#: wheel revolutions (nominal c_e: 10 m for the paper's car).
TURN_MIN_CHORD_REVS = 5.0
#: Half the chord [multiples of the fixes' own noise σ per axis] over which the track's
#: course is taken for its turns, at least :data:`~graphcal.log.track.COURSE_HALF_REVS`
#: wheel revolutions: a course error of √2σ / (2 · 25σ) = 0.03 rad at each end, whatever the
#: fixes' rate (20 Hz fixes of 1 m noise 1 s apart turn by ±0.15 rad on their own).
TRACK_HALF_CHORD_SIGMAS = 25.0
#: A window's turn counts as a turn of the track only beyond this many of the standard
#: errors its course's noise gives it (σ / half chord, or the robust scatter of the track's
#: turns where the wheels turn less than :data:`STRAIGHT_WHEEL_YAW` [rad], if larger), and
#: beyond :data:`TURN_MIN_YAW`; and the wheels (nominal θ) must turn the same way, by at
#: least :data:`TURN_MIN_YAW` / :data:`WHEEL_TURN_SLACK`.
TRACK_TURN_SIGMAS = 5.0
STRAIGHT_WHEEL_YAW = 0.05
WHEEL_TURN_SLACK = 4.0


@dataclass(frozen=True)
class TrackTurns:
    """The GNSS track's clear turns in consecutive windows of the grid, each as long in
    travel as the chord over which the course is taken (so that the courses at a window's
    two ends share no fix)."""

    ends: np.ndarray  # first grid row of each window, and the last window's end
    track: np.ndarray  # the track's turn [rad] in each window (NaN where masked)
    chords: np.ndarray  # [m]
    turning: np.ndarray  # windows that turn clearly while moving, the wheels too
    usable: np.ndarray  # grid rows not masked
    wheels: np.ndarray  # the wheels' turn [rad] in each window (nominal θ)
    wheel_ay: np.ndarray  # mean of the wheels' speed × yaw rate [m/s²] in each window
    track_turning: np.ndarray  # windows in which the track turns clearly, whatever the wheels

    def turns_of(self, yaw: np.ndarray) -> np.ndarray:
        """The turn [rad] of another signal's ``yaw`` in each window (its values at the
        window's ends: a heading's noise is small beside a clear turn, an integrated yaw
        rate has none), NaN where masked."""
        return _window_turns(yaw, self.usable, self.ends)

    def sized_as_the_wheels(self) -> TrackTurns:
        """These turns, only those whose size the wheels (nominal θ) confirm within a factor
        :data:`WHEEL_TURN_SLACK`: what an angle's unit is judged on. A course over short
        chords of a slow robot's noisy fixes can wrap by about a turn: ±5–6.7 rad where
        the wheels turned 0.03–0.55 rad refused a right heading in degrees as "0.0157x the
        track" (campaign seed 44's shape 101, 50 Hz fixes sharing 1.8 m over 8 s)."""
        with np.errstate(invalid="ignore"):
            sized = np.abs(self.track) < WHEEL_TURN_SLACK * np.abs(self.wheels)
        return dataclasses.replace(self, turning=self.turning & sized)

    def scale(self, turns: np.ndarray) -> tuple[float, int] | None:
        """Median of |turns| / |the track's turns| over the clear turns, and the window of
        the sharpest one; ``None`` if there are too few turns."""
        if self.turning.sum() < TURN_MIN_COUNT:
            return None
        ratio = np.abs(turns[self.turning]) / np.abs(self.track[self.turning])
        sharpest = int(np.flatnonzero(self.turning)[np.argmax(np.abs(self.track[self.turning]))])
        return float(np.median(ratio)), sharpest


def _window_turns(yaw: np.ndarray, usable: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Signed change of ``yaw`` over the windows between ``ends``; NaN where one holds
    masked samples."""
    turns = np.diff(yaw[ends])
    clean = np.add.reduceat((~usable).astype(int), ends[:-1]) == 0
    return np.where(clean, turns, np.nan)


def _noise_proof_course(
    c: dict[str, np.ndarray], nominal, fixed: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The track's course [rad] over a chord along the wheels' travel of
    :data:`TRACK_HALF_CHORD_SIGMAS` times the fixes' noise on each side (at least
    :data:`~graphcal.log.track.COURSE_HALF_REVS` revolutions), with the travel [m] at each
    row, the fixes' noise σ [m] and the half chord [m]."""
    dt = float(c["t"][1] - c["t"][0])
    travelled = np.concatenate(
        [[0.0], np.cumsum(np.abs(0.5 * (c["n_rl"] + c["n_rr"]))[:-1] * nominal[0])]
    )
    sigma = fix_noise(c, fixed)
    half = max(COURSE_HALF_REVS * float(nominal[0]), TRACK_HALF_CHORD_SIGMAS * sigma)
    heading = course(
        c["px"], c["py"], dt, travelled, min_distance=COURSE_MIN_REVS * float(nominal[0]),
        half_distance=half,
    )  # fmt: skip
    return heading, travelled, sigma, half


def fix_noise(columns: dict[str, np.ndarray], fixed: np.ndarray | None = None) -> float:
    """Robust σ [m] per axis of the fixes (rows ``fixed``; ``None``: every row) from their
    second differences (``6σ²`` each for white noise; the motion's share is small between
    fixes close together, and where they are far apart it only makes the estimate safe)."""
    rows = np.arange(len(columns["px"])) if fixed is None else np.flatnonzero(fixed)
    second = np.concatenate([np.diff(columns[k][rows], 2) for k in ("px", "py")])
    second = second[np.isfinite(second)]
    if not len(second):
        return 0.0
    return float(1.4826 * np.median(np.abs(second)) / np.sqrt(6.0))


def track_turns(
    columns: dict[str, np.ndarray],
    masked: np.ndarray,
    nominal=THETA_NOMINAL,
    fixed: np.ndarray | None = None,
) -> TrackTurns:
    """The clear turns of the track of the grid's drive-log ``columns`` (``t`` [s], ``px``,
    ``py`` [m], ``n_rl``, ``n_rr`` [rev]; ``fixed``: the rows that hold a fix, ``None``:
    all), leaving out windows with ``masked`` samples.

    The course is the direction of a chord along the wheels' travel (nominal c_e) of
    :data:`TRACK_HALF_CHORD_SIGMAS` times the fixes' noise (:func:`fix_noise`) on each side,
    so that noise cannot turn it; the windows are as long in travel as a chord, and one is a
    turn where the course turns by :data:`TRACK_TURN_SIGMAS` of its own noise and at least
    :data:`TURN_MIN_YAW`, over a chord of :data:`TURN_MIN_CHORD_REVS` of the nominal c_e."""
    c = columns
    dt = float(c["t"][1] - c["t"][0])
    heading, travelled, sigma, half = _noise_proof_course(c, nominal, fixed)
    n = len(travelled)
    marks = np.arange(0.0, max(travelled[-1], 2.0 * half), 2.0 * half)  # [0] when parked
    ends = np.unique(np.searchsorted(travelled, marks))
    ends = np.append(ends, n - 1) if ends[-1] < n - 1 else ends
    usable = ~masked
    track = _window_turns(heading, usable, ends)
    chords = np.hypot(np.diff(c["px"][ends]), np.diff(c["py"][ends]))
    least = TURN_MIN_CHORD_REVS * nominal[0]
    wheel_yaw = np.concatenate(
        [[0.0], np.cumsum((c["n_rr"] - c["n_rl"])[:-1] * nominal[0] / nominal[2])]
    )
    wheels = _window_turns(wheel_yaw, usable, ends)
    clear = max(TURN_MIN_YAW, TRACK_TURN_SIGMAS * sigma / half)
    # Where the wheels roll straight on, the course's turns are its own noise, correlated
    # noise included (which the fixes' second differences do not show).
    straight = np.isfinite(track) & (np.abs(wheels) < STRAIGHT_WHEEL_YAW) & (chords > least)
    if straight.sum() >= TURN_MIN_COUNT:
        scatter = np.abs(track[straight] - np.median(track[straight]))
        clear = max(clear, TRACK_TURN_SIGMAS * 1.4826 * float(np.median(scatter)))
    # A turn of the track is one of the wheels too (same way, at a nominal t_r within a
    # factor WHEEL_TURN_SLACK of the vehicle's).
    with np.errstate(invalid="ignore"):
        agree = (np.sign(wheels) == np.sign(track)) & (
            np.abs(wheels) > TURN_MIN_YAW / WHEEL_TURN_SLACK
        )
        track_turning = np.isfinite(track) & (np.abs(track) > clear) & (chords > least)
    turning = track_turning & agree
    speed = 0.5 * (c["n_rl"] + c["n_rr"]) * nominal[0] / dt
    rate = (c["n_rr"] - c["n_rl"]) * nominal[0] / nominal[2] / dt
    wheel_ay = np.add.reduceat(speed * rate, ends[:-1]) / np.diff(np.append(ends[:-1], n))
    return TrackTurns(ends, track, chords, turning, usable, wheels, wheel_ay, track_turning)


def lateral_acceleration_scale(
    ay: np.ndarray, turns: TrackTurns, dt: float, reference: np.ndarray | None = None
) -> tuple[float, int, float, float] | None:
    """How many times speed × yaw rate of the track a lateral acceleration ``ay`` [m/s² as
    logged, one per grid sample of ``dt`` s] is in the track's clear ``turns``: the median
    ratio of their magnitudes, the window of the sharpest turn and, there, the mean ``ay``
    and the track's speed × yaw rate [m/s²]; ``None`` if there are too few turns.

    The track's speed × yaw rate in a window is the wheels' (nominal θ: speed at each
    sample times yaw rate, averaged) scaled by the track's turn over the wheels': a window
    as long as a chord many times the fixes' noise holds stops, spins and bends, whose
    speeds and turns the window's totals alone would mix up. ``reference``: each window's
    turn [rad] of a yaw that passed its own check (the IMU's yaw rate, or the heading), in
    place of the track's: fixes whose errors wander together over tens of seconds bend the
    track's course by more than a robot's turns (a differential robot's 50 Hz fixes of
    1.8 m over 26 s: its valid lateral acceleration 0.185× the track's, refused)."""
    means, expected = _window_lateral_accelerations(ay, turns, reference)
    found = turns.scale(means / np.where(expected == 0, 1.0, expected) * turns.track)
    if found is None:
        return None
    ratio, k = found
    return ratio, k, float(means[k]), float(expected[k])


def lateral_acceleration_agreement(ay: np.ndarray, turns: TrackTurns) -> float | None:
    """Share of the track's clear ``turns`` in which a lateral acceleration ``ay`` [m/s², one
    per grid sample] points the way speed × yaw rate of the track does (to the left in a
    left turn); ``None`` if there are too few turns (or ``ay`` is all 0)."""
    means, expected = _window_lateral_accelerations(ay, turns, None)
    judged = turns.turning & (expected != 0) & (means != 0)
    if judged.sum() < TURN_MIN_COUNT:
        return None
    return float(np.mean(np.sign(means[judged]) == np.sign(expected[judged])))


def _window_lateral_accelerations(
    ay: np.ndarray, turns: TrackTurns, reference: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``ay`` in each window of ``turns`` and the track's speed × yaw rate there
    [m/s²] (0 where undefined), as :func:`lateral_acceleration_scale` compares them."""
    sums = np.add.reduceat(ay, turns.ends[:-1])
    counts = np.diff(np.append(turns.ends[:-1], len(ay)))
    turned = turns.track if reference is None else reference
    with np.errstate(invalid="ignore", divide="ignore"):
        expected = turns.wheel_ay * np.nan_to_num(turned) / turns.wheels
    return sums / counts, np.where(np.isfinite(expected), expected, 0.0)


def looks_like_g(ratio: float) -> bool:
    """A lateral acceleration ``ratio`` times speed × yaw rate is apparently in g (1/9.81)."""
    return abs(ratio * STANDARD_GRAVITY - 1.0) < G_RATIO_TOLERANCE
