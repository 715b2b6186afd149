"""The streams of an import checked against each other (:func:`check_recording`): the
wheels' distance against the GNSS track's, the direction of turns, the units, the heading
against the direction of travel and the IMU's signs."""

from __future__ import annotations

import numpy as np

from graphcal.log.heading_travel import (
    HEADING_OFFSET_ERROR,
    HEADING_OFFSET_SIGMAS,
    HEADING_OFFSET_WARNING,
    heading_offset,
)
from graphcal.log.timing import coarse_wheel_lag
from graphcal.log.turn_checks import wheel_off_scale
from graphcal.log.turns import (
    TURN_MIN_AGREEMENT,
    TURN_WINDOW_S,
    track_directions,
    track_turns,
    turn_agreement,
    turn_directions,
)
from graphcal.model import THETA_NOMINAL
from graphcal.recording.import_keys import convention_key, is_flag, key_name, set_key, stream_advice
from graphcal.recording.import_turns import check_turning
from graphcal.recording.import_units import check_units
from graphcal.recording.imu.mounting import mounted_fix
from graphcal.recording.resampling import Resampled
from graphcal.recording.stream_grid import interval_means
from graphcal.recording.streams import Provenance, Recording, StreamError, provenance_of
from graphcal.recording.track_distance import wheel_track_ratio
from graphcal.recording.vocabulary import SPEED_UNITS


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
    _check_wheel_scale(c, usable, resampled, recording, nominal)
    _check_imu_clock(c, usable, dt, resampled, recording)
    check_units(resampled, recording, nominal)
    _check_one_wheel(c, usable, resampled, recording, nominal)
    check_turning(resampled, recording, nominal)
    warnings = []
    found = heading_offset(c, usable, dt, nominal, resampled.measured)
    if found is not None and recording.pose.heading is not None:
        offset, sigma = found
        beyond = abs(offset) - HEADING_OFFSET_SIGMAS * sigma  # certainly beyond this
        where = provenance_of(recording.pose).at(("heading",))
        if beyond > HEADING_OFFSET_ERROR:
            raise StreamError(
                f"{where}: the heading differs from the direction of travel by "
                f"{np.degrees(offset):+.0f}° on average; "
                + stream_advice(
                    provenance_of(recording.pose),
                    "heading",
                    f"check {convention_key(recording.pose)} and the heading's zero (an IMU's "
                    "yaw has an arbitrary one), or leave the heading out (then positions only)",
                )
            )
        if beyond > HEADING_OFFSET_WARNING:
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


#: Accepted range of the wheels' distance (nominal c_e) over the GNSS track's (as the drive
#: log's own check of positions against the wheels, which would otherwise speak of drive-log
#: columns), and the standard errors of the comparison by which a ratio must lie outside it
#: to be refused (a short, noisy recording tells little).
WHEEL_SCALE_RANGE = (0.8, 1.25)
WHEEL_SCALE_SIGMAS = 3.0
#: Share of the longest stream the overlap should cover.
MIN_OVERLAP_OF_LONGEST = 0.5


def _check_wheel_scale(
    c: dict, usable: np.ndarray, resampled: Resampled, recording, nominal
) -> None:
    """One line if the wheels (nominal c_e) travel far more or less than the GNSS track, by
    more than :data:`WHEEL_SCALE_SIGMAS` of the comparison's own uncertainty: straight
    windows' chords against their wheel distance, the fixes' noise fitted out
    (:func:`~graphcal.recording.track_distance.wheel_track_ratio`)."""
    fixed = np.ones(len(c["t"]), bool) if resampled.measured is None else resampled.measured[:, 0]
    found = wheel_track_ratio(c, fixed, usable, nominal)
    if found is None:
        return
    ratio, sigma, at_least = found
    # Judged on the fit's own scale, the slope a = 1 / ratio² (σ_a = 2 a σ): a σ of the
    # logarithm taken at the estimate shrinks with an inflated slope (a robot's 1 Hz fixes of
    # 1.9 m: a = 6.0 ± 2.1, "the wheels travel 0.407x" at 4σ of log, 2.1σ from a = 1.56).
    slope, slope_sigma = ratio**-2.0, 2.0 * ratio**-2.0 * sigma
    low, high = WHEEL_SCALE_RANGE
    short = -np.inf if at_least else slope - low**-2.0  # a lower bound shows no shortfall
    beyond = max(short, high**-2.0 - slope)
    if beyond > WHEEL_SCALE_SIGMAS * slope_sigma:
        wheels = provenance_of(recording.wheels)
        raise StreamError(
            f"{wheels.at(('rear_left', 'rear_right'))}: the wheels travel {ratio:.3g}x the "
            f"distance of the GNSS track (with the nominal c_e = {nominal[0]:g} m); "
            f"{_speed_unit_hint(wheels, ratio)}"
        )


def _check_one_wheel(c: dict, usable: np.ndarray, resampled: Resampled, recording, nominal) -> None:
    """One line if one rear wheel's scale is off against the other's and the GNSS track's
    (:func:`~graphcal.log.turn_checks.wheel_off_scale`), before the turns' directions would
    call such wheels swapped."""
    fixed = None if resampled.measured is None else resampled.measured[:, 0]
    found = wheel_off_scale(c, track_turns(c, ~usable, nominal, fixed), nominal)
    if found is None:
        return
    off, scales, count = found
    names = {"n_rl": "rear_left", "n_rr": "rear_right"}
    other = "n_rr" if off == "n_rl" else "n_rl"
    wheels = provenance_of(recording.wheels)
    raise StreamError(
        f"{wheels.at((names[off],))}: where the GNSS track runs straight, {names[off]} travels "
        f"{scales[off]:.2f}x its distance and {names[other]} {scales[other]:.2f}x (the nominal "
        f"c_e; median of {count} straight stretches): {names[off]}'s scale is off; check its "
        "column, unit, ticks per revolution or circumference"
    )


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
                    f"the speeds are apparently in {unit}: {set_key(field, 'speed_unit', unit)} "
                    f'(now "{declared}")'
                )
    scaled = {"circumference": "m", "ticks_per_revolution": ""}
    for key, unit in scaled.items():
        value = None if field is None else field.declares(key)
        if value is not None:  # the wheels' distance is inversely proportional to it
            others = "--wheel-kind, --speed-unit" if is_flag(field) else "kind, speed_unit"
            return (
                f"check {key_name(field, key)} ({float(value) * ratio:.4g}"
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


def _check_imu_clock(c: dict, usable: np.ndarray, dt: float, resampled, recording) -> None:
    """One line if the IMU's yaw rate turns as the heading (or the track's course) did
    seconds earlier or later (:func:`~graphcal.log.timing.coarse_wheel_lag` on its integral):
    its clock is off the GNSS's, and the line gives the manifest's ``time_offset`` that
    puts it right (before the units' check, to which such turns look tiny)."""
    imu = recording.imu
    if imu is None or imu.yaw_rate is None:
        return
    values = interval_means(imu.t, imu.yaw_rate, c["t"] + resampled.overlap[0])
    turned = np.concatenate([[0.0], np.cumsum(values[:-1] * dt)])
    lag = coarse_wheel_lag(turned, c["psi"], usable, dt, 0, len(turned) - 1) * dt
    if lag:
        raise StreamError(
            f"{provenance_of(imu).at(('yaw_rate',))}: the IMU's yaw rate turns as the heading "
            f"did {abs(lag):.1f} s {'earlier' if lag > 0 else 'later'}: its clock is off the "
            f"GNSS's; set time_offset = {-lag:+.1f} in its section (s added to its time)"
        )


def _check_imu_signs(
    c: dict, usable: np.ndarray, dt: float, resampled, recording, nominal=THETA_NOMINAL
) -> None:
    """One line if the IMU's lateral acceleration or yaw rate turns against the GNSS track."""
    imu = recording.imu
    if imu is None:
        return
    window = max(1, round(TURN_WINDOW_S / dt))
    fixed = None if resampled.measured is None else resampled.measured[:, 0]
    track = track_directions(c, usable, window, nominal, fixed)  # beyond its course noise
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
        agreement = turn_agreement(turn_directions(integral, usable, window), track)
        if agreement is not None and agreement < TURN_MIN_AGREEMENT:
            fix = mounted_fix(provenance_of(imu).fields.get(quantity))
            raise StreamError(
                f"{provenance_of(imu).at((quantity,))}: the IMU's {name} has the opposite sign "
                f"to the turns of the GNSS track in {1 - agreement:.0%} of them; it must be "
                f"{hint} (ROS REP 103: x forward, y left, z up): "
                + (fix or "negate the column or fix the IMU's frame")
            )
