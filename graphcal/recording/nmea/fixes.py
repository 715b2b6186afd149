"""The fixes of a receiver's NMEA 0183 log: one per UTC epoch, with its time, position,
heading and quality (:func:`read_nmea`), before any is dropped.

* **Fixes**: GGA (position, fix quality, satellites, HDOP) and RMC (position, status, date,
  speed and course over ground) of the same UTC time of day are one fix, at its own time:
  the position is GGA's where the epoch has one, else RMC's. A second GGA (or RMC) of an
  epoch is skipped, with a note.
* **Time**: the UTC time of day joined to a date: RMC's date, or the manifest's ``date``
  (the UTC date of the log's first fix) for a log without RMC; a log that runs past midnight
  rolls over to the next day (a time of day more than 12 h before the one before it).
  Seconds since 1970-01-01 UTC (Unix time), as the CSV streams', plus ``time_offset``.
* **Heading**: HDT (true heading, e.g. of a dual-antenna receiver) or THS, which carry no
  time of their own, belong to the epoch of the last GGA or RMC before them in the file.
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.recording.nmea.sentences import (
    HEADING_TYPES,
    Sentences,
    angle,
    dates,
    first_line_text,
    no_fix_sentence,
    numbers,
    scan,
    text_columns,
    time_of_day,
)
from graphcal.recording.streams import StreamError

#: GGA fix quality (NMEA 0183 4.x) by number, and the ones whose position is a measurement.
FIX_QUALITY = {
    0: "invalid",
    1: "GPS",
    2: "DGPS",
    3: "PPS",
    4: "RTK fixed",
    5: "RTK float",
    6: "dead reckoning",
    7: "manual input",
    8: "simulator",
}
USABLE_QUALITY = (1, 2, 3, 4, 5, 8)
#: RMC mode indicators (NMEA 2.3+) whose position is not a measurement: N not valid,
#: E estimated (dead reckoning), M manual, S simulator is kept as GGA quality 8 is.
UNUSABLE_MODES = ("N", "E", "M")
#: Milliseconds in a day, and the step back in time of day that is a midnight rollover.
DAY_MS = 86_400_000
ROLLOVER_MS = DAY_MS // 2
#: Knots in m/s.
KNOT = 1852.0 / 3600.0


@dataclass(frozen=True)
class NmeaLog:
    """Every epoch of an NMEA log with a GGA or RMC sentence, in time order, before any fix
    is dropped (:func:`read_nmea`).

    Attributes:
        t: time [s] since 1970-01-01 UTC (Unix time) of each epoch, ``(M,)``; exact to the
            millisecond.
        latitude, longitude: WGS-84 [deg]: GGA's, else RMC's; NaN where the epoch gives none.
        heading: true heading [deg, compass: 0 = north, clockwise] of the epoch's HDT/THS,
            NaN where it has none.
        quality: GGA fix quality (0–8, :data:`FIX_QUALITY`), −1 where the epoch has no GGA.
        rmc_valid: RMC status A (and a usable mode), ``False`` where it is V or there is no
            RMC.
        has_rmc: the epoch has an RMC sentence.
        hdop: GGA horizontal dilution of precision [-], NaN where none.
        satellites: GGA satellites in use, NaN where none.
        speed: RMC speed over ground [m/s], NaN where none.
        course: RMC course over ground [deg, compass], NaN where none (not a heading).
        lines: file line (1-based) of each epoch's position sentence (GGA, else RMC).
        counts: sentences read, by type (``"GGA"``, ``"RMC"``, ``"HDT"``, ``"GSV"``, ...).
        notes: what was skipped and why (bad checksums, duplicates, sorting), one line each.
    """

    t: np.ndarray
    latitude: np.ndarray
    longitude: np.ndarray
    heading: np.ndarray
    quality: np.ndarray
    rmc_valid: np.ndarray
    has_rmc: np.ndarray
    hdop: np.ndarray
    satellites: np.ndarray
    speed: np.ndarray
    course: np.ndarray
    lines: np.ndarray
    counts: dict[str, int]
    notes: tuple[str, ...] = ()

    def usable(self) -> np.ndarray:
        """Epochs whose position is a measurement: GGA quality 1–5 or 8, or (no GGA) RMC
        status A with a usable mode; and a position."""
        gga = self.quality >= 0
        good = np.where(gga, np.isin(self.quality, USABLE_QUALITY), self.rmc_valid)
        return good & np.isfinite(self.latitude) & np.isfinite(self.longitude)


@dataclass(frozen=True)
class _PositionSentences:
    """The sentences of one position type (GGA or RMC) as columns.

    Attributes:
        seq: each sentence's place among the sentences read, ``(n,)``.
        fields: the first fields of each, as text columns.
        lines: each one's file line (1-based), ``(n,)``.
        tod: each one's UTC time of day [ms], −1 where it does not parse, ``(n,)``.
    """

    seq: np.ndarray
    fields: list[np.ndarray]
    lines: np.ndarray
    tod: np.ndarray


@dataclass(frozen=True)
class _Timed:
    """Every timed GGA and RMC in file order.

    Attributes:
        kind: 0 for a GGA, 1 for an RMC.
        seq: the place among the sentences read.
        index: the place among the sentences of its type.
        key: the time [ms] since 1970-01-01 UTC.
    """

    kind: np.ndarray
    seq: np.ndarray
    index: np.ndarray
    key: np.ndarray


def _first_of_each(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Unique keys, the index of each one's first occurrence, and how many repeat one."""
    unique, first = np.unique(keys, return_index=True)
    return unique, first, len(keys) - len(unique)


def _date_days(date: datetime.date | str | None) -> int | None:
    if date is None:
        return None
    if isinstance(date, str):
        date = datetime.date.fromisoformat(date)
    return (date - datetime.date(1970, 1, 1)).days


def read_nmea(
    path: str | os.PathLike[str],
    date: datetime.date | str | None = None,
    *,
    date_key: str = "date",
    manifest: str = "",
) -> NmeaLog:
    """Every GGA/RMC epoch of an NMEA 0183 log (module docstring).

    Args:
        path: the log, one sentence per line (text before a ``$`` is ignored).
        date: the UTC date of the first epoch (``"2025-11-23"``), for a log without RMC; with
            RMC the RMC dates are used.
        date_key: how to name ``date`` in messages (``"[gnss] date"``).
        manifest: where ``date`` is given, for messages (``"manifest.toml"``).

    Raises:
        StreamError: one line: a log without a GGA or RMC sentence (saying what it holds),
            or without RMC and without ``date``.
    """
    path = Path(path)
    source = str(path)
    found = scan(path)
    notes = _skipped_sentences(found, source)
    if not found.data["GGA"] and not found.data["RMC"]:
        raise StreamError(f"{source}: {no_fix_sentence(found)}")
    gga, rmc = _position_sentences(found, "GGA", 8), _position_sentences(found, "RMC", 12)
    untimed = np.concatenate([gga.lines[gga.tod < 0], rmc.lines[rmc.tod < 0]])
    if len(untimed):
        notes.append(
            f"{source}: skipped {len(untimed)} GGA/RMC sentence(s) without a time of day "
            f"(a receiver without a fix yet; {first_line_text(untimed)})"
        )
    if not (gga.tod >= 0).any() and not (rmc.tod >= 0).any():
        raise StreamError(
            f"{source}: none of its {len(gga.tod) + len(rmc.tod)} GGA/RMC sentences has a "
            "UTC time (the receiver never had a fix); log again once it has one"
        )
    timed = _timed(gga, rmc, _GivenDate(date, date_key, manifest), source, notes)
    epochs = np.unique(timed.key)
    gga_at, rmc_at = _first_per_epoch(timed, epochs, gga, rmc, source, notes)
    heading = _headings(found, timed, epochs, source, notes)
    return NmeaLog(
        t=epochs / 1000.0,
        heading=heading,
        has_rmc=rmc_at >= 0,
        counts=dict(found.counts),
        notes=tuple(notes),
        **_epoch_fields(gga, rmc, gga_at, rmc_at),
    )


def _skipped_sentences(found: Sentences, source: str) -> list[str]:
    """Notes on the sentences skipped for a bad checksum or as unparsable."""
    notes: list[str] = []
    if found.bad_checksum:
        notes.append(
            f"{source}: skipped {len(found.bad_checksum)} sentence(s) with a wrong or missing "
            f"checksum ({first_line_text(found.bad_checksum)})"
        )
    if found.unparsable:
        line, why = found.unparsable[0]
        notes.append(
            f"{source}: skipped {len(found.unparsable)} sentence(s) that do not parse "
            f"(first: line {line}: {why})"
        )
    return notes


def _position_sentences(found: Sentences, kind: str, count: int) -> _PositionSentences:
    """The sentences of ``kind`` (``"GGA"``, ``"RMC"``) with their first ``count`` fields."""
    fields = text_columns(found.data[kind], count)
    return _PositionSentences(
        seq=np.asarray(found.seq[kind], dtype=np.int64),
        fields=fields,
        lines=np.asarray(found.lines[kind], dtype=np.int64),
        tod=time_of_day(fields[0]),
    )


@dataclass(frozen=True)
class _GivenDate:
    """The UTC date the user gave (or ``None``), the key that gave it and where."""

    date: datetime.date | str | None
    key: str
    manifest: str


def _timed(
    gga: _PositionSentences,
    rmc: _PositionSentences,
    given: _GivenDate,
    source: str,
    notes: list[str],
) -> _Timed:
    """Every timed GGA and RMC in file order, with its time since 1970 (:func:`_days`); a
    note if some run back in time (the fixes are sorted by it)."""
    kind = np.concatenate([np.zeros(len(gga.seq), np.int8), np.ones(len(rmc.seq), np.int8)])
    seq = np.concatenate([gga.seq, rmc.seq])
    tod = np.concatenate([gga.tod, rmc.tod])
    index = np.concatenate([np.arange(len(gga.seq)), np.arange(len(rmc.seq))])
    timed = np.flatnonzero(tod >= 0)
    timed = timed[np.argsort(seq[timed], kind="stable")]
    kind, seq, tod, index = kind[timed], seq[timed], tod[timed], index[timed]
    rolled = np.concatenate([[0], np.cumsum(np.diff(tod) < -ROLLOVER_MS)])
    offset = _days(kind, index, rolled, gga, rmc, given, source, notes)
    key = (offset.astype(np.int64) + rolled) * DAY_MS + tod  # ms since 1970-01-01 UTC
    back = np.diff(key) < 0
    if back.any():
        first = int(np.flatnonzero(back)[0]) + 1
        line = (gga.lines if kind[first] == 0 else rmc.lines)[index[first]]
        notes.append(
            f"{source}: {int(back.sum())} sentence(s) earlier than the one before them (first: "
            f"line {line}); the fixes are sorted by time"
        )
    return _Timed(kind, seq, index, key)


def _days(
    kind: np.ndarray,
    index: np.ndarray,
    rolled: np.ndarray,
    gga: _PositionSentences,
    rmc: _PositionSentences,
    given_date: _GivenDate,
    source: str,
    notes: list[str],
) -> np.ndarray:
    """The day [days since 1970-01-01] of the first timed sentence's date, per timed sentence
    (RMC's date, less the midnights ``rolled`` since; else ``date``); one line if neither."""
    rmc_days = dates(rmc.fields[8]) if len(rmc.seq) else np.zeros(0, np.int64)
    day_of = np.full(len(kind), np.nan)
    is_rmc = kind == 1
    dated = np.zeros(len(kind), dtype=bool)
    dated[is_rmc] = rmc_days[index[is_rmc]] >= 0
    day_of[dated] = rmc_days[index[dated]] - rolled[dated]
    date, date_key, manifest = given_date.date, given_date.key, given_date.manifest
    given = _date_days(date)
    if dated.any():
        first_day = pd.Series(day_of).bfill().to_numpy()[0]
        offset = pd.Series(day_of).ffill().bfill().to_numpy()
        if given is not None and given != first_day:
            notes.append(
                f'{source}: {date_key} = "{date}" differs from the RMC date of the first fix '
                f"({np.datetime64(int(first_day), 'D')}); the RMC dates are used"
            )
        return offset
    if given is not None:
        return np.full(len(kind), float(given))
    rmc_text = f"{len(rmc.seq)} RMC without a date" if len(rmc.seq) else "no RMC"
    where = f" in {manifest}" if manifest else ""
    raise StreamError(
        f"{source}: {len(gga.seq)} GGA sentences and {rmc_text}: their UTC times of day need "
        f'a date: add {date_key} = "YYYY-MM-DD" (the UTC date of the first fix){where}'
    )


def _first_per_epoch(
    timed: _Timed,
    epochs: np.ndarray,
    gga: _PositionSentences,
    rmc: _PositionSentences,
    source: str,
    notes: list[str],
) -> tuple[np.ndarray, np.ndarray]:
    """One fix per epoch: the index of each epoch's first GGA and first RMC (−1: none); a
    note per type on the ones repeating an epoch."""
    m = len(epochs)
    gga_at = np.full(m, -1, np.int64)
    rmc_at = np.full(m, -1, np.int64)
    for kind_code, name, at in ((0, "GGA", gga_at), (1, "RMC", rmc_at)):
        mine = timed.kind == kind_code
        unique, first, repeated = _first_of_each(timed.key[mine])
        at[np.searchsorted(epochs, unique)] = timed.index[mine][first]
        if repeated:
            lines = gga.lines if kind_code == 0 else rmc.lines
            taken = np.zeros(int(mine.sum()), bool)
            taken[first] = True
            notes.append(
                f"{source}: skipped {repeated} {name} sentence(s) repeating the time of one "
                f"before them (another talker, or a log written twice; "
                f"{first_line_text(lines[timed.index[mine][~taken]])})"
            )
    return gga_at, rmc_at


def _take(values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Each epoch's value of its sentence ``at`` (NaN where it has none)."""
    out = np.full(len(at), np.nan)
    out[at >= 0] = values[at[at >= 0]]
    return out


def _epoch_fields(
    gga: _PositionSentences, rmc: _PositionSentences, gga_at: np.ndarray, rmc_at: np.ndarray
) -> dict[str, np.ndarray]:
    """The :class:`NmeaLog` fields of each epoch's GGA and RMC (GGA's position where the
    epoch has one): position, quality, RMC validity, HDOP, satellites, speed, course, line."""
    g, r = gga.fields, rmc.fields
    has_gga, has_rmc = gga_at >= 0, rmc_at >= 0
    lat_g = angle(g[1], g[2], ("N", "S"), 90.0)
    lon_g = angle(g[3], g[4], ("E", "W"), 180.0)
    lat_r = angle(r[2], r[3], ("N", "S"), 90.0)
    lon_r = angle(r[4], r[5], ("E", "W"), 180.0)
    quality_number = numbers(g[5])
    quality = np.where(np.isfinite(quality_number), quality_number, 0.0)  # unreadable: invalid
    rmc_ok = (r[1] == "A") & ~np.isin(r[11], UNUSABLE_MODES)
    rmc_valid = np.zeros(len(gga_at), dtype=bool)
    rmc_valid[has_rmc] = rmc_ok[rmc_at[has_rmc]]
    lines = np.where(has_gga, _take(gga.lines, gga_at), _take(rmc.lines, rmc_at))
    return {
        "latitude": np.where(has_gga, _take(lat_g, gga_at), _take(lat_r, rmc_at)),
        "longitude": np.where(has_gga, _take(lon_g, gga_at), _take(lon_r, rmc_at)),
        "quality": np.where(has_gga, _take(quality, gga_at), -1.0).astype(np.int64),
        "rmc_valid": rmc_valid,
        "hdop": _take(numbers(g[7]), gga_at),
        "satellites": _take(numbers(g[6]), gga_at),
        "speed": _take(numbers(r[6]) * KNOT, rmc_at),
        "course": _take(numbers(r[7]), rmc_at),
        "lines": lines.astype(np.int64),
    }


def _headings(
    found: Sentences, timed: _Timed, epochs: np.ndarray, source: str, notes: list[str]
) -> np.ndarray:
    """Each epoch's true heading [deg, compass] (NaN: none): an HDT/THS belongs to the epoch
    of the last GGA/RMC before it, the first one of an epoch (HDT before THS) is kept; a note
    on those before the first GGA/RMC."""
    heading = np.full(len(epochs), np.nan)
    skipped_heading = 0
    for name in HEADING_TYPES:
        rows = found.data[name]
        if not rows:
            continue
        value_column, flag = text_columns(rows, 2)
        value = numbers(value_column)
        ok = np.isfinite(value) & (value >= 0) & (value <= 360)
        if name == "THS":
            ok &= flag != "V"
        before = np.searchsorted(timed.seq, np.asarray(found.seq[name]), side="right") - 1
        ok &= before >= 0
        skipped_heading += int((before < 0).sum())
        epoch = np.searchsorted(epochs, timed.key[np.maximum(before, 0)])[ok]
        unique, first = np.unique(epoch, return_index=True)  # the epoch's first one
        fresh = np.isnan(heading[unique])  # HDT before THS
        heading[unique[fresh]] = value[ok][first[fresh]]
    if skipped_heading:
        notes.append(
            f"{source}: skipped {skipped_heading} heading sentence(s) before the first GGA/RMC "
            "(a heading belongs to the epoch of the last GGA/RMC before it)"
        )
    return heading
