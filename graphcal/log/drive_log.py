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
(:mod:`graphcal.log.track`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from graphcal.errors import GraphcalError
from graphcal.files import atomic_write_csv
from graphcal.model import THETA_NOMINAL

COLUMNS = ("t", "px", "py", "psi", "n_rl", "n_rr", "beta", "ay")
#: Optional column: 1 marks a sample no segment may span (e.g. a gap an import carried over).
MASK_COLUMN = "masked"
#: Optional column: the time [s] of the row's fix when it was taken between two rows.
FIX_TIME_COLUMN = "t_fix"
#: Optional column: the run (0, 1, …) a row belongs to, where a recording is several runs
#: whose clocks were each set apart (a robot's runs): each run has its own wheel time offset.
RUN_COLUMN = "run"
#: Columns that may be empty in a row (no fix, no heading there).
SPARSE_COLUMNS = ("px", "py", "psi")


class DriveLogError(GraphcalError, ValueError):
    """A drive log that cannot be used; the message is one line: what, where, how to fix."""


@dataclass(frozen=True)
class DriveLog:
    """A validated drive log: equally long float arrays, SI units, heading unwrapped.

    Use :func:`load_drive_log` to read one from CSV, :meth:`to_dataframe` for a pandas view.
    ``masked`` marks samples whose position disagrees with the wheels (jumps, frozen fixes;
    :mod:`graphcal.log.consistency`), ``mask_notes`` says where and why; no segment spans a
    masked sample. ``outlying`` marks isolated position spikes (a fix off the track and the
    next one back on it, e.g. multipath): segments keep them, calibration gives them no
    weight.

    ``measured`` ``(N, 2)`` says which rows measured the position and the heading (``None``:
    every row both, a uniform log), ``fix_lag`` ``(N,)`` [s] how long before the row's time
    its measurement was taken (``None``: at it). Where a component was not measured,
    ``px``, ``py``, ``psi`` hold the track (:mod:`graphcal.log.track`), not a measurement.
    ``tick_resolution`` [rev] is one count of the wheels' tick counters when the recording
    said so (an import's ``ticks_per_revolution``; ``None``: found from the rotations, if
    they are counts, :mod:`graphcal.log.quantization`). ``ay_from_wheels``: ``ay`` was
    derived from the wheels with the nominal theta (no IMU, no heading:
    :func:`graphcal.model.wheel_lateral_acceleration`), to be derived again with a solved
    one; ``ay_from_heading``: ``ay`` is the wheels' speed times the measured heading's rate (no
    IMU). ``pose_source`` is what measured the pose when the recording says so: ``"GNSS"``
    for geodetic fixes (a manifest's latitude and longitude, a bag's NavSatFix); ``None``
    when not known (a drive-log CSV, a local x/y pose: motion capture, a fused pose),
    which reports call the "position source" (:meth:`position_sensor`). ``wheel_noise``
    [rev per step] is the white noise the recording's own wheel rates show
    (:func:`graphcal.log.noise.rate_wheel_noise`; ``None``: not measured).
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
    ay_from_heading: bool = field(default=False, compare=False)
    run: np.ndarray | None = field(default=None, compare=False)
    pose_source: str | None = field(default=None, compare=False)
    wheel_noise: float | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        lengths = {name: np.shape(getattr(self, name)) for name in COLUMNS}
        if len(set(lengths.values())) != 1 or len(lengths["t"]) != 1:
            raise ValueError(f"DriveLog columns must be equally long 1-D arrays, got {lengths}")
        for name in ("masked", "outlying", "fix_lag", "run"):
            flags = getattr(self, name)
            if flags is not None and np.shape(flags) != lengths["t"]:
                raise ValueError(f"DriveLog.{name} must have one entry per sample")
        if self.measured is not None and np.shape(self.measured) != (len(self.t), 2):
            raise ValueError("DriveLog.measured must be (N, 2) booleans [position, heading]")

    @property
    def runs(self) -> int:
        """How many runs the log holds (1 without a ``run`` column)."""
        return 1 if self.run is None else int(self.run[-1]) + 1

    def position_sensor(self) -> str:
        """What reports call the point whose position the log measures: "GNSS antenna" for
        GNSS fixes, else "position source" (motion capture, a fused pose, not known)."""
        return "GNSS antenna" if self.pose_source == "GNSS" else "position source"

    def position_reference(self) -> str:
        """The point of the vehicle the model's positions belong to, which a lever arm is
        measured from: "centre of gravity" when the log has a sideslip (eq. 1 moves that
        point at ``beta`` to the heading), else "rear axle" (with ``beta = 0`` the model's
        point moves along the heading: a car's rear axle, or a point a little ahead of it
        when its rear tyres slip; docs/defects.md)."""
        return "centre of gravity" if np.any(self.beta != 0) else "rear axle"

    def run_of(self, rows: np.ndarray) -> np.ndarray:
        """The run of each of ``rows`` (all 0 for a log of one run)."""
        rows = np.asarray(rows)
        return np.zeros(rows.shape, np.int64) if self.run is None else self.run[rows]

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

    def pose(self, k: int) -> np.ndarray:
        """Measured state ``[px, py, psi]`` of sample ``k``, ``(3,)`` (a new array: not a row
        of :attr:`poses`, which would build, and keep alive, all ``N`` of them)."""
        return np.array([self.px[k], self.py[k], self.psi[k]], dtype=float)

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
        if self.run is not None:
            frame[RUN_COLUMN] = self.run.astype(np.int64)
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


def write_drive_log(log: DriveLog, path: str | os.PathLike[str]) -> None:
    """Write ``log`` as CSV atomically (full float precision; no partial file on failure)."""
    atomic_write_csv(log.to_dataframe(), path)
