"""Turns of the import's grid in windows of :data:`TURN_WINDOW_S`: the direction of travel,
the signed turn of a signal per window, and whether two signals turn the same way; and
:func:`turning`, which finds the one of the wheels, the track and the heading that turns
against the other two (mirrored tracks, headings and wheels), and :func:`check_turning`,
which says so in a recording's terms."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from graphcal.data.import_keys import convention_key, pose_names, stream_advice
from graphcal.data.resampling import Resampled
from graphcal.data.streams import Recording, StreamError, provenance_of
from graphcal.data.track import COURSE_MIN_REVS, course

#: Window [s] over which the pose's and the wheels' turning are compared.
TURN_WINDOW_S = 2.0
#: Yaw [rad] in such a window for it to count as a turn, and turns needed for a verdict.
TURN_MIN_YAW = 0.1
TURN_MIN_COUNT = 5
#: Share of turns in which two signals must agree; below it they turn opposite ways.
TURN_MIN_AGREEMENT = 0.25


def grid_course(c: dict, dt: float, nominal) -> np.ndarray:
    """The grid track's direction of travel (:func:`~graphcal.data.track.course`), defined
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


def turning(columns: dict[str, np.ndarray], usable: np.ndarray, nominal, heading: bool) -> Turning:
    """The :class:`Turning` of the grid's drive-log ``columns`` (``t``, ``px``, ``py``,
    ``psi`` [rad], ``n_rl``, ``n_rr`` [rev]) over the ``usable`` samples, in windows of
    :data:`TURN_WINDOW_S`: the wheels' yaw with the nominal theta ``nominal``, the track's
    course and, if a ``heading`` was logged, ``psi``."""
    c = columns
    dt = float(c["t"][1] - c["t"][0])
    window = max(1, round(TURN_WINDOW_S / dt))
    wheel_yaw = np.concatenate(
        [[0.0], np.cumsum((c["n_rr"][:-1] - c["n_rl"][:-1]) * nominal[0] / nominal[2])]
    )
    wheels = turn_directions(wheel_yaw, usable, window)
    track = turn_directions(grid_course(c, dt, nominal), usable, window)
    if not heading:
        return Turning(turn_agreement(wheels, track), None, None)
    psi = turn_directions(c["psi"], usable, window)
    return Turning(
        turn_agreement(wheels, track), turn_agreement(psi, track), turn_agreement(wheels, psi)
    )


def check_turning(resampled: Resampled, recording: Recording, nominal: np.ndarray) -> None:
    """One line if the GNSS track, the heading and the wheels do not turn the same way.

    A mirrored track (latitude/longitude or x/y swapped), a heading in the other convention
    (compass declared ENU) or swapped wheels (rear_left/rear_right) all show as turns in
    opposite directions (:meth:`Turning.opposite`).
    """
    pose = recording.pose
    turns = turning(resampled.columns, ~resampled.masked, nominal, pose.heading is not None)
    found = turns.opposite()
    if found is None:
        return
    signal, share = found
    if signal == "wheels":
        raise StreamError(
            f"{recording.wheels.source}: the wheels turn opposite to the GNSS track and the "
            f"heading in {share:.0%} of the turns; rear_left and rear_right are swapped"
        )
    if signal == "heading":
        raise StreamError(
            f"{pose.source}: the heading turns opposite to the GNSS track and the wheels in "
            f"{share:.0%} of the turns; "
            + stream_advice(
                provenance_of(pose),
                "heading",
                f"check {convention_key(pose)} (compass: 0 = north, clockwise; enu: 0 = east, "
                "counter-clockwise)",
            )
        )
    names = pose_names(pose.origin is not None)
    cause = f"{names} swapped" + (
        "" if turns.heading_track is not None else " or the wheels swapped"
    )
    cause = stream_advice(provenance_of(pose), "mirrored", cause)
    raise StreamError(
        f"{pose.source}: the GNSS track turns opposite to the wheels in "
        f"{share:.0%} of the turns, a mirrored track: {cause}; exchange them"
    )
