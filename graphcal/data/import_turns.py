"""Turns of the import's grid in windows of :data:`TURN_WINDOW_S`: the direction of travel,
the signed turn of a signal per window, and whether two signals turn the same way; and
:func:`check_turning`, which finds mirrored tracks, headings and wheels by them."""

from __future__ import annotations

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
    wheels = turn_directions(wheel_yaw, usable, window)
    track = turn_directions(grid_course(c, dt, nominal), usable, window)
    wheels_track = turn_agreement(wheels, track)
    pose = recording.pose
    heading = None
    if pose.heading is not None:
        heading = turn_agreement(turn_directions(c["psi"], usable, window), track)
    wheels_heading = (
        turn_agreement(wheels, turn_directions(c["psi"], usable, window))
        if pose.heading is not None
        else None
    )

    def opposite(value: float | None) -> bool:
        return value is not None and value < TURN_MIN_AGREEMENT

    def agree(value: float | None) -> bool:
        return value is not None and value >= 1 - TURN_MIN_AGREEMENT

    names = pose_names(pose.origin is not None)
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
            + stream_advice(
                provenance_of(pose),
                "heading",
                f"check {convention_key(pose)} (compass: 0 = north, clockwise; enu: 0 = east, "
                "counter-clockwise)",
            )
        )
    if opposite(wheels_track) and (heading is None or agree(wheels_heading)):
        cause = f"{names} swapped" + ("" if heading is not None else " or the wheels swapped")
        cause = stream_advice(provenance_of(pose), "mirrored", cause)
        raise StreamError(
            f"{pose.source}: the GNSS track turns opposite to the wheels in "
            f"{1 - wheels_track:.0%} of the turns, a mirrored track: {cause}; exchange them"
        )
