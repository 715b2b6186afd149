"""GNSS fixes from a receiver's NMEA 0183 log: ``[gnss] nmea = "receiver.nmea"``, as a pose
stream (:func:`read_nmea_pose`). The sentences are read by :mod:`graphcal.recording.nmea.sentences`
and joined into one fix per epoch by :mod:`graphcal.recording.nmea.fixes`.

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
"""

from __future__ import annotations

import dataclasses
import datetime
import itertools
from dataclasses import dataclass, field

import numpy as np

from graphcal.recording.geodesy import geodetic_to_local
from graphcal.recording.nmea.fixes import FIX_QUALITY, USABLE_QUALITY, NmeaLog, read_nmea
from graphcal.recording.nmea.sentences import HEADING_TYPES, first_line_text
from graphcal.recording.section import Section
from graphcal.recording.streams import Field, PoseStream, Provenance, StreamError

#: Manifest keys of a section that reads an NMEA log (and what they replace).
NMEA_KEYS = ("nmea", "date", "time_offset", "heading")


@dataclass(frozen=True)
class SentenceProvenance(Provenance):
    """The :class:`~graphcal.recording.streams.Provenance` of an NMEA log's fixes: each fix's line
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
            f"({first_line_text(log.lines[mine])})"
        )
    rmc_only = ~usable & (log.quality < 0)
    if rmc_only.any():
        notes.append(
            f"{source}: dropped {int(rmc_only.sum())} RMC-only fix(es) with status V, mode N/E/M "
            f"or no position ({first_line_text(log.lines[rmc_only])})"
        )
    return notes


def read_nmea_pose(table: Section, notes: list[str]) -> PoseStream:
    """The pose stream of a manifest section with ``nmea = "receiver.nmea"`` (module
    docstring): usable fixes in a local east/north frame [m] around the first one, a true
    heading [rad, ENU] where every fix has one; ``notes`` gets what was skipped or dropped.

    Args:
        table: the section (``gnss`` or ``pose``): its keys, file and errors.
        notes: the recording's notes, appended to.
    """
    section = table.name
    name, date, use_heading = _nmea_keys(table)
    offset = table.number("time_offset", 0.0)
    path = table.resolve(name)
    source = str(path)
    if not path.is_file():
        raise StreamError(
            f"{source}: no such file (named in {table.source} [{section}] nmea); check the path"
        )
    try:
        log = read_nmea(path, date, date_key=f"[{section}] date", manifest=table.source)
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
    provenance = _provenance(log, usable, source, section)
    latitude, longitude = log.latitude[usable], log.longitude[usable]
    x, y, origin = geodetic_to_local(latitude, longitude, source, provenance=provenance)
    psi = _heading(log, usable, use_heading, source, section, notes)
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


def _nmea_keys(table: Section) -> tuple[str, datetime.date | None, bool]:
    """The section's NMEA keys, checked: the log's path, the UTC ``date`` (or ``None``) and
    whether to use the heading."""
    section = table.name
    extra = sorted(set(table) - set(NMEA_KEYS))
    if extra:
        raise table.error(
            f"[{section}] {', '.join(extra)}: not used with nmea = ...; an NMEA log's sentences "
            f"give the time, position and heading (keys: {', '.join(NMEA_KEYS)})"
        )
    name = table["nmea"]
    if not isinstance(name, str) or not name:
        raise table.error(f"[{section}] nmea must be the NMEA log's path (text), got {name!r}")
    date = table.get("date")
    if date is not None:
        if isinstance(date, str):
            try:
                date = datetime.date.fromisoformat(date)
            except ValueError:
                date = None
        if not isinstance(date, datetime.date) or isinstance(date, datetime.datetime):
            raise table.error(
                f'[{section}] date = {table["date"]!r}: give the UTC date as "YYYY-MM-DD"'
            )
    use_heading = table.get("heading", True)
    if use_heading is not False and use_heading is not True:
        raise table.error(
            f"[{section}] heading = {use_heading!r}: with nmea, heading = false ignores the "
            "HDT/THS heading (the log's sentences name the fields)"
        )
    return name, date, use_heading


def _provenance(log: NmeaLog, usable: np.ndarray, source: str, section: str) -> SentenceProvenance:
    """The :class:`SentenceProvenance` of the usable fixes: their lines, quality and HDOP,
    and the log's own advice."""
    fields = {
        "time": Field("UTC time", f"[{section}] nmea", "s since 1970 (RMC date or date)"),
        "latitude": Field("GGA/RMC latitude", f"[{section}] nmea", "degrees WGS-84"),
        "longitude": Field("longitude", f"[{section}] nmea", "degrees WGS-84"),
        "heading": Field("HDT/THS heading", f"[{section}] nmea", "degrees true"),
    }
    heading_advice = (
        "the heading is the receiver's true heading (HDT/THS, the direction of its antennas' "
        "baseline): check that the baseline points along the car (the receiver's heading "
        f"offset), or set [{section}] heading = false to measure positions only"
    )
    return SentenceProvenance(
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


def _heading(
    log: NmeaLog,
    usable: np.ndarray,
    use_heading: bool,
    source: str,
    section: str,
    notes: list[str],
) -> np.ndarray | None:
    """The usable fixes' true heading [rad, ENU] when every one has one and it is used, else
    ``None`` (with a note if some have one)."""
    psi = None
    headings = log.heading[usable]
    logged = np.isfinite(headings)
    if logged.any() and use_heading:
        if logged.all():
            psi = np.radians(90.0 - headings)
        else:
            notes.append(
                f"{source}: HDT/THS heading at {int(logged.sum())} of {len(logged)} fixes "
                f"({first_line_text(log.lines[usable][~logged])} has none): positions only are "
                "used (the GNSS course)"
            )
    elif logged.any():
        notes.append(f"{source}: HDT/THS heading ignored ([{section}] heading = false)")
    return psi
