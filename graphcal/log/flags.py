"""The rows of a drive log that measured something, and those marked not to be used: from
its sparse cells (``px``, ``py``, ``psi`` empty where not measured), its ``t_fix`` column
(a fix taken between two rows) and its ``masked`` column; each problem one line
(:func:`graphcal.log.checks.fail`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from graphcal.log.checks import ColumnOrigin, fail, first_row
from graphcal.log.consistency import runs
from graphcal.log.drive_log import FIX_TIME_COLUMN, MASK_COLUMN, RUN_COLUMN
from graphcal.units import time_text


def measured_components(
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
        row = first_row(half)
        column = "py" if px[row] else "px"
        raise fail(
            source,
            column,
            row,
            "empty where the other coordinate is given",
            "give both px and py of a fix, or leave both empty in a row without one",
        )
    measured = np.column_stack([px, np.isfinite(arrays["psi"])])
    if px.sum() < 2:
        raise fail(
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
        row = first_row(outside)
        raise fail(
            source,
            FIX_TIME_COLUMN,
            row,
            f"fix time {time_text(t_fix[row])} s is not after the previous row's t and at most "
            f"this row's t = {time_text(t[row])} s",
            "write each fix in the first row at or after its time",
        )
    unused = has_time & ~measured.any(axis=1)
    if unused.any():
        row = first_row(unused)
        raise fail(
            source,
            FIX_TIME_COLUMN,
            row,
            "a fix time in a row without px, py or psi",
            "leave t_fix empty where the row holds no measurement",
        )
    return measured, (lag if (lag > 0).any() else None)


def marked_samples(
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
            row = first_row(bad)
            raise fail(
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


def run_column(frame: pd.DataFrame, source: str) -> np.ndarray | None:
    """The optional ``run`` column (:data:`~graphcal.log.drive_log.RUN_COLUMN`): whole
    numbers from 0, never decreasing; ``None`` without it or when every row is run 0."""
    if RUN_COLUMN not in frame.columns:
        return None
    raw = pd.to_numeric(frame[RUN_COLUMN], errors="coerce").to_numpy(dtype=float)
    bad = ~(np.isfinite(raw) & (raw >= 0) & (raw == np.round(raw)))
    if bad.any():
        row = first_row(bad)
        raise fail(
            source,
            RUN_COLUMN,
            row,
            f"value {frame[RUN_COLUMN].iloc[row]!r} is not a run number (0, 1, 2, …)",
            "number the runs 0, 1, 2, … in the order they were recorded",
        )
    steps = np.diff(raw)
    if (steps < 0).any() or (steps > 1).any():
        row = first_row(np.concatenate([[False], (steps < 0) | (steps > 1)]))
        raise fail(
            source,
            RUN_COLUMN,
            row,
            f"run {raw[row]:g} after run {raw[row - 1]:g}",
            "the runs must follow one another: 0, then 1, then 2, …",
        )
    if raw[0] != 0:
        raise fail(source, RUN_COLUMN, 0, f"the first run is {raw[0]:g}", "number runs from 0")
    if raw[-1] == 0:
        return None
    return raw.astype(np.int64)
