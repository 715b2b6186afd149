"""Whether the heading, the IMU's yaw rate and its lateral acceleration are in the units the
user declared: each compared with the GNSS track in its clear turns (:func:`check_units`)."""

from __future__ import annotations

import numpy as np

from graphcal.log.turns import (
    TURN_MIN_COUNT,
    TrackTurns,
    lateral_acceleration_scale,
    looks_like_g,
    track_turns,
)
from graphcal.model import THETA_NOMINAL
from graphcal.recording.column_origins import sample_before
from graphcal.recording.import_keys import key_name, set_key, stream_advice
from graphcal.recording.imu.mounting import mounted_fix
from graphcal.recording.resampling import Resampled
from graphcal.recording.stream_grid import interval_means
from graphcal.recording.streams import Provenance, Recording, StreamError, provenance_of

#: A heading or IMU yaw rate turning more than this many times as much as the GNSS track
#: (or less than its inverse) is in the wrong unit (degrees for radians is 57.3x).
ANGLE_SCALE_LIMIT = 8.0
#: The same for the IMU's lateral acceleration against speed × the track's yaw rate (an
#: acceleration in g is 1/9.81 of it).
ACCELERATION_SCALE_LIMIT = 3.0


def _span(
    provenance: Provenance, t: np.ndarray, grid: np.ndarray, turns: TrackTurns, k: int
) -> str:
    """``from line 2301 to line 2381``: the stream's samples at window ``k``'s ends."""
    a, b = turns.ends[k], turns.ends[k + 1]
    first, last = sample_before(t, grid[a]), sample_before(t, grid[b])
    return f"from {provenance.line(first)} to {provenance.line(last)}"


def _unit_advice(field, key: str, ratio: float, limit: float, units: tuple[str, str]) -> str:
    """``set heading_unit = "deg"`` when the declared unit is the other of ``units`` (radians
    first, degrees second) and the ratio says so; else which key to check."""
    declared = None if field is None else field.declares(key)
    radians, degrees = units
    if declared == radians and ratio > limit:
        return f"it is apparently in {degrees}: {set_key(field, key, degrees)}"
    if declared == degrees and ratio < 1.0 / limit:
        return f"it is apparently in {radians}: {set_key(field, key, radians)}"
    if declared is not None:
        return f'check {key_name(field, key)} (now "{declared}"; {radians} or {degrees})'
    return f"it must be in {radians} (REP 103)"


#: Manifest key and its units, per quantity whose turns are compared with the track's.
_ANGLE_UNIT_KEYS = {
    "heading": ("heading_unit", ("rad", "deg")),
    "yaw_rate": ("yaw_rate_unit", ("rad/s", "deg/s")),
}


def _check_angle_scale(angle, quantity: str, stream, times, turns, usable, grid) -> None:
    """One line if ``angle`` [rad as declared: the heading, or the yaw rate's integral] turns
    far more or less than the GNSS track in its clear turns whose size the wheels confirm
    (a unit mistake)."""
    turns = turns.sized_as_the_wheels()
    turned = turns.turns_of(angle)
    found = turns.scale(turned)
    if found is None or 1 / ANGLE_SCALE_LIMIT <= found[0] <= ANGLE_SCALE_LIMIT:
        return
    ratio, k = found
    where = provenance_of(stream)
    key, units = _ANGLE_UNIT_KEYS[quantity]
    if mounted_fix(where.fields.get(quantity)):  # a mounted IMU's angular_velocity
        key = "angular_velocity_unit"
    advice = _unit_advice(where.fields.get(quantity), key, ratio, ANGLE_SCALE_LIMIT, units)
    advice = stream_advice(where, quantity, advice)
    raise StreamError(
        f"{where.at((quantity,))}: the {quantity.replace('_', ' ')} turns {ratio:.3g}x as much "
        f"as the GNSS track in its turns (e.g. {_span(where, times, grid, turns, k)}: "
        f"{turned[k]:.3g} rad as declared where the track turns "
        f"{turns.track[k]:.3g} rad); {advice}"
    )


def check_units(
    resampled: Resampled, recording: Recording, nominal: np.ndarray = THETA_NOMINAL
) -> None:
    """One line if the heading, the IMU's yaw rate or its lateral acceleration is in another
    unit than the manifest declares, in the stream's own terms (its file, column, manifest
    key and lines, and the key to change).

    Each is compared with the GNSS track in its clear turns
    (:func:`~graphcal.log.turns.track_turns`: a course over chords long beside the fixes'
    noise; ``nominal``: the vehicle's theta): the heading's turn and the yaw rate's integral
    with the track's turn (degrees declared radians turn 57x as much), the lateral acceleration with
    speed × the track's yaw rate (an acceleration in g is 1/9.81 of it).
    """
    fixed = None if resampled.measured is None else resampled.measured[:, 0]
    turns = track_turns(resampled.columns, resampled.masked, nominal, fixed)
    if turns.turning.sum() < TURN_MIN_COUNT:
        return
    c = resampled.columns
    dt = float(c["t"][1] - c["t"][0])
    grid = c["t"] + resampled.overlap[0]
    usable = ~resampled.masked
    pose, imu = recording.pose, recording.imu
    reference = None  # the turns of a yaw that passed its check: the lateral acceleration's
    if pose.heading is not None:
        _check_angle_scale(c["psi"], "heading", pose, pose.t, turns, usable, grid)
        reference = turns.turns_of(c["psi"])
    if imu is None:
        return
    where = provenance_of(imu)
    if imu.yaw_rate is not None:
        rate = interval_means(imu.t, imu.yaw_rate, grid)
        yaw = np.concatenate([[0.0], np.cumsum(rate[:-1] * dt)])
        _check_angle_scale(yaw, "yaw_rate", imu, imu.t, turns, usable, grid)
        reference = turns.turns_of(yaw)
    if imu.lateral_acceleration is not None:
        mean = interval_means(imu.t, imu.lateral_acceleration, grid)
        found = lateral_acceleration_scale(mean, turns, dt, reference)
        if found is not None and not (
            1 / ACCELERATION_SCALE_LIMIT <= found[0] <= ACCELERATION_SCALE_LIMIT
        ):
            ratio, k, logged, expected = found
            advice = (
                "it is apparently in g: multiply the column by 9.81"
                if looks_like_g(ratio)
                else "give it in m/s², positive to the left"
            )
            raise StreamError(
                f"{where.at(('lateral_acceleration',))}: the lateral acceleration is "
                f"{ratio:.3g}x the speed × yaw rate of the GNSS track in its turns (e.g. "
                f"{_span(where, imu.t, grid, turns, k)}: {logged:.3g} m/s² where "
                f"the track's is {expected:.3g} m/s²); {advice}"
            )
