"""Whether the wheels, the track and the heading of an import turn the same way
(:func:`check_turning`): the one that turns against the other two
(:func:`graphcal.log.turns.turning`: mirrored tracks, headings and wheels), said in the
recording's terms."""

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
    opposite directions (:meth:`~graphcal.log.turns.Turning.opposite`).
    """
    pose = recording.pose
    fixed = None if resampled.measured is None else resampled.measured[:, 0]
    heading = pose.heading is not None
    turns = turning(resampled.columns, ~resampled.masked, nominal, heading, fixed)
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
