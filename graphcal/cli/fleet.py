"""``graphcal fleet``: calibrate a fleet's logs on Dask and find changes of theta."""

from __future__ import annotations

import argparse
from pathlib import Path

from graphcal import default_workers, vehicle_settings_in
from graphcal.cli.arguments import in_range, value_option, whole
from graphcal.cli.options import (
    add_segment_options,
    add_vehicle_option,
    settings_from_args,
    timed_progress,
)

NAME = "fleet"
HELP = "calibrate a fleet's logs on Dask and find changes of theta"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The fleet's source, ``--out``, the Dask cluster, the test's false-alarm probability,
    the settings file, and the segment and vehicle options."""
    p.add_argument(
        "source",
        type=Path,
        help="a directory VEHICLE/DAY.csv (VEHICLE/vehicle.toml: that vehicle's profile) or a "
        "CSV manifest with columns vehicle, day, path (and optionally profile)",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="result directory (kept between runs: resumable)"
    )
    value_option(
        p,
        "--workers",
        whole(1),
        "N",
        "worker processes of the local Dask cluster (default: one per core)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="a running Dask scheduler (tcp://HOST:8786) instead of a local cluster",
    )
    p.add_argument(
        "--alpha",
        type=in_range(1e-12, 0.5, "probability"),
        default=1e-3,
        help="false-alarm probability of each day's test for a change of theta (0.001)",
    )
    value_option(
        p,
        "--config",
        Path,
        "FILE",
        "TOML settings file for every log (see graphcal/pipeline/configuration/settings.py)",
    )
    p.add_argument("--no-progress-bar", action="store_true", help="progress lines instead of a bar")
    add_segment_options(p)
    add_vehicle_option(p)


def run(args: argparse.Namespace) -> int:
    """Calibrate every log of a fleet on Dask; per vehicle, changes of theta over days."""
    from graphcal import FleetOptions, run_fleet

    settings = settings_from_args(args)
    keep = vehicle_settings_in(args.config) if args.config else set()
    say = timed_progress()
    fleet = run_fleet(
        args.source,
        args.out,
        settings,
        FleetOptions(
            workers=args.workers or default_workers(),
            scheduler=args.scheduler,
            alpha=args.alpha,
            keep=keep,
            bar=not args.no_progress_bar,
        ),
        progress=say,
    )
    say(f"wrote {', '.join(p.name for p in fleet.written)} to {Path(args.out)}")
    for line in fleet.summary():
        print(line)
    return 0
