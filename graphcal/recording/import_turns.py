"""Turns of the import's grid in windows of :data:`TURN_WINDOW_S`: the direction of travel,
the signed turn of a signal per window, and whether two signals turn the same way; and
:func:`turning`, which finds the one of the wheels, the track and the heading that turns
against the other two (mirrored tracks, headings and wheels), and :func:`check_turning`,
which says so in a recording's terms."""

from __future__ import annotations

import numpy as np

from graphcal.log.turns import turning
from graphcal.recording.import_keys import convention_key, pose_names, stream_advice
from graphcal.recording.resampling import Resampled
from graphcal.recording.streams import Recording, StreamError, provenance_of


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
