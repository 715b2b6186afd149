"""The named columns of a manifest section's CSV file, read and checked, with provenance."""

from __future__ import annotations

import numpy as np
import pandas as pd

from graphcal.log.load import readable_csv
from graphcal.recording.section import Section
from graphcal.recording.streams import Field, Provenance, StreamError, check_time, unique_samples
from graphcal.recording.vocabulary import TIME_UNITS

#: The sample rates [Hz] of a plausible sensor stream (a 0.2 Hz GNSS to a 5 kHz IMU; bounds
#: away from the common 1 Hz and 1 kHz, whose jittered intervals straddle them): a median
#: sample interval that is not in the time unit declared but is in another is that unit's.
#: Inside the range the interval cannot tell a 1 Hz stream in s from a 1 kHz one in ms; the
#: streams' spans do (:mod:`graphcal.recording.manifest.time_spans`).
PLAUSIBLE_STREAM_RATE_HZ = (0.2, 5000.0)


def _interval_text(seconds: float) -> str:
    """A sample interval [s] in the unit that reads best: ``10 ms``, ``2.5 s``, ``10 us``."""
    for name in ("s", "ms", "us", "ns"):
        value = seconds / TIME_UNITS[name]
        if abs(value) >= 1 or name == "ns":
            return f"{value:.3g} {name}"
    raise AssertionError("unreachable")


def check_time_unit(raw: np.ndarray, unit: str, source: str, section: str, declared: str) -> None:
    """Refuse, in one line, a stream whose times read in ``unit`` (as ``declared``, the key as
    the manifest has it) give a median sample interval no sensor has (outside
    :data:`PLAUSIBLE_STREAM_RATE_HZ`) when another time unit gives a plausible one: the
    ``time_unit`` to set, before any check that would blame the speeds or the positions."""
    if len(raw) < 2:
        return
    interval = float(np.median(np.diff(raw)))  # [unit]
    slowest, fastest = (1.0 / rate for rate in PLAUSIBLE_STREAM_RATE_HZ)

    def plausible(name: str) -> bool:
        return fastest <= interval * TIME_UNITS[name] <= slowest

    if plausible(unit):
        return
    fits = [name for name in TIME_UNITS if plausible(name)]
    if not fits:
        return  # no unit explains it: left to the checks of the rate and gaps
    # of two units that fit, the one nearest a 20 ms interval (50 Hz, the typical car's)
    likely = min(fits, key=lambda name: abs(np.log(interval * TIME_UNITS[name] / 0.02)))
    read_as = interval * TIME_UNITS[unit]
    raise StreamError(
        f"the times of {source} look like {likely} (median interval "
        f"{_interval_text(interval * TIME_UNITS[likely])} read as {_interval_text(read_as)}, "
        f'{declared}: a {1 / read_as:.3g} Hz sensor): set time_unit = "{likely}" in '
        f"[{section}]"
    )


def read_columns(
    table: Section,
    columns: dict[str, str],
    notes: list[str],
    units: dict[str, str] | None = None,
    declared: dict[str, dict[str, str]] | None = None,
) -> tuple[str, np.ndarray, dict[str, np.ndarray], Provenance]:
    """Read the named columns of a section's CSV: ``(source, time [s], {role: values},
    provenance)``, each role's column named as the user wrote it with its manifest key and
    ``units`` (how the role's unit was declared); a time written twice is dropped when the
    rows agree and refused when they differ (:func:`graphcal.recording.streams.unique_samples`)."""
    section = table.name
    name = table.get("file")
    if not isinstance(name, str) or not name:
        raise table.error(f"[{section}] needs file (the stream's CSV, relative to the manifest)")
    path = table.resolve(name)
    source = str(path)
    if not path.is_file():
        raise StreamError(
            f"{source}: no such file (named in {table.source} [{section}] file); check the path"
        )
    time_column = table.text("time")
    unit = table.choice("time_unit", TIME_UNITS, "s")
    offset = table.number("time_offset", 0.0)
    header = readable_csv(source, lambda: pd.read_csv(path, nrows=0, skipinitialspace=True))
    available = [str(c).strip() for c in header.columns]
    wanted = {"time": time_column, **columns}
    for role, column in wanted.items():
        if column not in available:
            raise StreamError(
                f"{source}: no column {column!r} (the manifest's [{section}] {role}); the file "
                f"has {', '.join(available[:12])}"
            )
    frame = readable_csv(
        source,
        lambda: pd.read_csv(
            path,
            usecols=lambda c: str(c).strip() in set(wanted.values()),
            skipinitialspace=True,
            engine="c",
        ),
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    values = {}
    for role, column in wanted.items():
        numeric = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(numeric)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise StreamError(
                f"{source}: column {column!r}, line {row + 2}: value "
                f"{str(frame[column].iloc[row])!r} is not a finite number; fill or drop that row"
            )
        values[role] = numeric
    units = {"time": table.declaration("time_unit", "s"), **(units or {})}
    declared = {"time": {"time_unit": unit}, **(declared or {})}
    fields = {
        role: Field(
            column, f"[{section}] {role}", units.get(role), tuple(declared.get(role, {}).items())
        )
        for role, column in wanted.items()
    }
    provenance = Provenance(source, fields, np.arange(len(frame)) + 2)  # the header is line 1
    raw = values.pop("time")
    keep = unique_samples(raw, values, provenance, notes, unit=unit)
    if len(keep) < len(raw):
        raw, provenance = raw[keep], provenance.take(keep)
        values = {role: column[keep] for role, column in values.items()}
    check_time(raw, source, provenance, unit)
    check_time_unit(raw, unit, source, section, table.declaration("time_unit", "s"))
    t = raw * TIME_UNITS[unit] + offset
    return source, t, values, provenance
