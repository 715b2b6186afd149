"""``graphcal check``: validate a drive log (or a recording, imported in memory) and
summarize it."""

from __future__ import annotations

import argparse

from graphcal import (
    log_check_lines,
    log_excitation_lines,
    log_masked_lines,
    open_log,
    recording_path,
)
from graphcal.cli.options import (
    add_recording_options,
    add_segment_options,
    add_vehicle_option,
    check_recording_options,
    recording_keywords,
    settings_from_args,
)

NAME = "check"
HELP = "validate a drive log and summarize it"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The log, and the segment, recording and vehicle options."""
    p.add_argument("log", type=recording_path, help="drive-log CSV, streams manifest or ROS bag")
    add_segment_options(p)
    add_recording_options(p)
    add_vehicle_option(p)


def run(args: argparse.Namespace) -> int:
    """Validate a drive log (or a manifest or bag, imported in memory) and summarize it."""
    check_recording_options(args, args.log)
    settings = settings_from_args(args)
    log, imported = open_log(  # too short for one segment: refused as calibrate refuses it
        args.log,
        settings.vehicle,
        min_distance=settings.segments.length,
        **recording_keywords(args),
    )
    summary = log_check_lines(log, settings)
    print(f"{args.log}: valid {'recording' if imported else 'drive log'}")
    if imported is not None:
        for line in imported.lines():
            print(f"  {line}")
    for line in summary:
        print(line)
    for line in [*log_excitation_lines(log, settings), *log_masked_lines(log)]:
        print(line)
    for warning in imported.warnings if imported is not None else ():
        print(f"warning: {warning}")
    return 0
