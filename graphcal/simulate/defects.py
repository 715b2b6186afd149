"""Defects of real drive logs, added to a synthetic drive with the truth kept.

:func:`degrade` rebuilds a :class:`~graphcal.simulate.drive.SyntheticDrive`'s measured log
from its noise-free truth, the drive's own white noise (measured − truth) and the defects of
a :class:`Defects`; :func:`parse_defects` reads them from text such as
``"outliers,latency=0.1,lever_arm=1.5"`` (``graphcal simulate --defects``).

Order in which the defects act (each on the result of the one before):

* wheels: true rotation → per-wheel slip (relative scale) → latency (the cumulative rotation
  read ``latency`` earlier) → tick quantization of the cumulative rotation → the drive's own
  white wheel noise;
* position: true centre of gravity → antenna lever arm → GNSS fixes at ``gnss_rate`` with
  white noise (the drive's own noise when every log sample is a fix) → multipath outliers on
  the fixes → outages (fixes held or missing) → fixes to the log rate (interpolated, or
  sample-and-hold);
* heading: true heading → slow bias + white noise (the drive's own white noise unless
  ``heading_white`` replaces it); a fused heading comes from the INS, so the GNSS rate and
  holding outages leave it alone, and only a true dropout (the pose stream silent) bridges it;
* sideslip, lateral acceleration and time are the drive's own.

:mod:`graphcal.simulate.defect_effects` applies them. Every random choice comes from
``seed``: one :class:`numpy.random.SeedSequence` child per defect (spawned from
``[seed, 13]``, apart from the drive's own streams), always all of them, so switching one
defect on does not change another's realisation.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from graphcal.log.drive_log import DriveLog
from graphcal.simulate.defect_effects import defective_pose, defective_wheels
from graphcal.simulate.defect_settings import (
    DEFECT_NAMES,
    DEFECTS,
    DEFECTS_IN_ALL,
    HEADING_BIAS_RATE,
    HEADING_WHITE,
    Defects,
)

if TYPE_CHECKING:
    from graphcal.simulate.drive import SyntheticDrive

#: The random streams, one per defect, in spawn order (never reorder: it changes seeds).
_STREAMS = ("gnss", "outliers", "outages", "heading", "slip", "ticks")


def _knob(name: str, value: str | None, whole: bool = False) -> float | None:
    if value is None:
        return None
    try:
        number = float(value)
    except ValueError:
        raise ValueError(f"defect {name}={value}: not a number") from None
    if not np.isfinite(number) or (whole and number != int(number)):
        kind = "a whole number" if whole else "a finite number"
        raise ValueError(f"defect {name}={value}: must be {kind}")
    return number


def _switch(name: str, value: str | None, fields: dict) -> None:
    """Switch defect ``name`` on in ``fields`` (Defects keywords), at its default or ``value``."""
    if name in ("gnss10hz", "hold", "interpolated"):
        rate = _knob(name, value)
        if rate is not None or fields.get("gnss_rate") is None:
            fields["gnss_rate"] = 10.0 if rate is None else rate
        fields["gnss_hold"] = name == "hold"
        fields["gnss_interpolate"] = name == "interpolated"
    elif name == "outliers":
        share = _knob(name, value)
        fields["outlier_share"] = 0.005 if share is None else share
    elif name in ("outages", "dropouts"):
        count = _knob(name, value, whole=True)
        fields["outages"] = 2 if count is None else int(count)
        fields["outage_hold"] = name == "outages"
    elif name == "heading_bias":
        rate = _knob(name, value)
        fields["heading_bias_rate"] = HEADING_BIAS_RATE if rate is None else rate
        fields["heading_white"] = HEADING_WHITE
    elif name == "latency":
        latency = _knob(name, value)
        fields["latency"] = 0.05 if latency is None else latency
    elif name == "lever_arm":
        if value is None:
            fields["lever_arm"] = (1.2, 0.0)
        else:
            parts = value.split(":")
            if len(parts) > 2:
                raise ValueError(f"defect lever_arm={value}: give LONGITUDINAL[:LATERAL] metres")
            arm = [_knob(name, p) for p in parts]
            fields["lever_arm"] = (float(arm[0]), float(arm[1]) if len(arm) == 2 else 0.0)
    elif name == "ticks":
        ticks = _knob(name, value, whole=True)
        fields["ticks_per_revolution"] = 96 if ticks is None else int(ticks)
    elif name == "slip":
        sigma = _knob(name, value)
        fields["slip_sigma"] = 0.0015 if sigma is None else sigma


def parse_defects(text: str) -> Defects:
    """Defects from a comma-separated list, e.g. ``"outliers,latency=0.1,lever_arm=1.5"``.

    A name switches that defect on at its realistic default; ``name=value`` sets its main
    knob (SI units, :data:`DEFECTS`); ``lever_arm=LONG:LAT`` both of its components. ``all``
    switches on every name of :data:`DEFECTS_IN_ALL`; names after it override it (``all,hold``,
    ``all,dropouts``, ``all,latency=0.1``). ``outages`` and ``dropouts`` together are refused
    (both set the one kind of outage), as are ``gnss10hz`` and ``hold``. Empty or ``none``:
    no defect.

    Raises:
        ValueError: one line, for an unknown name (listing the known ones) or a bad value.
    """
    fields: dict = {}
    explicit: set[str] = set()
    for entry in (e.strip() for e in text.split(",")):
        if not entry or entry.lower() == "none":
            continue
        name, _, value = entry.partition("=")
        name, value = name.strip().lower(), value.strip() if "=" in entry else None
        if name == "all" and value is None:
            for each in DEFECTS_IN_ALL:
                _switch(each, None, fields)
            continue
        if name not in DEFECTS:
            raise ValueError(
                f"unknown defect {name!r}; known: all, {', '.join(DEFECT_NAMES)} "
                "(name=value sets its size)"
            )
        for pair in (("outages", "dropouts"), ("gnss10hz", "hold")):
            other = pair[1 - pair.index(name)] if name in pair else None
            if other in explicit:
                raise ValueError(f"defects {other} and {name} exclude each other; choose one")
        explicit.add(name)
        _switch(name, value, fields)
    try:
        return Defects(**fields)
    except ValueError as exc:
        raise ValueError(str(exc).removeprefix("Defects: ")) from None


def degrade(drive: SyntheticDrive, defects: Defects, seed: int) -> SyntheticDrive:
    """``drive`` with ``defects`` in its measured log; the truth and ``theta_true`` kept.

    The measured log is rebuilt from the noise-free truth, the drive's own white noise
    (measured − truth) and the defects, in the order of the module docstring, so
    ``Defects()`` gives the drive's measured log back. A true dropout marks its samples in the
    log's ``masked`` (with a note); ``write_drive_log`` writes them as the ``masked`` column.

    Args:
        drive: a drive from :func:`~graphcal.simulate.drive.simulate_drive`, not yet degraded.
        defects: which defects, how large.
        seed: seed of every random choice of the defects (independent of the drive's seed).

    Returns:
        a new drive with ``defects`` and ``defect_seed`` recorded.

    Raises:
        ValueError: a drive already degraded, or too short for the outages.
    """
    if drive.defects is not None:
        raise ValueError("the drive already has defects; degrade the clean drive")
    children = np.random.SeedSequence([int(seed), 13]).spawn(len(_STREAMS))
    rngs = {name: np.random.default_rng(s) for name, s in zip(_STREAMS, children, strict=True)}
    wheels = defective_wheels(drive, defects, rngs)
    px, py, psi, masked, notes, sparse = defective_pose(drive, defects, rngs)
    clean = drive.measured
    measured = DriveLog(
        t=clean.t.copy(),
        px=px,
        py=py,
        psi=psi,
        n_rl=wheels[:, 0],
        n_rr=wheels[:, 1],
        beta=clean.beta.copy(),
        ay=clean.ay.copy(),
        source=clean.source,
        masked=masked,
        mask_notes=notes,
        **sparse,
    )
    return dataclasses.replace(drive, measured=measured, defects=defects, defect_seed=int(seed))
