"""The sentences of a receiver's NMEA 0183 log, read with pynmea2 and turned into numbers.

pynmea2 (the optional extra ``graphcal[nmea]``, imported only here) checks each sentence's
checksum and splits it into fields (THS, which it does not know, is checked here); the
fields are turned into numbers for the whole log at once (numpy), so a 3-hour 10 Hz log
(over 200,000 sentences) reads in a few seconds. A sentence with a wrong or missing
checksum, or that does not parse, is counted, never fatal; other sentence types (GSV, GSA,
VTG, proprietary ones) are counted and skipped; text before a ``$`` on a line (a logger's
time stamp) is ignored.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.recording.streams import StreamError

#: Sentence types (after the two-letter talker) that are read.
POSITION_TYPES = ("GGA", "RMC")
HEADING_TYPES = ("HDT", "THS")
_MISSING_PYNMEA2 = 'reading NMEA logs needs the pynmea2 package: pip install -e ".[nmea]"'


def _import_pynmea2():
    try:
        import pynmea2
    except ImportError:
        raise StreamError(_MISSING_PYNMEA2) from None
    return pynmea2


@dataclass
class Sentences:
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


def scan(path: Path) -> Sentences:
    """Read the log's lines: checksum-checked fields of GGA, RMC, HDT and THS; counts of the
    rest."""
    pynmea2 = _import_pynmea2()
    found = Sentences()
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


def text_columns(rows: list[list[str]], count: int) -> list[np.ndarray]:
    """The first ``count`` fields of each sentence as text columns ('' where missing)."""
    return [
        np.array([row[k] if len(row) > k else "" for row in rows], dtype=object)
        for k in range(count)
    ]


def numbers(column: np.ndarray) -> np.ndarray:
    """A text column as floats, NaN where a field is not a number."""
    return np.asarray(pd.to_numeric(column, errors="coerce"), dtype=float)


def time_of_day(column: np.ndarray) -> np.ndarray:
    """``hhmmss.ss`` → milliseconds of the day (int64), −1 where it does not parse."""
    value = numbers(column)
    hours = np.floor(value / 10_000.0)
    minutes = np.floor(value / 100.0) - 100.0 * hours
    seconds = value - 10_000.0 * hours - 100.0 * minutes
    ok = np.isfinite(value) & (value >= 0) & (hours < 24) & (minutes < 60) & (seconds < 61)
    ms = np.round((3600.0 * hours + 60.0 * minutes + seconds) * 1000.0)
    return np.where(ok, ms, -1).astype(np.int64)


def angle(column: np.ndarray, hemisphere: np.ndarray, signs: tuple[str, str], limit: float):
    """``ddmm.mmmm`` / ``dddmm.mmmm`` with N/S (E/W) → signed degrees; NaN where it does not
    parse (an empty field: no fix)."""
    value = numbers(column)
    degrees = np.floor(value / 100.0)
    minutes = value - 100.0 * degrees
    positive, negative = signs
    sign = np.where(hemisphere == positive, 1.0, np.where(hemisphere == negative, -1.0, np.nan))
    angle = sign * (degrees + minutes / 60.0)
    ok = np.isfinite(angle) & (minutes < 60.0) & (np.abs(angle) <= limit)
    return np.where(ok, angle, np.nan)


def dates(column: np.ndarray) -> np.ndarray:
    """RMC's ``ddmmyy`` → days since 1970-01-01 (int64), −1 where it does not parse."""
    parsed = pd.to_datetime(pd.Series(column, dtype=object), format="%d%m%y", errors="coerce")
    days = parsed.to_numpy(dtype="datetime64[D]").astype(np.int64)
    return np.where(parsed.isna().to_numpy(), -1, days)


def first_line_text(lines: list[int] | np.ndarray) -> str:
    """``first: line 12``: the first of ``lines`` (file lines, 1-based), for a note."""
    return f"first: line {int(np.min(lines))}"


def no_fix_sentence(found: Sentences) -> str:
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
