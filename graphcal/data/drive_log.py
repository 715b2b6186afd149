"""The drive-log format: CSV, one row per sample, columns ``t, px, py, psi, n_rl, n_rr, beta, ay``.

* ``t`` time [s], uniformly sampled;
* ``px, py`` measured position in a local metric frame [m];
* ``psi`` measured heading [rad] (unwrapped on load);
* ``n_rl, n_rr`` measured rear-left / rear-right wheel rotation during the sample interval [rev];
* ``beta`` sideslip angle [rad]; ``ay`` lateral acceleration [m/s²].

Row ``k``'s inputs drive the step from row ``k`` to row ``k+1`` (eq. 1), so the last row's
inputs are unused. Extra columns are ignored. :func:`load_drive_log` validates the file and
raises :class:`DriveLogError` with one line naming the file, the column and the first bad line.

**Sparse measurements.** The wheel rotations are the uniform grid; the pose need not be: a
row without a fix leaves ``px`` and ``py`` empty, a row without a heading leaves ``psi``
empty, and a fix taken between two rows keeps its own time in the optional column
``t_fix`` (after the previous row's ``t``, at most its own row's). Each measurement is then
used once, at its own time (:class:`DriveLog` ``measured`` and ``fix_lag``); the pose at
the other rows is a track for cutting and initial values, never a measurement
(:mod:`graphcal.data.track`).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np
import pandas as pd

from graphcal.data.consistency import MAX_MASKED_SHARE, runs, screen
from graphcal.data.streams import time_text
from graphcal.data.track import fill_track
from graphcal.errors import GraphcalError, first_line
from graphcal.files import atomic_write_csv
from graphcal.model import THETA_NOMINAL

COLUMNS = ("t", "px", "py", "psi", "n_rl", "n_rr", "beta", "ay")
#: Optional column: 1 marks a sample no segment may span (e.g. a gap an import carried over).
MASK_COLUMN = "masked"
#: Optional column: the time [s] of the row's fix when it was taken between two rows.
FIX_TIME_COLUMN = "t_fix"
#: Columns that may be empty in a row (no fix, no heading there).
SPARSE_COLUMNS = ("px", "py", "psi")

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


T = TypeVar("T")


class DriveLogError(GraphcalError, ValueError):
    """A drive log that cannot be used; the message is one line: what, where, how to fix."""


@dataclass(frozen=True)
class DriveLog:
    """A validated drive log: equally long float arrays, SI units, heading unwrapped.

    Use :func:`load_drive_log` to read one from CSV, :meth:`to_dataframe` for a pandas view.
    ``masked`` marks samples whose position disagrees with the wheels (jumps, frozen fixes;
    :mod:`graphcal.data.consistency`), ``mask_notes`` says where and why; no segment spans a
    masked sample. ``outlying`` marks isolated position spikes (a fix off the track and the
    next one back on it, e.g. multipath): segments keep them, calibration gives them no
    weight.

    ``measured`` ``(N, 2)`` says which rows measured the position and the heading (``None``:
    every row both, a uniform log), ``fix_lag`` ``(N,)`` [s] how long before the row's time
    its measurement was taken (``None``: at it). Where a component was not measured,
    ``px``, ``py``, ``psi`` hold the track (:mod:`graphcal.data.track`), not a measurement.
    ``tick_resolution`` [rev] is one count of the wheels' tick counters when the recording
    said so (an import's ``ticks_per_revolution``; ``None``: found from the rotations, if
    they are counts, :mod:`graphcal.data.quantization`). ``ay_from_wheels``: ``ay`` was
    derived from the wheels with the nominal theta (no IMU, no heading:
    :func:`graphcal.model.wheel_lateral_acceleration`), to be derived again with a solved
    one.
    """

    t: np.ndarray
    px: np.ndarray
    py: np.ndarray
    psi: np.ndarray
    n_rl: np.ndarray
    n_rr: np.ndarray
    beta: np.ndarray
    ay: np.ndarray
    source: str = field(default="<memory>", compare=False)
    masked: np.ndarray | None = field(default=None, compare=False)
    mask_notes: tuple[str, ...] = field(default=(), compare=False)
    outlying: np.ndarray | None = field(default=None, compare=False)
    measured: np.ndarray | None = field(default=None, compare=False)
    fix_lag: np.ndarray | None = field(default=None, compare=False)
    tick_resolution: float | None = field(default=None, compare=False)
    ay_from_wheels: bool = field(default=False, compare=False)

    def __post_init__(self) -> None:
        lengths = {name: np.shape(getattr(self, name)) for name in COLUMNS}
        if len(set(lengths.values())) != 1 or len(lengths["t"]) != 1:
            raise ValueError(f"DriveLog columns must be equally long 1-D arrays, got {lengths}")
        for name in ("masked", "outlying", "fix_lag"):
            flags = getattr(self, name)
            if flags is not None and np.shape(flags) != lengths["t"]:
                raise ValueError(f"DriveLog.{name} must have one entry per sample")
        if self.measured is not None and np.shape(self.measured) != (len(self.t), 2):
            raise ValueError("DriveLog.measured must be (N, 2) booleans [position, heading]")

    @property
    def sparse(self) -> bool:
        """Some rows lack a measured position or heading, or measured it between rows."""
        return self.measured is not None or self.fix_lag is not None

    @property
    def position_measured(self) -> np.ndarray:
        """``(N,)``: the row holds a position fix."""
        if self.measured is None:
            return np.ones(len(self.t), bool)
        return np.asarray(self.measured[:, 0], bool)

    @property
    def heading_measured(self) -> np.ndarray:
        """``(N,)``: the row holds a measured heading."""
        if self.measured is None:
            return np.ones(len(self.t), bool)
        return np.asarray(self.measured[:, 1], bool)

    @property
    def fix_fraction(self) -> np.ndarray | None:
        """``(N,)`` in ``(0, 1]``: where in the step before each row its measurement was
        taken (1: at the row; row 0 is always 1), or ``None`` for every one at its row."""
        if self.fix_lag is None:
            return None
        step = np.diff(self.t)
        fraction = np.ones(len(self.t))
        fraction[1:] = 1.0 - self.fix_lag[1:] / step
        return fraction

    def __len__(self) -> int:
        return len(self.t)

    @property
    def dt(self) -> float:
        """Sampling interval [s] (median of the time differences)."""
        return float(np.median(np.diff(self.t)))

    @property
    def poses(self) -> np.ndarray:
        """Measured states ``[px, py, psi]``, shape ``(N, 3)``."""
        return np.column_stack([self.px, self.py, self.psi])

    @property
    def inputs(self) -> np.ndarray:
        """Model inputs ``[n_rl, n_rr, beta, ay]``, shape ``(N, 4)``; row k drives step k → k+1."""
        return np.column_stack([self.n_rl, self.n_rr, self.beta, self.ay])

    def travelled_distance(self, wheel_circumference: float = THETA_NOMINAL[0]) -> np.ndarray:
        """Distance [m] travelled up to each sample along the path, from the mean wheel
        rotation, ``(N,)``, with ``wheel_circumference`` (the vehicle's nominal c_e; default:
        the paper's car). A step backwards (a robot reversing) adds its length too, a spin on
        the spot (the wheels turning opposite ways) next to nothing: the distance never
        decreases, so segments cut by it stay in order."""
        return travelled_along_path(self.n_rl, self.n_rr, wheel_circumference)

    def to_dataframe(self) -> pd.DataFrame:
        """The log as a DataFrame with the format's columns (and ``masked`` if any is); rows
        without a measured position or heading leave those cells empty (NaN), and a fix
        between rows has its time in ``t_fix`` (:func:`measurement_frame`)."""
        columns = {name: getattr(self, name) for name in COLUMNS}
        frame = measurement_frame(columns, self.measured, self.fix_lag)
        if self.masked is not None:
            frame[MASK_COLUMN] = self.masked.astype(np.int8)
        return frame

    @classmethod
    def from_arrays(cls, source: str = "<memory>", **columns: np.ndarray) -> DriveLog:
        """Build a log from arrays named like the columns (copies to float arrays)."""
        missing = [c for c in COLUMNS if c not in columns]
        if missing:
            raise ValueError(f"missing columns {missing}")
        return cls(**{c: np.array(columns[c], dtype=float) for c in COLUMNS}, source=source)


def travelled_along_path(
    n_rl: np.ndarray, n_rr: np.ndarray, wheel_circumference: float
) -> np.ndarray:
    """Distance [m] along the path up to each sample, ``(N,)``: the cumulative absolute
    mean rotation of the two wheels (row k's rotation is the step k → k+1) times the
    circumference. Forward driving alone gives the plain cumulative distance."""
    per_step = np.abs(0.5 * (n_rl[:-1] + n_rr[:-1])) * wheel_circumference
    return np.concatenate([[0.0], np.cumsum(per_step)])


def measurement_frame(
    columns: dict[str, np.ndarray], measured: np.ndarray | None, fix_lag: np.ndarray | None
) -> pd.DataFrame:
    """The drive-log columns as a DataFrame, ``px, py`` empty in rows without a position fix
    and ``psi`` in rows without a heading (``measured`` ``(N, 2)``, ``None``: all measured),
    and a ``t_fix`` column with the time of each fix taken between rows (``fix_lag`` [s];
    empty where the row's measurements are at its own time)."""
    frame = pd.DataFrame(columns)
    if measured is not None:
        frame.loc[~measured[:, 0], ["px", "py"]] = np.nan
        frame.loc[~measured[:, 1], "psi"] = np.nan
    if fix_lag is not None and (fix_lag > 0).any():  # only where it is not the row's own t
        frame[FIX_TIME_COLUMN] = np.where(fix_lag > 0, frame["t"] - fix_lag, np.nan)
    return frame


def measurement_line(log: DriveLog) -> str:
    """What a log's pose rows measure, in one line: fixes and headings, their rates, and
    how many were taken between rows (for ``graphcal check``)."""
    duration = max(float(log.t[-1] - log.t[0]), 1e-9)
    parts = []
    kinds = (("position fixes", log.position_measured), ("headings", log.heading_measured))
    for name, rows in kinds:
        count = int(rows.sum())
        parts.append(f"{count} {name} ({count / duration:.1f} Hz)" if count else f"no {name}")
    between = 0 if log.fix_lag is None else int((log.fix_lag > 0).sum())
    if between:
        parts.append(f"{between} taken between rows, each used at its own time (t_fix)")
    return ", ".join(parts)


def _line(row: int) -> int:
    """File line of a data row (header is line 1)."""
    return int(row) + 2


def _fail(
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
        where += f", line {_line(row)}"
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


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def _check_repeated(names: list[str], source: str) -> None:
    """One line naming a format column that the header repeats."""
    repeated = sorted({c for c in names if c in COLUMNS and names.count(c) > 1})
    if repeated:
        raise _fail(
            source,
            repeated[0],
            None,
            f"column appears more than once in the header ({names.count(repeated[0])} times)",
            "keep one column of each name",
        )


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
    sideslip or lateral acceleration, negative or implausible wheel rotations and, when
    ``min_distance`` [m] is given, a log too short for one segment.

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
    nominal = _checked_nominal(nominal)

    def fail(*args, **kwargs) -> DriveLogError:
        return _fail(*args, **kwargs, origins=origins)

    _check_repeated([str(c) for c in frame.columns], source)
    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise fail(
            source,
            None,
            None,
            f"missing column(s) {', '.join(repr(c) for c in missing)}",
            f"the header must contain {', '.join(COLUMNS)}",
        )
    if len(frame) < 2:
        raise fail(source, None, None, f"only {len(frame)} data row(s)", "a log needs many samples")

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
                row = _first(bad_text)
                raise fail(
                    source,
                    column,
                    row,
                    f"non-numeric value {str(raw.iloc[row])!r}",
                    "every value must be a number",
                )
        not_finite = ~np.isfinite(numeric)
        if column in SPARSE_COLUMNS:  # empty: no measurement in that row
            not_finite &= ~np.isnan(numeric)
        if not_finite.any():
            row = _first(not_finite)
            raise fail(
                source,
                column,
                row,
                f"value is {numeric[row]} (missing or not finite)",
                "fill the gap or cut the log there",
            )
        arrays[column] = numeric

    t = arrays["t"]
    with np.errstate(over="ignore", invalid="ignore"):
        dt = np.diff(t)
    if not np.all(np.isfinite(dt)):
        row = _first(~np.isfinite(dt)) + 1
        raise fail(
            source, "t", row, "time value too large to difference", "give the time in seconds"
        )
    if (dt <= 0).any():
        row = _first(dt <= 0) + 1
        raise fail(
            source,
            "t",
            row,
            f"time does not increase ({time_text(t[row])} s after {time_text(t[row - 1])} s on "
            f"line {_line(row - 1)})",
            "sort the rows by time and remove duplicates",
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
        )
    uneven = np.abs(dt - dt_nominal) > TIME_TOLERANCE * dt_nominal
    if uneven.any():
        row = _first(uneven) + 1
        raise fail(
            source,
            "t",
            row,
            f"non-uniform sampling: step {dt[row - 1]:.6g} s where the log's interval is "
            f"{dt_nominal:.6g} s",
            "resample the log to a uniform rate (gaps must be cut into separate logs)",
        )

    measured, lag = _measured_components(frame, arrays, source, origins)
    psi = arrays["psi"][measured[:, 1]]
    jumps = np.abs(np.diff(psi))
    degree_wrap = (jumps > 4.0 * np.pi) & (jumps < 3.0 * 360.0)
    if degree_wrap.any():
        row = _first(degree_wrap) + 1
        row = int(np.flatnonzero(measured[:, 1])[row])
        raise fail(
            source,
            "psi",
            row,
            f"heading jumps by {jumps[_first(degree_wrap)]:.4g}, apparently degrees wrapping "
            "at 360",
            "convert the heading to radians (multiply by pi/180)",
            imported=(
                f"the QUANTITY jumps by {jumps[_first(degree_wrap)]:.4g} rad between two "
                "samples, apparently degrees wrapping at 360"
            ),
        )

    for column, limit, unit, hint in (
        ("beta", MAX_SIDESLIP, "rad", "give the sideslip in radians"),
        ("ay", MAX_LATERAL_ACCELERATION, "m/s²", "give the lateral acceleration in m/s²"),
    ):
        too_big = np.abs(arrays[column]) > limit
        if too_big.any():
            row = _first(too_big)
            raise fail(
                source,
                column,
                row,
                f"implausible value {arrays[column][row]:.6g} (|{column}| over {limit:g} {unit})",
                hint,
                imported=(
                    f"implausible QUANTITY {arrays[column][row]:.4g} {unit} (over {limit:g} {unit})"
                ),
            )

    for column in ("n_rl", "n_rr"):
        n = arrays[column]
        negative = n < -NEGATIVE_ROTATION_TOLERANCE
        if not reverses and negative.any():
            row = _first(negative)
            raise fail(
                source,
                column,
                row,
                f"negative wheel rotation {n[row]:.6g} rev",
                "a car's model covers forward driving only: cut reversing manoeuvres from the "
                f"log, or, for a robot that spins on the spot or reverses, set {REVERSES_KEY} in "
                "the vehicle profile (--vehicle)",
                imported=f"QUANTITY turns backwards ({n[row]:.4g} rev)",
            )
        limit = MAX_PLAUSIBLE_SPEED * dt_nominal / nominal[0]
        too_big = np.abs(n) > limit
        if too_big.any():
            row = _first(too_big)
            raise fail(
                source,
                column,
                row,
                f"implausible wheel rotation {n[row]:.6g} rev per {dt_nominal:.4g} s sample "
                f"(over {MAX_PLAUSIBLE_SPEED:.0f} m/s)",
                "give the rotation during each sample interval, not a cumulative count or angle "
                "in degrees (take the difference between rows)",
                imported=(
                    f"implausible QUANTITY: {abs(n[row]) * nominal[0] / dt_nominal:.4g} m/s with "
                    f"c_e = {nominal[0]:g} m (over {MAX_PLAUSIBLE_SPEED:.0f} m/s)"
                ),
            )

    sparse = not measured.all() or lag is not None
    if sparse:
        travelled = travelled_along_path(arrays["n_rl"], arrays["n_rr"], nominal[0])
        arrays["px"], arrays["py"], arrays["psi"] = fill_track(
            t, arrays["px"], arrays["py"], arrays["psi"], measured, lag, travelled, nominal[0]
        )
    arrays["psi"] = np.unwrap(arrays["psi"])
    marked, marked_notes = _marked_samples(frame, source, marked, marked_notes, t)
    log = DriveLog(
        **arrays,
        source=source,
        masked=marked,
        mask_notes=marked_notes,
        measured=measured if not measured.all() else None,
        fix_lag=lag,
    )
    _check_heading_units(log, nominal=nominal, origins=origins)
    pair = _positions_against_wheels(origins)
    try:
        # positions checked against the wheels: refused, masked or clean
        log = screen(log, nominal=nominal)
    except ValueError as exc:
        if pair is None:
            raise DriveLogError(f"{source}: {exc}") from None
        what = str(exc).split("; ", 1)[0].removeprefix("line ").split(": ", 1)[-1]
        raise DriveLogError(f"{pair[0]}: {what}; {pair[1]}") from None
    if log.masked is not None and log.masked.mean() > MAX_MASKED_SHARE:
        what = (
            f"{log.masked.mean():.0%} of the samples have positions that disagree with the "
            f"wheels (first: {log.mask_notes[0]})"
        )
        if pair is not None:
            raise DriveLogError(f"{pair[0]}: {what}; {pair[1]}")
        raise fail(
            source,
            None,
            None,
            what,
            "check the position columns (units, frame) against the wheel rotations",
        )

    if min_distance > 0:
        distance = log.travelled_distance(nominal[0])[-1]
        if distance < min_distance:
            raise fail(
                source,
                None,
                None,
                f"log covers only {distance:.1f} m, shorter than one {min_distance:.0f} m segment",
                "use a longer drive or a shorter --segment-length",
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


def _measured_components(
    frame: pd.DataFrame,
    arrays: dict[str, np.ndarray],
    source: str,
    origins: Mapping[str, ColumnOrigin] | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Which rows measured the position and the heading ``(N, 2)``, and each row's fix lag
    [s] (``None``: every measurement at its row) from the ``t_fix`` column."""
    px, py = np.isfinite(arrays["px"]), np.isfinite(arrays["py"])
    half = px != py
    if half.any():
        row = _first(half)
        column = "py" if px[row] else "px"
        raise _fail(
            source,
            column,
            row,
            "empty where the other coordinate is given",
            "give both px and py of a fix, or leave both empty in a row without one",
        )
    measured = np.column_stack([px, np.isfinite(arrays["psi"])])
    if px.sum() < 2:
        raise _fail(
            source,
            "px",
            None,
            f"only {int(px.sum())} row(s) hold a position",
            "a log needs position fixes along the drive",
            origins,
        )
    if FIX_TIME_COLUMN not in frame.columns:
        return measured, None
    t = arrays["t"]
    t_fix = pd.to_numeric(frame[FIX_TIME_COLUMN], errors="coerce").to_numpy(dtype=float)
    has_time = np.isfinite(t_fix)
    lag = np.where(has_time, t - np.where(has_time, t_fix, t), 0.0)
    step = np.concatenate([[0.0], np.diff(t)])
    outside = has_time & ((lag < 0) | (lag >= step) & (lag > 0))
    if outside.any():
        row = _first(outside)
        raise _fail(
            source,
            FIX_TIME_COLUMN,
            row,
            f"fix time {time_text(t_fix[row])} s is not after the previous row's t and at most "
            f"this row's t = {time_text(t[row])} s",
            "write each fix in the first row at or after its time",
        )
    unused = has_time & ~measured.any(axis=1)
    if unused.any():
        row = _first(unused)
        raise _fail(
            source,
            FIX_TIME_COLUMN,
            row,
            "a fix time in a row without px, py or psi",
            "leave t_fix empty where the row holds no measurement",
        )
    return measured, (lag if (lag > 0).any() else None)


def _marked_samples(
    frame: pd.DataFrame,
    source: str,
    marked: np.ndarray | None,
    notes: tuple[str, ...],
    t: np.ndarray,
) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Samples marked as not to be used: ``marked`` and the file's ``masked`` column."""
    if marked is not None:
        marked = np.asarray(marked, dtype=bool)
        if marked.shape != t.shape:
            raise ValueError(
                f"marked must have one entry per sample ({len(t)}), got {marked.shape}"
            )
    if MASK_COLUMN in frame.columns:
        raw = pd.to_numeric(frame[MASK_COLUMN], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isin(raw, (0.0, 1.0))
        if bad.any():
            row = _first(bad)
            raise _fail(
                source,
                MASK_COLUMN,
                row,
                f"value {frame[MASK_COLUMN].iloc[row]!r} is not 0 or 1",
                "mark samples to leave out with 1, all others with 0",
            )
        in_file = raw == 1.0
        new_notes = [
            f"t = {t[a]:.1f}–{t[b]:.1f} s marked masked in the file"
            for a, b in runs(in_file)
            if marked is None or not marked[a : b + 1].all()
        ]
        marked = in_file if marked is None else marked | in_file
        notes = (*notes, *new_notes)
    if marked is None or not marked.any():
        return None, ()
    return marked, tuple(notes)


def _checked_nominal(nominal: np.ndarray) -> np.ndarray:
    """``nominal`` as a float array, after checking it is a usable ``[c_e, c_d, t_r, d]``."""
    nominal = np.asarray(nominal, dtype=float)
    usable = nominal.shape == (4,) and np.isfinite(nominal).all()
    if not (usable and nominal[0] > 0 and nominal[2] > 0):
        raise ValueError(
            f"nominal must be a finite [c_e, c_d, t_r, d] with c_e, t_r > 0, got {nominal}"
        )
    return nominal


def _check_heading_units(
    log: DriveLog,
    window_s: float = 2.0,
    *,
    nominal: np.ndarray = THETA_NOMINAL,
    origins: Mapping[str, ColumnOrigin] | None = None,
) -> None:
    """Catch a heading given in degrees without wrap-arounds.

    Compares heading changes over ``window_s`` windows (the heading is already unwrapped in
    radians) with the yaw the wheel rotations imply (nominal theta ``nominal``). In radians
    the ratio is near 1; in degrees it is near 57.
    """
    window = max(1, round(window_s / log.dt))
    if len(log) <= 2 * window:
        return
    n_rl, n_rr = log.n_rl[:-1], log.n_rr[:-1]
    wheel_yaw = np.concatenate([[0.0], np.cumsum((n_rr - n_rl) * nominal[0] / nominal[2])])
    wheel_turn = np.abs(wheel_yaw[window::window] - wheel_yaw[:-window:window]).sum()
    heading_turn = np.abs(log.psi[window::window] - log.psi[:-window:window]).sum()
    if wheel_turn > 1.0 and heading_turn > 15.0 * wheel_turn:
        raise _fail(
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


#: Leading bytes of compressed files, and the pandas name of each compression.
_COMPRESSED = {
    b"\x1f\x8b": "gzip",
    b"BZh": "bz2",
    b"\xfd7zXZ\x00": "xz",
    b"PK\x03\x04": "zip",
    b"\x28\xb5\x2f\xfd": "zstd",
}


def _compression(path: Path) -> str | None:
    """The compression of ``path`` by its leading bytes (whatever its name), or ``None``."""
    with open(path, "rb") as handle:
        head = handle.read(6)
    return next((kind for magic, kind in _COMPRESSED.items() if head.startswith(magic)), None)


def _header(path: Path, compression: str | None) -> list[str]:
    """The raw column names of the first line, before pandas renames repeated ones."""
    frame = pd.read_csv(path, nrows=0, compression=compression, skipinitialspace=True)
    names = [str(c).strip() for c in frame.columns]
    # pandas has already renamed repeats to "name.1"; read the line itself for the truth.
    first = pd.read_csv(
        path, nrows=1, header=None, compression=compression, dtype=str, skipinitialspace=True
    )
    raw = [str(c).strip() for c in first.iloc[0].tolist()]
    return raw if len(raw) == len(names) else names


def _header_of(path: Path) -> tuple[str | None, list[str]]:
    compression = _compression(path)
    return compression, _header(path, compression)


def _readable(source: str, read: Callable[[], T]) -> T:
    """``read()``, with a file that cannot be read or parsed as CSV as one-line errors."""
    try:
        return read()
    except OSError as exc:
        raise DriveLogError(
            f"{source}: cannot read ({exc.strerror or exc}); check the file"
        ) from exc
    except (
        pd.errors.ParserError,
        pd.errors.EmptyDataError,
        UnicodeDecodeError,
        EOFError,
        ValueError,
    ) as exc:
        first = first_line(str(exc)) or type(exc).__name__
        raise DriveLogError(
            f"{source}: not a readable CSV ({first}); export the log as CSV"
        ) from exc


def load_drive_log(
    path: str | os.PathLike[str],
    min_distance: float = 0.0,
    *,
    nominal: np.ndarray = THETA_NOMINAL,
    reverses: bool = False,
) -> DriveLog:
    """Read and validate a drive-log CSV (see the module docstring for the format).

    The file may be compressed (gzip, bz2, xz, zip, zstd), whatever its name.

    Args:
        path: CSV file with a header row.
        min_distance: shortest acceptable travelled distance [m] (e.g. one segment length).
        nominal: the vehicle's nominal theta ``[c_e, c_d, t_r, d]`` (SI; default: the
            paper's car), which turns wheel rotations into distance and yaw for the checks
            (``VehicleProfile.theta_nominal``).
        reverses: wheels turning backwards are motion (``VehicleProfile.reverses``: a robot
            spinning on the spot or reversing); ``False`` (a car) refuses negative rotations.

    Raises:
        DriveLogError: with one line naming the file, the column and the first bad line.
    """
    source = str(path)
    path = Path(path)
    if path.is_dir():
        inside = sorted(p.name for p in path.glob("*.csv"))[:3]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise DriveLogError(
            f"{source}: is a directory, not a drive-log CSV{hint}; give the CSV file's path"
        )
    if not path.is_file():
        raise DriveLogError(f"{source}: no such file; check the path")
    compression, names = _readable(source, lambda: _header_of(path))
    _check_repeated(names, source)
    if len(names) == 1:  # before the full read, which would warn about ragged rows
        for separator, label in (
            (";", "semicolons"),
            ("\t", "tabs"),
            ("|", "bars"),
            (" ", "spaces"),
        ):
            if separator in names[0] and "," not in names[0]:
                raise DriveLogError(
                    f"{source}: the header '{names[0][:60]}' is one column: the file is "
                    f"separated by {label}, not commas; export it with ',' between columns "
                    "and '.' as the decimal point"
                )
    # index_col=False: a trailing comma on data rows must not shift the columns.
    frame = _readable(
        source,
        lambda: pd.read_csv(
            path, engine="c", skipinitialspace=True, index_col=False, compression=compression
        ),
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    log = validate_frame(frame, source, min_distance, nominal=nominal, reverses=reverses)
    return dataclasses.replace(log, **_from_import_sidecar(path))


def _from_import_sidecar(path: Path) -> dict:
    """What the ``<stem>.json`` sidecar that ``graphcal import`` wrote beside the CSV says
    that the CSV cannot: the wheels' tick resolution (``ticks_per_revolution``; counts
    interpolated onto the grid are no longer whole and cannot be found again) and whether
    ``ay`` came from the wheels (``ay_from_wheels``). Empty without such a sidecar."""
    try:
        meta = json.loads(path.with_name(f"{path.stem}.json").read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(meta, dict) or not str(meta.get("generator", "")).endswith(" import"):
        return {}
    found: dict = {}
    ticks = meta.get("ticks_per_revolution")
    if isinstance(ticks, int | float) and not isinstance(ticks, bool) and ticks >= 1:
        found["tick_resolution"] = 1.0 / float(ticks)
    if meta.get("ay_from_wheels") is True:
        found["ay_from_wheels"] = True
    return found


def write_drive_log(log: DriveLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as CSV atomically (full float precision; no partial file on failure)."""
    atomic_write_csv(log.to_dataframe(), path)
