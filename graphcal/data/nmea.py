"""GNSS fixes from a receiver's NMEA 0183 log: ``[gnss] nmea = "receiver.nmea"``.

pynmea2 (the optional extra ``graphcal[nmea]``, imported only here) checks each sentence's
checksum and splits it into fields; the fields are turned into numbers for the whole log at
once (numpy), so a 3-hour 10 Hz log (over 200,000 sentences) reads in a few seconds.

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
  The course over ground (VTG's, RMC's) is the direction of travel, not the heading, and is
  never used as one. The heading is used only when every kept fix has one (else positions
  only, with a note); ``heading = false`` ignores it.
* **Fix quality**: fixes with GGA quality 0 (invalid), 6 (dead reckoning: the receiver's
  own odometry, not a measurement of it) or 7 (manual input), and RMC-only fixes with status
  V (or mode N or E) are dropped, with a note; the fix qualities, HDOP and satellites of the
  kept fixes are summarised in a note. Every fix has the same weight in calibration (the
  vehicle's ``position_sigma``): the estimator has no per-fix weight (yet), so HDOP is
  reported, not used.
* **Bad sentences**: a sentence with a wrong or missing checksum, or whose time, position
  or date does not parse, is skipped and counted in a note, never fatal; other sentence
  types (GSV, GSA, VTG, proprietary ones) are counted and skipped; text before a ``$`` on a
  line (a logger's time stamp) is ignored.
"""

from __future__ import annotations

import dataclasses
import datetime
import itertools
import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from graphcal.data.geodesy import geodetic_to_local
from graphcal.data.streams import Field, PoseStream, Provenance, StreamError

#: Sentence types (after the two-letter talker) that are read.
POSITION_TYPES = ("GGA", "RMC")
HEADING_TYPES = ("HDT", "THS")
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
#: Manifest keys of a section that reads an NMEA log (and what they replace).
NMEA_KEYS = ("nmea", "date", "time_offset", "heading")
_MISSING_PYNMEA2 = 'reading NMEA logs needs the pynmea2 package: pip install -e ".[nmea]"'


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
class SentenceProvenance(Provenance):
    """The :class:`~graphcal.data.streams.Provenance` of an NMEA log's fixes: each fix's line
    is printed with its sentence, and the log gives its own advice where the advice for CSV
    columns (``heading_convention``, ``latitude``/``longitude`` swapped) does not apply.

    Attributes:
        section: the manifest section (``"[gnss]"``).
        advice: how to fix, by topic: ``"position"``, ``"heading"``, ``"mirrored"``.
        quality: GGA fix quality of each fix (−1: RMC only), or ``None``.
        hdop: GGA HDOP [-] of each fix (NaN: none), or ``None``. Kept for a per-fix weight;
            the estimator does not use one yet.
    """

    section: str = "[gnss]"
    advice: dict[str, str] = field(default_factory=dict)
    quality: np.ndarray | None = None
    hdop: np.ndarray | None = None

    def take(self, keep: np.ndarray) -> SentenceProvenance:
        """The provenance of the fixes ``keep`` (indices or a mask), with their quality."""
        return dataclasses.replace(
            self,
            lines=np.asarray(self.lines)[keep],
            quality=None if self.quality is None else self.quality[keep],
            hdop=None if self.hdop is None else self.hdop[keep],
        )

    def columns(self, *quantities: str) -> str:
        """``GGA/RMC latitude and longitude ([gnss] nmea)``."""
        names = list(dict.fromkeys(self.fields[q].name for q in quantities if q in self.fields))
        return f"{' and '.join(names)} ({self.section} nmea)" if names else f"{self.section} nmea"

    def line(self, k: int) -> str:
        """``line 1234 ("$GNGGA,101519.30,...*5C")``."""
        number = int(self.lines[int(k)])
        return f'line {number} ("{_sentence_at(self.file, number)}")'


def _sentence_at(path: str, number: int) -> str:
    """The sentence on line ``number`` of ``path`` (read when a message needs it)."""
    try:
        with open(path, encoding="ascii", errors="replace") as handle:
            text = next(itertools.islice(handle, number - 1, None), "")
    except OSError:
        return "?"
    text = text.strip()
    start = text.find("$")
    return text[start:] if start >= 0 else text


def _import_pynmea2():
    try:
        import pynmea2
    except ImportError:
        raise StreamError(_MISSING_PYNMEA2) from None
    return pynmea2


@dataclass
class _Sentences:
    """The sentences of interest, in file order: their order number, line and fields."""

    seq: dict[str, list[int]] = field(default_factory=lambda: {k: [] for k in _WANTED})
    lines: dict[str, list[int]] = field(default_factory=lambda: {k: [] for k in _WANTED})
    data: dict[str, list[list[str]]] = field(default_factory=lambda: {k: [] for k in _WANTED})
    counts: Counter = field(default_factory=Counter)
    bad_checksum: list[int] = field(default_factory=list)
    unparsable: list[tuple[int, str]] = field(default_factory=list)
    lines_read: int = 0
    first_text: str = ""


_WANTED = (*POSITION_TYPES, *HEADING_TYPES)


def _scan(path: Path) -> _Sentences:
    """Read the log's lines: checksum-checked fields of GGA, RMC, HDT and THS; counts of the
    rest."""
    pynmea2 = _import_pynmea2()
    found = _Sentences()
    seq = number = 0
    parse, checksum = pynmea2.parse, pynmea2.NMEASentence.checksum
    parse_error = pynmea2.ParseError  # ChecksumError and SentenceTypeError are ParseErrors
    checksum_error = pynmea2.ChecksumError
    with open(path, encoding="ascii", errors="replace") as handle:
        for number, raw in enumerate(handle, 1):
            start = raw.find("$")
            if start < 0:
                if raw.strip() and not found.first_text:
                    found.first_text = raw.strip()[:40]
                continue
            text = raw[start:].rstrip()
            kind = text[3:6] if text[1:2] != "P" else "proprietary"
            kind = kind if kind.isalnum() else "unreadable"
            if kind not in _WANTED:
                found.counts[kind] += 1
                continue
            if kind == "THS":  # NMEA 4.x, which pynmea2 does not know: checked here
                body, star, given = text[1:].partition("*")
                try:
                    ok = star and int(given[:2], 16) == checksum(body)
                except ValueError:
                    ok = False
                if not ok:
                    found.bad_checksum.append(number)
                    continue
                data = body.split(",")[1:]
            else:
                try:
                    data = parse(text, check=True).data
                except checksum_error:
                    found.bad_checksum.append(number)
                    continue
                except (parse_error, ValueError) as exc:
                    found.unparsable.append((number, str(exc.args[0] if exc.args else exc)))
                    continue
            found.counts[kind] += 1
            found.seq[kind].append(seq)
            found.lines[kind].append(number)
            found.data[kind].append(data)
            seq += 1
    found.lines_read = number
    return found


def _columns(rows: list[list[str]], count: int) -> list[np.ndarray]:
    """The first ``count`` fields of each sentence as text columns ('' where missing)."""
    return [
        np.array([row[k] if len(row) > k else "" for row in rows], dtype=object)
        for k in range(count)
    ]


def _numbers(column: np.ndarray) -> np.ndarray:
    return np.asarray(pd.to_numeric(column, errors="coerce"), dtype=float)


def _time_of_day(column: np.ndarray) -> np.ndarray:
    """``hhmmss.ss`` → milliseconds of the day (int64), −1 where it does not parse."""
    value = _numbers(column)
    hours = np.floor(value / 10_000.0)
    minutes = np.floor(value / 100.0) - 100.0 * hours
    seconds = value - 10_000.0 * hours - 100.0 * minutes
    ok = np.isfinite(value) & (value >= 0) & (hours < 24) & (minutes < 60) & (seconds < 61)
    ms = np.round((3600.0 * hours + 60.0 * minutes + seconds) * 1000.0)
    return np.where(ok, ms, -1).astype(np.int64)


def _angle(column: np.ndarray, hemisphere: np.ndarray, signs: tuple[str, str], limit: float):
    """``ddmm.mmmm`` / ``dddmm.mmmm`` with N/S (E/W) → signed degrees; NaN where it does not
    parse (an empty field: no fix)."""
    value = _numbers(column)
    degrees = np.floor(value / 100.0)
    minutes = value - 100.0 * degrees
    positive, negative = signs
    sign = np.where(hemisphere == positive, 1.0, np.where(hemisphere == negative, -1.0, np.nan))
    angle = sign * (degrees + minutes / 60.0)
    ok = np.isfinite(angle) & (minutes < 60.0) & (np.abs(angle) <= limit)
    return np.where(ok, angle, np.nan)


def _dates(column: np.ndarray) -> np.ndarray:
    """RMC's ``ddmmyy`` → days since 1970-01-01 (int64), −1 where it does not parse."""
    parsed = pd.to_datetime(pd.Series(column, dtype=object), format="%d%m%y", errors="coerce")
    days = parsed.to_numpy(dtype="datetime64[D]").astype(np.int64)
    return np.where(parsed.isna().to_numpy(), -1, days)


def _first_of_each(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Unique keys, the index of each one's first occurrence, and how many repeat one."""
    unique, first = np.unique(keys, return_index=True)
    return unique, first, len(keys) - len(unique)


def _first_line(lines: list[int] | np.ndarray) -> str:
    return f"first: line {int(np.min(lines))}"


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
    found = _scan(path)
    notes: list[str] = []
    if found.bad_checksum:
        notes.append(
            f"{source}: skipped {len(found.bad_checksum)} sentence(s) with a wrong or missing "
            f"checksum ({_first_line(found.bad_checksum)})"
        )
    if found.unparsable:
        line, why = found.unparsable[0]
        notes.append(
            f"{source}: skipped {len(found.unparsable)} sentence(s) that do not parse "
            f"(first: line {line}: {why})"
        )
    if not found.data["GGA"] and not found.data["RMC"]:
        raise StreamError(f"{source}: {_no_fix_sentence(found)}")

    # Per position sentence: order in the file, time of day, fields.
    tables = {}
    for kind, count in (("GGA", 8), ("RMC", 12)):
        rows = found.data[kind]
        columns = _columns(rows, count)
        tables[kind] = (np.asarray(found.seq[kind], dtype=np.int64), columns)
    gga_seq, g = tables["GGA"]
    rmc_seq, r = tables["RMC"]
    gga_lines = np.asarray(found.lines["GGA"], dtype=np.int64)
    rmc_lines = np.asarray(found.lines["RMC"], dtype=np.int64)
    gga_tod, rmc_tod = _time_of_day(g[0]), _time_of_day(r[0])
    untimed = np.concatenate([gga_lines[gga_tod < 0], rmc_lines[rmc_tod < 0]])
    if len(untimed):
        notes.append(
            f"{source}: skipped {len(untimed)} GGA/RMC sentence(s) without a time of day "
            f"(a receiver without a fix yet; {_first_line(untimed)})"
        )
    if not (gga_tod >= 0).any() and not (rmc_tod >= 0).any():
        raise StreamError(
            f"{source}: none of its {len(gga_tod) + len(rmc_tod)} GGA/RMC sentences has a "
            "UTC time (the receiver never had a fix); log again once it has one"
        )

    # Every timed GGA and RMC in file order: day of each (RMC date, rolled over at midnight).
    kind = np.concatenate([np.zeros(len(gga_seq), np.int8), np.ones(len(rmc_seq), np.int8)])
    seq = np.concatenate([gga_seq, rmc_seq])
    tod = np.concatenate([gga_tod, rmc_tod])
    index = np.concatenate([np.arange(len(gga_seq)), np.arange(len(rmc_seq))])
    timed = np.flatnonzero(tod >= 0)
    timed = timed[np.argsort(seq[timed], kind="stable")]
    kind, seq, tod, index = kind[timed], seq[timed], tod[timed], index[timed]
    rolled = np.concatenate([[0], np.cumsum(np.diff(tod) < -ROLLOVER_MS)])
    rmc_days = _dates(r[8]) if len(rmc_seq) else np.zeros(0, np.int64)
    day_of = np.full(len(tod), np.nan)
    is_rmc = kind == 1
    dated = np.zeros(len(tod), dtype=bool)
    dated[is_rmc] = rmc_days[index[is_rmc]] >= 0
    day_of[dated] = rmc_days[index[dated]] - rolled[dated]
    given = _date_days(date)
    if dated.any():
        first_day = pd.Series(day_of).bfill().to_numpy()[0]
        offset = pd.Series(day_of).ffill().bfill().to_numpy()
        if given is not None and given != first_day:
            notes.append(
                f'{source}: {date_key} = "{date}" differs from the RMC date of the first fix '
                f"({np.datetime64(int(first_day), 'D')}); the RMC dates are used"
            )
    elif given is not None:
        offset = np.full(len(tod), float(given))
    else:
        rmc = f"{len(rmc_seq)} RMC without a date" if len(rmc_seq) else "no RMC"
        where = f" in {manifest}" if manifest else ""
        raise StreamError(
            f"{source}: {len(gga_seq)} GGA sentences and {rmc}: their UTC times of day need "
            f'a date: add {date_key} = "YYYY-MM-DD" (the UTC date of the first fix){where}'
        )
    key = (offset.astype(np.int64) + rolled) * DAY_MS + tod  # ms since 1970-01-01 UTC
    back = np.diff(key) < 0
    if back.any():
        first = int(np.flatnonzero(back)[0]) + 1
        line = (gga_lines if kind[first] == 0 else rmc_lines)[index[first]]
        notes.append(
            f"{source}: {int(back.sum())} sentence(s) earlier than the one before them (first: "
            f"line {line}); the fixes are sorted by time"
        )

    # One fix per epoch: the first GGA and the first RMC of each time.
    epochs = np.unique(key)
    m = len(epochs)
    gga_at = np.full(m, -1, np.int64)
    rmc_at = np.full(m, -1, np.int64)
    for kind_code, name, at in ((0, "GGA", gga_at), (1, "RMC", rmc_at)):
        mine = kind == kind_code
        unique, first, repeated = _first_of_each(key[mine])
        at[np.searchsorted(epochs, unique)] = index[mine][first]
        if repeated:
            lines = gga_lines if kind_code == 0 else rmc_lines
            taken = np.zeros(int(mine.sum()), bool)
            taken[first] = True
            notes.append(
                f"{source}: skipped {repeated} {name} sentence(s) repeating the time of one "
                f"before them (another talker, or a log written twice; "
                f"{_first_line(lines[index[mine][~taken]])})"
            )
    has_gga, has_rmc = gga_at >= 0, rmc_at >= 0

    def take(values: np.ndarray, at: np.ndarray) -> np.ndarray:
        """Each epoch's value of its sentence ``at`` (NaN where it has none)."""
        out = np.full(m, np.nan)
        out[at >= 0] = values[at[at >= 0]]
        return out

    lat_g = _angle(g[1], g[2], ("N", "S"), 90.0)
    lon_g = _angle(g[3], g[4], ("E", "W"), 180.0)
    lat_r = _angle(r[2], r[3], ("N", "S"), 90.0)
    lon_r = _angle(r[4], r[5], ("E", "W"), 180.0)
    latitude = np.where(has_gga, take(lat_g, gga_at), take(lat_r, rmc_at))
    longitude = np.where(has_gga, take(lon_g, gga_at), take(lon_r, rmc_at))
    quality_number = _numbers(g[5])
    quality = np.where(np.isfinite(quality_number), quality_number, 0.0)  # unreadable: invalid
    quality = np.where(has_gga, take(quality, gga_at), -1.0).astype(np.int64)
    rmc_ok = (r[1] == "A") & ~np.isin(r[11], UNUSABLE_MODES)
    rmc_valid = np.zeros(m, dtype=bool)
    rmc_valid[has_rmc] = rmc_ok[rmc_at[has_rmc]]
    lines = np.where(has_gga, take(gga_lines, gga_at), take(rmc_lines, rmc_at)).astype(np.int64)

    # Heading: HDT/THS belong to the epoch of the last GGA/RMC before them.
    heading = np.full(m, np.nan)
    skipped_heading = 0
    for name in HEADING_TYPES:
        rows = found.data[name]
        if not rows:
            continue
        value_column, flag = _columns(rows, 2)
        value = _numbers(value_column)
        ok = np.isfinite(value) & (value >= 0) & (value <= 360)
        if name == "THS":
            ok &= flag != "V"
        before = np.searchsorted(seq, np.asarray(found.seq[name]), side="right") - 1
        ok &= before >= 0
        skipped_heading += int((before < 0).sum())
        epoch = np.searchsorted(epochs, key[np.maximum(before, 0)])[ok]
        unique, first = np.unique(epoch, return_index=True)  # the epoch's first one
        fresh = np.isnan(heading[unique])  # HDT before THS
        heading[unique[fresh]] = value[ok][first[fresh]]
    if skipped_heading:
        notes.append(
            f"{source}: skipped {skipped_heading} heading sentence(s) before the first GGA/RMC "
            "(a heading belongs to the epoch of the last GGA/RMC before it)"
        )
    hdop = take(_numbers(g[7]), gga_at)
    satellites = take(_numbers(g[6]), gga_at)
    speed = take(_numbers(r[6]) * KNOT, rmc_at)
    course = take(_numbers(r[7]), rmc_at)
    counts = dict(found.counts)
    return NmeaLog(
        t=epochs / 1000.0,
        latitude=latitude,
        longitude=longitude,
        heading=heading,
        quality=quality,
        rmc_valid=rmc_valid,
        has_rmc=has_rmc,
        hdop=hdop,
        satellites=satellites,
        speed=speed,
        course=course,
        lines=lines,
        counts=counts,
        notes=tuple(notes),
    )


def _no_fix_sentence(found: _Sentences) -> str:
    """Why a log gives no fix: what it holds instead."""
    others = ", ".join(f"{n} {k}" for k, n in found.counts.most_common(6))
    bad = len(found.bad_checksum)
    if bad:
        return (
            f"no GGA or RMC sentence with a valid checksum ({bad} fail theirs, first: line "
            f"{found.bad_checksum[0]}); is the log corrupt or cut?"
        )
    if found.unparsable:
        line, why = found.unparsable[0]
        return f"no GGA or RMC sentence that parses (line {line}: {why})"
    if others:
        return (
            f"no GGA or RMC sentence (found {others}); [gnss] nmea needs the receiver's GGA "
            "or RMC position sentences: enable them in its output"
        )
    start = f" (it starts with {found.first_text!r})" if found.first_text else " (it is empty)"
    return (
        f"no NMEA sentence in {found.lines_read} line(s){start}; [gnss] nmea needs a "
        "receiver's NMEA 0183 log (lines like $GPGGA,...)"
    )


def _summary(log: NmeaLog, kept: np.ndarray, source: str) -> str:
    """One note: the kept fixes' qualities, HDOP and satellites, and that HDOP is no weight."""
    counts = log.counts
    parts = [f"{int(kept.sum())} fixes from {counts.get('GGA', 0)} GGA, {counts.get('RMC', 0)} RMC"]
    heading = sum(counts.get(k, 0) for k in HEADING_TYPES)
    if heading:
        parts[0] += f", {heading} HDT/THS"
    quality = log.quality[kept]
    if (quality >= 0).any():
        numbers, tally = np.unique(quality[quality >= 0], return_counts=True)
        parts.append(
            "quality "
            + ", ".join(
                f"{FIX_QUALITY.get(int(q), 'unknown')} ({int(q)}) {n / len(quality):.0%}"
                for q, n in zip(numbers, tally, strict=True)
            )
        )
    hdop = log.hdop[kept]
    hdop = hdop[np.isfinite(hdop)]
    if len(hdop):
        parts.append(
            f"HDOP median {np.median(hdop):.2g}, 95% {np.percentile(hdop, 95):.2g}, max "
            f"{hdop.max():.2g}"
        )
    satellites = log.satellites[kept]
    satellites = satellites[np.isfinite(satellites)]
    if len(satellites):
        parts.append(
            f"{satellites.min():.0f}–{satellites.max():.0f} satellites (median "
            f"{np.median(satellites):.0f})"
        )
    return (
        f"{source}: " + "; ".join(parts) + " (every fix is weighted alike, by the vehicle's "
        "position_sigma: HDOP and quality are reported, not used)"
    )


def _dropped(log: NmeaLog, usable: np.ndarray, source: str) -> list[str]:
    """Notes on the fixes left out, by reason."""
    notes = []
    for q in sorted(set(log.quality[~usable & (log.quality >= 0)].tolist())):
        mine = ~usable & (log.quality == q)
        if q in USABLE_QUALITY:  # a usable quality without a readable position
            what = "GGA without a readable position"
        else:
            what = f"fix quality {q} ({FIX_QUALITY.get(q, 'unknown')})"
        notes.append(
            f"{source}: dropped {int(mine.sum())} fix(es) with {what} "
            f"({_first_line(log.lines[mine])})"
        )
    rmc_only = ~usable & (log.quality < 0)
    if rmc_only.any():
        notes.append(
            f"{source}: dropped {int(rmc_only.sum())} RMC-only fix(es) with status V, mode N/E/M "
            f"or no position ({_first_line(log.lines[rmc_only])})"
        )
    return notes


def read_nmea_pose(manifest: Any, section: str, table: dict, notes: list[str]) -> PoseStream:
    """The pose stream of a manifest section with ``nmea = "receiver.nmea"`` (module
    docstring): usable fixes in a local east/north frame [m] around the first one, a true
    heading [rad, ENU] where every fix has one; ``notes`` gets what was skipped or dropped.

    Args:
        manifest: the :class:`graphcal.data.manifest.Manifest` (its path, errors, numbers).
        section: ``"gnss"`` or ``"pose"``.
        table: the section's keys.
        notes: the recording's notes, appended to.
    """
    extra = sorted(set(table) - set(NMEA_KEYS))
    if extra:
        raise manifest.error(
            f"[{section}] {', '.join(extra)}: not used with nmea = ...; an NMEA log's sentences "
            f"give the time, position and heading (keys: {', '.join(NMEA_KEYS)})"
        )
    name = table["nmea"]
    if not isinstance(name, str) or not name:
        raise manifest.error(f"[{section}] nmea must be the NMEA log's path (text), got {name!r}")
    date = table.get("date")
    if date is not None:
        if isinstance(date, str):
            try:
                date = datetime.date.fromisoformat(date)
            except ValueError:
                date = None
        if not isinstance(date, datetime.date) or isinstance(date, datetime.datetime):
            raise manifest.error(
                f'[{section}] date = {table["date"]!r}: give the UTC date as "YYYY-MM-DD"'
            )
    use_heading = table.get("heading", True)
    if use_heading is not False and use_heading is not True:
        raise manifest.error(
            f"[{section}] heading = {use_heading!r}: with nmea, heading = false ignores the "
            "HDT/THS heading (the log's sentences name the fields)"
        )
    offset = manifest.number(table, "time_offset", 0.0, section)
    path = manifest.resolve(name)
    source = str(path)
    if not path.is_file():
        raise StreamError(
            f"{source}: no such file (named in {manifest.source} [{section}] nmea); check the path"
        )
    try:
        log = read_nmea(path, date, date_key=f"[{section}] date", manifest=manifest.source)
    except OSError as exc:
        raise StreamError(f"{source}: cannot read ({exc.strerror or exc})") from None
    notes.extend(log.notes)
    usable = log.usable()
    notes.extend(_dropped(log, usable, source))
    if usable.sum() < 2:
        raise StreamError(
            f"{source}: {int(usable.sum())} usable fix(es) of {len(usable)} epochs (fix quality "
            f"0, 6 or 7, or RMC status V); a pose stream needs many: log where the receiver "
            "has a fix"
        )
    notes.append(_summary(log, usable, source))
    fields = {
        "time": Field("UTC time", f"[{section}] nmea", "s since 1970 (RMC date or date)"),
        "latitude": Field("GGA/RMC latitude", f"[{section}] nmea", "degrees WGS-84"),
        "longitude": Field("longitude", f"[{section}] nmea", "degrees WGS-84"),
        "heading": Field("HDT/THS heading", f"[{section}] nmea", "degrees true"),
    }
    heading_advice = (
        "the heading is the receiver's true heading (HDT/THS, the direction of its antennas' "
        "baseline): check that the baseline points along the car (the receiver's heading "
        f"offset), or set [{section}] heading = false to use the GNSS course"
    )
    provenance = SentenceProvenance(
        file=source,
        fields=fields,
        lines=log.lines[usable],
        section=f"[{section}]",
        quality=log.quality[usable],
        hdop=log.hdop[usable],
        advice={
            "position": (
                "check the receiver's fix there (its GGA fix quality, HDOP, satellites); "
                "delete the sentences of a bad fix"
            ),
            "heading": heading_advice,
            "mirrored": "rear_left and rear_right swapped (an NMEA log's track is not)",
        },
    )
    latitude, longitude = log.latitude[usable], log.longitude[usable]
    x, y, origin = geodetic_to_local(latitude, longitude, source, provenance=provenance)
    psi = None
    headings = log.heading[usable]
    logged = np.isfinite(headings)
    if logged.any() and use_heading:
        if logged.all():
            psi = np.radians(90.0 - headings)
        else:
            notes.append(
                f"{source}: HDT/THS heading at {int(logged.sum())} of {len(logged)} fixes "
                f"({_first_line(log.lines[usable][~logged])} has none): positions only are "
                "used (the GNSS course)"
            )
    elif logged.any():
        notes.append(f"{source}: HDT/THS heading ignored ([{section}] heading = false)")
    if log.counts.get("VTG") and psi is None:
        notes.append(
            f"{source}: VTG course over ground is the direction of travel, not the heading; "
            "not used (the course comes from the positions)"
        )
    return PoseStream(
        t=log.t[usable] + offset,
        x=x,
        y=y,
        heading=psi,
        sideslip=None,
        source=source,
        origin=origin,
        provenance=provenance,
    )
