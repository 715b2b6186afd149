"""``graphcal import``: a streams manifest or a ROS bag into a drive-log CSV."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from graphcal import (
    GraphcalError,
    log_distance_line,
    log_excitation_lines,
    log_masked_lines,
    recording_path,
)
from graphcal.cli.options import (
    add_recording_options,
    add_segment_options,
    add_vehicle_option,
    bag_options,
    check_recording_options,
    settings_from_args,
    timed_progress,
)

NAME = "import"
HELP = "import a streams manifest or a ROS bag into a drive-log CSV"


class _PrintManifestKeys(argparse.Action):
    """``graphcal import --help-manifest``: print every manifest key with its default."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from graphcal import manifest_help

        print(manifest_help())
        parser.exit()


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The recording, ``--out``, ``--help-manifest``, and the recording, segment and vehicle
    options."""
    p.add_argument(
        "source",
        type=recording_path,
        help="streams manifest (.toml, or the directory holding manifest.toml), ROS 1 bag, "
        "ROS 2 bag, MCAP",
    )
    p.add_argument("--out", type=str, required=True, help="drive-log CSV to write (+ .json)")
    p.add_argument(
        "--help-manifest",
        action=_PrintManifestKeys,
        help="print every key of a streams manifest, with its default, and exit",
    )
    add_recording_options(p)
    add_segment_options(p)
    add_vehicle_option(p)


def run(args: argparse.Namespace) -> int:
    """Import a streams manifest (TOML) or a ROS 1/2 bag or MCAP file into a drive-log CSV."""
    from graphcal import check_import_output, import_recording, is_recording, write_import

    if is_recording(args.source):  # else import_recording says what it is not
        check_recording_options(args, args.source)
    settings = settings_from_args(args)
    check_import_output(args.source, args.out)
    out = Path(args.out)
    say = timed_progress()
    imported = import_recording(
        args.source,
        rate=args.rate,
        max_gap=args.max_gap,
        bag=bag_options(args),
        nominal=settings.vehicle.theta_nominal,
        reverses=settings.vehicle.reverses,
    )
    say(f"imported {args.source}")
    log = imported.log
    print(f"{args.source}: recording")
    for line in imported.lines():
        print(f"  {line}")
    distance = log_distance_line(log, settings.vehicle)
    print(f"  distance         {distance}, {log.t[-1] - log.t[0]:.1f} s")
    for line in [*log_excitation_lines(log, settings), *log_masked_lines(log)]:
        print(line)
    for warning in imported.warnings:
        print(f"warning: {warning}")
    try:
        written = write_import(imported, out)
    except OSError as exc:
        raise GraphcalError(
            f"cannot write {out}: {exc.strerror or exc}; nothing was written"
        ) from exc
    say(f"wrote {', '.join(str(p) for p in written)}")
    return 0


DESCRIPTION = (
    run.__doc__
    + " The manifest's keys are documented in graphcal/recording/manifest/manifest.py "
    + "(graphcal import --help-manifest) and the README."
)
