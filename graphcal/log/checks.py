"""The checks of a drive-log table, one at a time, each raising :class:`DriveLogError` with one
line: what, where (the file, the column, the first bad line) and how to fix it. For an
imported recording, :class:`ColumnOrigin` turns the line into the user's terms (the stream's
file, column, manifest key and line). :func:`graphcal.log.validation.validate_frame`
runs them in order.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from graphcal.log.drive_log import (
    COLUMNS,
    SPARSE_COLUMNS,
    DriveLogError,
)
from graphcal.model import THETA_NOMINAL
from graphcal.units import time_text

if TYPE_CHECKING:
    from graphcal.log.drive_log import DriveLog

#: Relative tolerance on the sampling interval before a log counts as non-uniform: 25 % lets
#: timestamp jitter through (±3 ms per sample at 40 Hz) but stops at a dropped sample.
TIME_TOLERANCE = 0.25
#: Plausible sampling intervals [s]; outside, the time is probably not in seconds.
SAMPLING_INTERVAL_RANGE = (1e-4, 10.0)
#: Largest plausible |sideslip| [rad] (about 29°) and |lateral acceleration| [m/s²] (1.5 g).
MAX_SIDESLIP = 0.5
MAX_LATERAL_ACCELERATION = 15.0
#: Most negative wheel rotation [rev] accepted as encoder noise at standstill.
NEGATIVE_ROTATION_TOLERANCE = 0.005
#: Highest plausible speed [m/s] implied by one wheel's rotation with the nominal circumference.
MAX_PLAUSIBLE_SPEED = 100.0
#: The vehicle-profile key that makes wheels turning backwards motion (a robot), as a user
#: writes it.
REVERSES_KEY = "reverses = true"


def file_line(row: int) -> int:
    """File line of a data row (header is line 1)."""
    return int(row) + 2


def fail(
    path: str,
    column: str | None,
    row: int | None,
    what: str,
    fix: str,
    origins: Mapping[str, ColumnOrigin] | None = None,
    imported: str | None = None,
) -> DriveLogError:
    """The one-line error of a check on ``column`` at data row ``row``: in the drive log's
    terms, or, for a column with an origin (an imported recording), in the user's: the
    stream's file, column, manifest key and line, the check's ``imported`` text (``QUANTITY``
    in it replaced by what the column holds) and the origin's fix."""
    origin = None if origins is None or column is None else origins.get(column)
    if origin is not None:
        said = what if imported is None else imported.replace("QUANTITY", origin.quantity)
        return DriveLogError(f"{origin.where(row)}: {said}; {origin.fix}")
    where = path
    if column is not None:
        where += f": column '{column}'"
    if row is not None:
        where += f", line {file_line(row)}"
    return DriveLogError(f"{where}: {what}; {fix}")


@dataclass(frozen=True)
class ColumnOrigin:
    """Where an imported drive-log column came from, so that a check that fires on it speaks
    of the user's streams, never of a drive-log column the user did not write.

    Attributes:
        quantity: what the column holds, in words (``"lateral acceleration (the wheels'
            speed × the IMU's yaw rate)"``).
        where: ``where(row)``: the stream file(s), column(s) with their manifest keys and
            the line(s) behind drive-log row ``row``; ``where(None)`` without a line.
        fix: the how-to-fix: the manifest key(s) to check or change.
    """

    quantity: str
    where: Callable[[int | None], str]
    fix: str


def first_row(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def check_repeated(names: list[str], source: str) -> None:
    """One line naming a format column that the header repeats."""
    repeated = sorted({c for c in names if c in COLUMNS and names.count(c) > 1})
    if repeated:
        raise fail(
            source,
            repeated[0],
            None,
            f"column appears more than once in the header ({names.count(repeated[0])} times)",
            "keep one column of each name",
        )


def check_columns(
    frame: pd.DataFrame, source: str, origins: Mapping[str, ColumnOrigin] | None = None
) -> None:
    """One line if the table lacks a format column or has fewer than two rows."""
    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise fail(
            source,
            None,
            None,
            f"missing column(s) {', '.join(repr(c) for c in missing)}",
            f"the header must contain {', '.join(COLUMNS)}",
            origins=origins,
        )
    if len(frame) < 2:
        raise fail(
            source,
            None,
            None,
            f"only {len(frame)} data row(s)",
            "a log needs many samples",
            origins=origins,
        )


def numeric_columns(
    frame: pd.DataFrame, source: str, origins: Mapping[str, ColumnOrigin] | None = None
) -> dict[str, np.ndarray]:
    """The format columns as float arrays; one line for a value that is not a number, or not
    finite (empty is allowed in :data:`SPARSE_COLUMNS`: no measurement in that row)."""
    arrays: dict[str, np.ndarray] = {}
    for column in COLUMNS:
        raw = frame[column]
        if pd.api.types.is_numeric_dtype(raw.dtype):
            numeric = raw.to_numpy(dtype=float)
        else:
            numeric = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
            text = raw.astype(str).str.strip().str.lower()
            blank = raw.isna().to_numpy() | text.isin(["", "nan", "na", "null"]).to_numpy()
            bad_text = np.isnan(numeric) & ~blank
            if bad_text.any():
                row = first_row(bad_text)
                raise fail(
                    source,
                    column,
                    row,
                    f"non-numeric value {str(raw.iloc[row])!r}",
                    "every value must be a number",
                    origins=origins,
                )
        not_finite = ~np.isfinite(numeric)
        if column in SPARSE_COLUMNS:  # empty: no measurement in that row
            not_finite &= ~np.isnan(numeric)
        if not_finite.any():
            row = first_row(not_finite)
            raise fail(
                source,
                column,
                row,
                f"value is {numeric[row]} (missing or not finite)",
                "fill the gap or cut the log there",
                origins=origins,
            )
        arrays[column] = numeric
    return arrays


def sampling_interval(
    t: np.ndarray, source: str, origins: Mapping[str, ColumnOrigin] | None = None
) -> float:
    """The log's sampling interval [s] (the median step of ``t``); one line if the time does
    not increase, is not in seconds or is not uniform (:data:`TIME_TOLERANCE`)."""
    with np.errstate(over="ignore", invalid="ignore"):
        dt = np.diff(t)
    if not np.all(np.isfinite(dt)):
        row = first_row(~np.isfinite(dt)) + 1
        raise fail(
            source,
            "t",
            row,
            "time value too large to difference",
            "give the time in seconds",
            origins=origins,
        )
    if (dt <= 0).any():
        row = first_row(dt <= 0) + 1
        raise fail(
            source,
            "t",
            row,
            f"time does not increase ({time_text(t[row])} s after {time_text(t[row - 1])} s on "
            f"line {file_line(row - 1)})",
            "sort the rows by time and remove duplicates",
            origins=origins,
        )
    dt_nominal = float(np.median(dt))
    low, high = SAMPLING_INTERVAL_RANGE
    if not low <= dt_nominal <= high:
        raise fail(
            source,
            "t",
            None,
            f"sampling interval {dt_nominal:.6g} is not plausible in seconds",
            "give the time in seconds (not ms, µs or ns)",
            origins=origins,
        )
    uneven = np.abs(dt - dt_nominal) > TIME_TOLERANCE * dt_nominal
    if uneven.any():
        row = first_row(uneven) + 1
        raise fail(
            source,
            "t",
            row,
            f"non-uniform sampling: step {dt[row - 1]:.6g} s where the log's interval is "
            f"{dt_nominal:.6g} s",
            "resample the log to a uniform rate; across a gap, add the missing rows at that "
            "rate with masked = 1 (no segment spans them), or let `graphcal import` do it",
            origins=origins,
        )
    return dt_nominal


def check_heading_wraps(
    psi: np.ndarray,
    measured: np.ndarray,
    source: str,
    origins: Mapping[str, ColumnOrigin] | None = None,
) -> None:
    """One line if the measured headings jump as degrees wrapping at 360 do."""
    psi = psi[measured[:, 1]]
    jumps = np.abs(np.diff(psi))
    degree_wrap = (jumps > 4.0 * np.pi) & (jumps < 3.0 * 360.0)
    if degree_wrap.any():
        row = first_row(degree_wrap) + 1
        row = int(np.flatnonzero(measured[:, 1])[row])
        raise fail(
            source,
            "psi",
            row,
            f"heading jumps by {jumps[first_row(degree_wrap)]:.4g}, apparently degrees wrapping "
            "at 360",
            "convert the heading to radians (multiply by pi/180)",
            imported=(
                f"the QUANTITY jumps by {jumps[first_row(degree_wrap)]:.4g} rad between two "
                "samples, apparently degrees wrapping at 360"
            ),
            origins=origins,
        )


def check_inputs(
    arrays: dict[str, np.ndarray],
    dt_nominal: float,
    nominal: np.ndarray,
    reverses: bool,
    source: str,
    origins: Mapping[str, ColumnOrigin] | None = None,
) -> None:
    """One line for an implausible sideslip or lateral acceleration, a negative wheel
    rotation (unless the vehicle ``reverses``) or one implausibly large (over
    :data:`MAX_PLAUSIBLE_SPEED` with the nominal c_e)."""
    for column, limit, unit, hint in (
        ("beta", MAX_SIDESLIP, "rad", "give the sideslip in radians"),
        ("ay", MAX_LATERAL_ACCELERATION, "m/s²", "give the lateral acceleration in m/s²"),
    ):
        too_big = np.abs(arrays[column]) > limit
        if too_big.any():
            row = first_row(too_big)
            raise fail(
                source,
                column,
                row,
                f"implausible value {arrays[column][row]:.6g} (|{column}| over {limit:g} {unit})",
                hint,
                imported=(
                    f"implausible QUANTITY {arrays[column][row]:.4g} {unit} (over {limit:g} {unit})"
                ),
                origins=origins,
            )
    for column in ("n_rl", "n_rr"):
        n = arrays[column]
        negative = n < -NEGATIVE_ROTATION_TOLERANCE
        if not reverses and negative.any():
            row = first_row(negative)
            raise fail(
                source,
                column,
                row,
                f"negative wheel rotation {n[row]:.6g} rev",
                "a car's model covers forward driving only: cut reversing manoeuvres from the "
                f"log, or, for a robot that spins on the spot or reverses, set {REVERSES_KEY} in "
                "the vehicle profile (--vehicle)",
                imported=f"QUANTITY turns backwards ({n[row]:.4g} rev)",
                origins=origins,
            )
        limit = MAX_PLAUSIBLE_SPEED * dt_nominal / nominal[0]
        too_big = np.abs(n) > limit
        if too_big.any():
            row = first_row(too_big)
            raise fail(
                source,
                column,
                row,
                f"implausible wheel rotation {n[row]:.6g} rev per {dt_nominal:.4g} s sample "
                f"(over {MAX_PLAUSIBLE_SPEED:.0f} m/s)",
                "give the rotation in revolutions during each sample interval, not in radians "
                "or degrees, not a cumulative count (take the difference between rows)",
                imported=(
                    f"implausible QUANTITY: {abs(n[row]) * nominal[0] / dt_nominal:.4g} m/s with "
                    f"c_e = {nominal[0]:g} m (over {MAX_PLAUSIBLE_SPEED:.0f} m/s)"
                ),
                origins=origins,
            )


def checked_nominal(nominal: np.ndarray) -> np.ndarray:
    """``nominal`` as a float array, after checking it is a usable ``[c_e, c_d, t_r, d]``."""
    nominal = np.asarray(nominal, dtype=float)
    usable = nominal.shape == (4,) and np.isfinite(nominal).all()
    if not (usable and nominal[0] > 0 and nominal[2] > 0):
        raise ValueError(
            f"nominal must be a finite [c_e, c_d, t_r, d] with c_e, t_r > 0, got {nominal}"
        )
    return nominal


def check_heading_units(
    log: DriveLog,
    window_s: float = 2.0,
    *,
    nominal: np.ndarray = THETA_NOMINAL,
    origins: Mapping[str, ColumnOrigin] | None = None,
) -> None:
    """Catch a heading given in degrees without wrap-arounds.

    Compares heading changes over ``window_s`` windows (the heading is already unwrapped in
    radians) with the yaw the wheel rotations imply (nominal theta ``nominal``). In radians
    the ratio is near 1; in degrees it is near 57. A log without a measured heading holds
    the GNSS track's course, graphcal's own in radians: nothing to check (from noisy fixes
    it turns at random: a differential robot's 50 Hz fixes of 1.7 m, 22x the wheels' turn,
    were refused as degrees).
    """
    window = max(1, round(window_s / log.dt))
    if len(log) <= 2 * window or not log.heading_measured.any():
        return
    n_rl, n_rr = log.n_rl[:-1], log.n_rr[:-1]
    wheel_yaw = np.concatenate([[0.0], np.cumsum((n_rr - n_rl) * nominal[0] / nominal[2])])
    wheel_turn = np.abs(wheel_yaw[window::window] - wheel_yaw[:-window:window]).sum()
    heading_turn = np.abs(log.psi[window::window] - log.psi[:-window:window]).sum()
    if wheel_turn > 1.0 and heading_turn > 15.0 * wheel_turn:
        raise fail(
            log.source,
            "psi",
            None,
            f"heading turns {heading_turn / wheel_turn:.0f}x more than the wheel rotations imply, "
            "apparently degrees",
            "convert the heading to radians (multiply by pi/180)",
            origins,
            (
                f"the QUANTITY turns {heading_turn / wheel_turn:.0f}x more than the wheel "
                "rotations imply, apparently degrees"
            ),
        )
