"""``graphcal simulate --fleet DIR``: a synthetic fleet with per-vehicle truths and one change."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graphcal import GraphcalError, Progress
from graphcal.cli.arguments import value_option, whole

if TYPE_CHECKING:
    from graphcal import FleetChange


#: ``--change`` when not given: v3's c_e 3 mm lower from day 3 on.
DEFAULT_CHANGE = "3:3:-3"


def add_fleet_options(p: argparse.ArgumentParser) -> None:
    """``--fleet DIR`` with its ``--vehicles``, ``--days`` and ``--change``."""
    value_option(
        p,
        "--fleet",
        Path,
        "DIR",
        "instead of one drive, a synthetic fleet in DIR (VEHICLE/DAY.csv, each with its "
        "truth, and fleet_truth.csv) for `graphcal fleet`",
    )
    p.add_argument("--vehicles", type=whole(1), default=6, help="with --fleet: vehicles (6)")
    p.add_argument("--days", type=whole(1), default=3, help="with --fleet: days (3)")
    p.add_argument(
        "--change",
        default=None,
        metavar="V:DAY:MM",
        help=f"with --fleet: vehicle V's c_e changes by MM mm from day DAY on, or none "
        f"(default {DEFAULT_CHANGE} where the fleet has that vehicle and day, else none)",
    )


def simulate_fleet_command(args: argparse.Namespace, say: Progress) -> int:
    """``simulate --fleet DIR``: a synthetic fleet with per-vehicle truths and one change."""
    from graphcal import simulate_fleet

    others = [name for name in ("out", "streams", "defects") if getattr(args, name) is not None]
    if others:
        raise GraphcalError(
            f"--fleet writes a fleet of clean drives at the paper's noise; it does not take "
            f"{', '.join('--' + n for n in others)}"
        )
    text = args.change
    if text is None:  # the default change, where the fleet has its vehicle and day
        vehicle, day, _ = (int(part) for part in DEFAULT_CHANGE.split(":"))
        inside = vehicle <= args.vehicles and day <= args.days
        text = DEFAULT_CHANGE if inside else "none"
    change = _change(text)
    length_km = 4.0 if args.length_km is None else args.length_km
    try:
        truth = simulate_fleet(args.fleet, args.vehicles, args.days, length_km, args.seed, change)
    except ValueError as exc:
        raise GraphcalError(f"--fleet: {exc}") from None
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.fleet}: {exc.strerror or exc}") from exc
    what = (
        "no change"
        if change is None
        else f"c_e {text.split(':')[2]} mm on v{change.vehicle} from day{change.day}"
    )
    say(
        f"wrote a fleet of {args.vehicles} vehicles × {args.days} days of {length_km:g} km "
        f"({what}) to {args.fleet}; truths in {truth.name}"
    )
    return 0


def _change(text: str) -> FleetChange | None:
    """``--change VEHICLE:DAY:C_E_MM`` as a :class:`graphcal.FleetChange`, or ``None``."""
    from graphcal import FleetChange

    if text.lower() == "none":
        return None
    try:
        vehicle, day, millimetres = text.split(":")
        return FleetChange(
            int(vehicle.lstrip("v")),
            int(day.removeprefix("day")),
            np.array([float(millimetres) * 1e-3, 0.0, 0.0, 0.0]),
        )
    except ValueError:
        raise GraphcalError(
            f"--change {text}: expected VEHICLE:DAY:C_E_MM (e.g. 3:3:-3 or v3:day3:-3) or none"
        ) from None
