"""A raw table in the drive-log format validated into a :class:`DriveLog`: the checks of
:mod:`graphcal.log.checks` in order, the track filled in where a row measured
nothing (:mod:`graphcal.log.track`), the samples marked not to be used, and the positions
screened against the wheels (:mod:`graphcal.log.consistency`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from graphcal.log.checks import (
    ColumnOrigin,
    check_columns,
    check_heading_units,
    check_heading_wraps,
    check_inputs,
    check_repeated,
    checked_nominal,
    fail,
    numeric_columns,
    sampling_interval,
)
from graphcal.log.consistency import MAX_MASKED_SHARE, screen
from graphcal.log.drive_log import DriveLog, DriveLogError, travelled_along_path
from graphcal.log.flags import marked_samples, measured_components, run_column
from graphcal.log.heading_travel import check_heading_against_travel
from graphcal.log.track import fill_track
from graphcal.log.turn_checks import (
    check_lateral_acceleration_units,
    check_track_stretch,
    check_turn_directions,
    check_wheel_ratio,
    check_wheels_turn,
    log_turns,
)
from graphcal.model import THETA_NOMINAL


def validate_frame(
    frame: pd.DataFrame,
    source: str,
    min_distance: float = 0.0,
    *,
    marked: np.ndarray | None = None,
    marked_notes: tuple[str, ...] = (),
    nominal: np.ndarray = THETA_NOMINAL,
    origins: Mapping[str, ColumnOrigin] | None = None,
    reverses: bool = False,
) -> DriveLog:
    """Validate a raw table in the drive-log format and return the :class:`DriveLog`.

    Checks, in order: repeated or missing columns, non-numeric values, NaN/inf, time
    non-increasing, not in seconds or non-uniform, heading apparently in degrees, implausible
    sideslip or lateral acceleration, negative or implausible wheel rotations, positions
    against the wheels, (a CSV's: an import checks its streams) one wheel's scale off, wheels,
    track and heading turning different ways or a lateral acceleration in g
    (:mod:`graphcal.log.turn_checks`), the heading pointing away from the direction of
    travel (:mod:`graphcal.log.heading_travel`) and, when ``min_distance`` [m] is given, a log
    too short for one segment.

    ``reverses`` (``VehicleProfile.reverses``): wheels turning backwards are motion (a robot
    spinning on the spot or reversing), accepted like forward rotations; else (a car) a
    negative rotation beyond encoder noise is refused.

    Samples to leave out come from the optional ``masked`` column (non-zero = masked, e.g.
    gaps an import carried over), from ``marked`` with one note per span in
    ``marked_notes``, and from the consistency screen; no segment spans any of them.

    The checks that turn wheel rotations into speed, distance or yaw (implausible rotations,
    heading units, positions against the wheels, ``min_distance``) use ``nominal``, the
    vehicle's nominal theta ``[c_e, c_d, t_r, d]`` (default: the paper's car).

    ``origins`` (an import's, by drive-log column) turns each message into the user's terms:
    the stream's file, column, manifest key and line instead of the drive-log column and row.
    """
    nominal = checked_nominal(nominal)
    check_repeated([str(c) for c in frame.columns], source)
    check_columns(frame, source, origins)
    arrays = numeric_columns(frame, source, origins)
    t = arrays["t"]
    dt_nominal = sampling_interval(t, source, origins)
    measured, lag = measured_components(frame, arrays, source, origins)
    check_heading_wraps(arrays["psi"], measured, source, origins)
    check_inputs(arrays, dt_nominal, nominal, reverses, source, origins)
    sparse = not measured.all() or lag is not None
    if sparse:
        travelled = travelled_along_path(arrays["n_rl"], arrays["n_rr"], nominal[0])
        arrays["px"], arrays["py"], arrays["psi"] = fill_track(
            t, arrays["px"], arrays["py"], arrays["psi"], measured, lag, travelled, nominal[0]
        )
    arrays["psi"] = np.unwrap(arrays["psi"])
    marked, marked_notes = marked_samples(frame, source, marked, marked_notes, t)
    log = DriveLog(
        **arrays,
        source=source,
        masked=marked,
        mask_notes=marked_notes,
        measured=measured if not measured.all() else None,
        fix_lag=lag,
        run=run_column(frame, source),
    )
    check_heading_units(log, nominal=nominal, origins=origins)
    log = _screened(log, source, nominal, origins)
    _check_columns_against_each_other(log, nominal, origins)
    if min_distance > 0:
        distance = log.travelled_distance(nominal[0])[-1]
        if distance < min_distance:
            raise fail(
                source,
                None,
                None,
                f"log covers only {distance:.1f} m, shorter than one {min_distance:.0f} m segment",
                "use a longer drive or a shorter --segment-length",
                origins=origins,
            )
    return log


def _check_columns_against_each_other(
    log: DriveLog, nominal: np.ndarray, origins: Mapping[str, ColumnOrigin] | None
) -> None:
    """The wheels, track and heading against each other: one wheel's scale, the turns'
    directions and ``ay``'s unit for a CSV (an import checked its streams against each
    other, in their terms), and the heading against the direction of travel for both."""
    if origins is None:
        turns = log_turns(log, nominal)
        check_wheel_ratio(log, turns, nominal)
        check_track_stretch(log, turns, nominal)
        check_wheels_turn(log, turns)
        check_turn_directions(log, nominal)
        check_lateral_acceleration_units(log, turns)
    check_heading_against_travel(log, nominal, origins)


def _screened(
    log: DriveLog,
    source: str,
    nominal: np.ndarray,
    origins: Mapping[str, ColumnOrigin] | None,
) -> DriveLog:
    """``log`` with its positions checked against the wheels (:func:`screen`): refused,
    masked or clean; refused too when more than :data:`MAX_MASKED_SHARE` is masked."""
    pair = _positions_against_wheels(origins)
    gaps = np.zeros(len(log.t), bool) if log.masked is None else log.masked.copy()
    gap_notes = len(log.mask_notes)
    try:
        # positions checked against the wheels: refused, masked or clean
        log = screen(log, nominal=nominal)
    except ValueError as exc:
        if pair is None:
            raise DriveLogError(f"{source}: {exc}") from None
        what = str(exc).split("; ", 1)[0].removeprefix("line ").split(": ", 1)[-1]
        raise DriveLogError(f"{pair[0]}: {what}; {pair[1]}") from None
    # The share among the samples an import did not already mark as gaps: drives on one clock
    # with long gaps between them (every stream stopped) are no disagreement.
    disagreeing = np.zeros(len(log.t), bool) if log.masked is None else log.masked & ~gaps
    share = disagreeing.sum() / max(1, np.count_nonzero(~gaps))
    if share > MAX_MASKED_SHARE:
        first = (log.mask_notes[gap_notes:] or log.mask_notes)[0]
        what = (
            f"{share:.0%} of the samples have positions that disagree with the "
            f"wheels (first: {first})"
        )
        if pair is not None:
            raise DriveLogError(f"{pair[0]}: {what}; {pair[1]}")
        raise fail(
            source,
            None,
            None,
            what,
            "check the position columns (units, frame) against the wheel rotations",
            origins=origins,
        )
    return log


def _positions_against_wheels(
    origins: Mapping[str, ColumnOrigin] | None,
) -> tuple[str, str] | None:
    """For an import, where a check of the positions against the wheels fired (the pose and
    the wheel streams) and what to check; ``None`` for a drive-log CSV."""
    if origins is None or "px" not in origins or "n_rl" not in origins:
        return None
    pose, wheels = origins["px"], origins["n_rl"]
    return f"{pose.where(None)} against {wheels.where(None)}", f"{pose.fix}; {wheels.fix}"
