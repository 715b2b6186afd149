"""A synthetic receiver's NMEA 0183 log of a simulated recording's GNSS fixes.

:func:`receiver_fixes` puts the GNSS fixes of
:func:`graphcal.simulate.streams.simulate_streams` on a receiver's epochs: each fix's UTC
time rounded to the centisecond (what ``hhmmss.ss`` holds), its position and heading the
drive's at that time plus the recording's own noise of that fix, and the speed and course
over ground. :func:`nmea_lines` formats fixes as GGA + RMC (and optionally HDT) sentences
with correct checksums, latitude and longitude as ``ddmm.mmmmmmm`` (7 decimals of minutes:
0.19 mm), and :func:`write_nmea` writes the log; :func:`nmea_manifest` is the recording's
manifest with ``[gnss] nmea = ...`` instead of ``gnss.csv``.
"""

from __future__ import annotations

import datetime
import os
from functools import reduce
from operator import xor
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.files import atomic_write_text
from graphcal.recording.geodesy import geodetic_to_local, local_to_geodetic
from graphcal.simulate.streams import EPOCH, SyntheticRecording, replace_section

#: Knots in m/s.
KNOT = 1852.0 / 3600.0
#: Units of 1e-7 minutes in a degree (the 7 decimals of ``ddmm.mmmmmmm``).
_UNITS_PER_DEGREE = 60 * 10**7
#: RMC mode indicator (NMEA 2.3) of each GGA fix quality.
_MODE = {1: "A", 2: "D", 3: "P", 4: "R", 5: "F", 8: "S"}


def checksum(body: str) -> str:
    """The NMEA checksum of ``body`` (the text between ``$`` and ``*``): two hex digits."""
    return f"{reduce(xor, body.encode('ascii'), 0):02X}"


def sentence(body: str) -> str:
    """``$<body>*<checksum>``."""
    return f"${body}*{checksum(body)}"


def receiver_fixes(sim: SyntheticRecording, quality: int = 5, seed: int = 0) -> pd.DataFrame:
    """The recording's GNSS fixes on a receiver's epochs (module docstring).

    Args:
        sim: a recording of :func:`~graphcal.simulate.streams.simulate_streams`.
        quality: the GGA fix quality written (5: RTK float, decimetres, as the recording's
            0.2 m position noise).
        seed: of the HDOP and satellite counts.

    Returns:
        columns ``t`` [s, Unix time UTC, whole centiseconds], ``lat``, ``lon`` [deg WGS-84],
        ``heading`` [deg, compass], ``speed`` [m/s] and ``course`` [deg, compass] over
        ground, ``quality``, ``hdop`` [-], ``satellites``.
    """
    truth = sim.drive.truth
    origin = sim.settings.origin
    t_fine = EPOCH + truth.t
    gnss = sim.gnss
    t = gnss["t"].to_numpy()
    epochs = np.round(t * 100.0) / 100.0
    east, north, _ = geodetic_to_local(
        gnss["lat"].to_numpy(), gnss["lon"].to_numpy(), "gnss", origin
    )
    # the recording's noise of each fix, moved with it to the receiver's epoch
    east = east - np.interp(t, t_fine, truth.px) + np.interp(epochs, t_fine, truth.px)
    north = north - np.interp(t, t_fine, truth.py) + np.interp(epochs, t_fine, truth.py)
    lat, lon = local_to_geodetic(east, north, origin)
    psi = np.radians(90.0 - gnss["heading"].to_numpy())
    psi_truth = np.unwrap(truth.psi)
    psi = psi - np.interp(t, t_fine, psi_truth) + np.interp(epochs, t_fine, psi_truth)
    mid = 0.5 * (t_fine[1:] + t_fine[:-1])
    vx = np.interp(epochs, mid, np.diff(truth.px) / np.diff(t_fine))
    vy = np.interp(epochs, mid, np.diff(truth.py) / np.diff(t_fine))
    rng = np.random.default_rng(seed)
    return pd.DataFrame(
        {
            "t": epochs,
            "lat": lat,
            "lon": lon,
            "heading": np.mod(90.0 - np.degrees(psi), 360.0),
            "speed": np.hypot(vx, vy),
            "course": np.mod(90.0 - np.degrees(np.arctan2(vy, vx)), 360.0),
            "quality": np.full(len(t), quality),
            "hdop": np.round(0.6 + 0.5 * rng.random(len(t)), 2),
            "satellites": rng.integers(11, 19, len(t)),
        }
    )


def _angles(degrees: np.ndarray, width: int, signs: str) -> list[str]:
    """``ddmm.mmmmmmm,N`` (``width`` digits of degrees), exact to 1e-7 minutes."""
    units = np.round(np.abs(degrees) * _UNITS_PER_DEGREE).astype(np.int64)
    whole, rest = np.divmod(units, _UNITS_PER_DEGREE)
    minutes, fraction = np.divmod(rest, 10**7)
    hemisphere = np.where(degrees < 0, signs[1], signs[0])
    return [
        f"{d:0{width}d}{m:02d}.{f:07d},{h}"
        for d, m, f, h in zip(whole, minutes, fraction, hemisphere, strict=True)
    ]


def _times(t: np.ndarray) -> tuple[list[str], list[str]]:
    """UTC ``hhmmss.ss`` and ``ddmmyy`` of Unix times [s]."""
    centis = np.round(np.asarray(t) * 100.0).astype(np.int64)
    days, of_day = np.divmod(centis, 8_640_000)
    hours, rest = np.divmod(of_day, 360_000)
    minutes, rest = np.divmod(rest, 6000)
    seconds, hundredths = np.divmod(rest, 100)
    times = [
        f"{h:02d}{m:02d}{s:02d}.{c:02d}"
        for h, m, s, c in zip(hours, minutes, seconds, hundredths, strict=True)
    ]
    start = datetime.date(1970, 1, 1)
    dates = {d: (start + datetime.timedelta(days=int(d))).strftime("%d%m%y") for d in set(days)}
    return times, [dates[d] for d in days]


def nmea_lines(
    fixes: pd.DataFrame, *, rmc: bool = True, hdt: bool = False, talker: str = "GN"
) -> list[str]:
    """The sentences of ``fixes`` (columns of :func:`receiver_fixes`), per fix a GGA, an RMC
    (``rmc``) and an HDT (``hdt``), with correct checksums."""
    times, dates = _times(fixes["t"].to_numpy())
    lats = _angles(fixes["lat"].to_numpy(), 2, "NS")
    lons = _angles(fixes["lon"].to_numpy(), 3, "EW")
    lines = []
    for k, row in enumerate(fixes.itertuples(index=False)):
        quality = int(row.quality)
        lines.append(
            sentence(
                f"{talker}GGA,{times[k]},{lats[k]},{lons[k]},{quality},"
                f"{int(row.satellites):02d},{row.hdop:.2f},120.000,M,41.500,M,,"
            )
        )
        if rmc:
            lines.append(
                sentence(
                    f"{talker}RMC,{times[k]},A,{lats[k]},{lons[k]},{row.speed / KNOT:.3f},"
                    f"{row.course:.2f},{dates[k]},,,{_MODE.get(quality, 'A')}"
                )
            )
        if hdt:
            lines.append(sentence(f"{talker}HDT,{row.heading:.2f},T"))
    return lines


def write_nmea(
    fixes: pd.DataFrame,
    path: str | os.PathLike[str],
    *,
    rmc: bool = True,
    hdt: bool = False,
    talker: str = "GN",
) -> Path:
    """Write the NMEA log of ``fixes`` (:func:`nmea_lines`), CR LF line ends as a receiver's."""
    text = "\r\n".join(nmea_lines(fixes, rmc=rmc, hdt=hdt, talker=talker)) + "\r\n"
    return atomic_write_text(Path(path), text)


def nmea_manifest(sim: SyntheticRecording, nmea: str = "receiver.nmea", **keys: str) -> str:
    """The recording's manifest (:meth:`SyntheticRecording.manifest`) with a ``[gnss]`` that
    reads the NMEA log ``nmea``, plus ``keys`` (``date="2025-11-23"``)."""
    return replace_section(sim.manifest(), "gnss", nmea_section(nmea, **keys))


def nmea_section(nmea: str = "receiver.nmea", **keys: str) -> str:
    """A manifest's ``[gnss]`` section reading the NMEA log ``nmea`` (relative to the
    manifest), plus ``keys`` (``date="2025-11-23"``): positions only unless it has HDT."""
    extra = "".join(f'{key} = "{value}"\n' for key, value in keys.items())
    return f'[gnss]\nnmea = "{nmea}"\n{extra}'
