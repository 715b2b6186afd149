"""The wheel stream's speeds checked sample by sample, before the resampling averages a bad
sample into its neighbours (issue 35).

A single corrupt wheel line (a CAN frame at 999 km/h, a speed typed in another unit) shares
its grid interval with the good samples around it: on the drive log's grid it is diluted
below any plausible-speed limit but still turns the heading by tens of degrees, and the
check that notices names drive-log times. Checked on the stream itself, the message names
the file, the column or signal and the line (a candump log's line) in the stream's time.
"""

from __future__ import annotations

import numpy as np

from graphcal.recording.streams import StreamError, WheelStream, provenance_of

#: Smallest jump [m/s] of one sample away from both its neighbours, and back, that no wheel
#: makes (54 km/h in one sample interval and back): a corrupt sample.
MAX_SPIKE_SPEED = 15.0

_SIDES = (("rear_left", "rear-left", "left"), ("rear_right", "rear-right", "right"))


def wheel_speeds(stream: WheelStream, circumference: float) -> dict[str, np.ndarray]:
    """Each rear wheel's speed [m/s] at each sample of ``stream`` with the nominal
    ``circumference`` [m]; a cumulative stream's over the interval up to the sample (the
    first sample: 0)."""
    speeds = {}
    for _, _, side in _SIDES:
        values = np.asarray(getattr(stream, side), dtype=float)
        if stream.cumulative:
            rate = np.diff(values) / np.diff(stream.t)
            values = np.concatenate([[0.0], rate])
        speeds[side] = values * circumference
    return speeds


def check_wheel_speeds(stream: WheelStream, circumference: float) -> None:
    """Refuse, in one line naming the stream's file, column and line, a sample of a speed
    stream that leaves both neighbours by over :data:`MAX_SPIKE_SPEED` (with the nominal
    ``circumference`` [m]) and comes back. Speeds wrong throughout (a unit, a circumference)
    are left to the checks against the GNSS track, which name the key to change; a
    cumulative stream's bad count to the drive log's checks."""
    provenance = provenance_of(stream)
    speeds = wheel_speeds(stream, circumference)
    for key, name, side in _SIDES:
        v = speeds[side]
        if stream.cumulative or len(v) < 3:
            continue
        before, after = v[1:-1] - v[:-2], v[1:-1] - v[2:]
        spike = (np.minimum(np.abs(before), np.abs(after)) > MAX_SPIKE_SPEED) & (
            np.sign(before) == np.sign(after)
        )
        if spike.any():
            k = int(np.flatnonzero(spike)[0]) + 1
            raise StreamError(
                f"{provenance.at((key,), k)}: implausible {name} wheel speed at t = "
                f"{stream.t[k]:.3f} s: {v[k]:.4g} m/s between "
                f"{v[k - 1]:.4g} and {v[k + 1]:.4g} m/s at the samples before and after (with "
                f"c_e = {circumference:g} m; no wheel jumps by over {MAX_SPIKE_SPEED:g} m/s and "
                f"back in one sample): a corrupt sample; remove that {provenance.unit}"
            )
