"""Options shared by several commands (segments, vehicle, recordings), the settings they
give, and the timed progress lines every command prints on stderr."""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from graphcal import (
    MANIFEST_SUFFIXES,
    SPEED_UNITS,
    WHEEL_KINDS,
    BagOptions,
    GraphcalError,
    Progress,
    Settings,
    configure_settings,
    is_recording,
)
from graphcal.cli.arguments import at_least, in_range, non_negative, value_option

#: The bag flags' help: a field of a topic, dotted into nested fields and indices.
FIELD_HELP = "TOPIC:FIELD, the field dotted into nested fields and indices: /car/wheels:w[2].v"


def timed_progress() -> Progress:
    """A progress callback: each line on stderr after the seconds since this call."""
    start = time.perf_counter()

    def say(message: str) -> None:
        print(f"[{time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr, flush=True)

    return say


def add_segment_options(p: argparse.ArgumentParser) -> None:
    """``--segment-length``, ``--segment-stride``, ``--min-yaw-rate``, ``--yaw-statistic``."""
    value_option(
        p,
        "--segment-length",
        at_least(0.01, "m"),
        "M",
        "calibration segment length [m] (default 150, paper §5.1; with --vehicle "
        "scaled by its track over the car's 1.55 m; at least 5 tracks)",
    )
    value_option(
        p,
        "--segment-stride",
        at_least(1.0, "m"),
        "M",
        "distance between segment starts [m]; shorter than the length gives "
        "overlapping segments (default: disjoint)",
    )
    value_option(
        p,
        "--min-yaw-rate",
        non_negative,
        "RAD_S",
        "select segments whose |yaw rate| statistic exceeds this (default 0.15 rad/s)",
    )
    p.add_argument(
        "--yaw-statistic",
        choices=["mean", "median", "rms"],
        default=None,
        help="statistic of |yaw rate| used for selection (default mean)",
    )


def add_vehicle_option(p: argparse.ArgumentParser) -> None:
    """``--vehicle FILE``: a vehicle profile."""
    value_option(
        p,
        "--vehicle",
        Path,
        "FILE",
        "vehicle profile (TOML: nominal theta, sensor noise, ticks per revolution; "
        "data/vehicles/*.toml); default the paper's car",
    )


def add_recording_options(p: argparse.ArgumentParser) -> None:
    """The options of a recording read in place of a drive-log CSV: rate, gaps, and a bag's
    topics, wheel fields and heading, yaw-rate and lateral-acceleration fields."""
    g = p.add_argument_group(
        "recordings (a streams manifest or a ROS bag instead of a drive-log CSV)"
    )
    value_option(
        g,
        "--rate",
        in_range(1.0, 1000.0, "Hz"),
        "HZ",
        "rate of the drive log [Hz] (default: the manifest's rate, else 40)",
    )
    value_option(
        g,
        "--max-gap",
        at_least(0.01, "s"),
        "S",
        "a longer gap in any stream is masked [s] (default: the manifest's, else 0.5)",
    )
    g.add_argument("--pose-topic", default=None, help="bag: NavSatFix/Odometry/Pose topic")
    g.add_argument(
        "--wheel-topic",
        default=None,
        help="bag: JointState, Dataspeed WheelSpeedReport or PACMod WheelSpeedRpt topic (the "
        "last two are found by type), or the topic of --rear-left/--rear-right FIELDs",
    )
    g.add_argument("--imu-topic", default=None, help="bag: Imu topic (optional)")
    _add_wheel_field_options(g)
    _add_motion_field_options(g)


def _add_wheel_field_options(g: argparse._ArgumentGroup) -> None:
    """The bag's wheel joints or fields and their kind and unit."""
    g.add_argument(
        "--rear-left",
        default=None,
        metavar="JOINT|TOPIC:FIELD",
        help=f"bag: joint, or {FIELD_HELP}",
    )
    g.add_argument(
        "--rear-right",
        default=None,
        metavar="JOINT|TOPIC:FIELD",
        help="bag: joint, or field (of --rear-left's topic when no TOPIC: is given)",
    )
    g.add_argument(
        "--wheel-kind",
        choices=list(WHEEL_KINDS),
        default=None,
        help="bag: joints: positions (angle) [rad] or velocities (angular_speed) [rad/s] "
        "(default: positions if logged); fields: any, as [wheels] kind (a vendor message: "
        "angular_speed)",
    )
    g.add_argument(
        "--speed-unit",
        choices=list(SPEED_UNITS),
        default=None,
        help="bag fields, --wheel-kind speed: their unit (default m/s)",
    )
    value_option(
        g,
        "--circumference",
        at_least(0.01, "m"),
        "M",
        "bag fields, --wheel-kind speed: the ECU's wheel circumference [m]",
    )
    value_option(
        g,
        "--ticks-per-revolution",
        at_least(1.0, "ticks"),
        "N",
        "bag fields, --wheel-kind ticks: counts per wheel revolution",
    )


def _add_motion_field_options(g: argparse._ArgumentGroup) -> None:
    """The bag's heading, yaw-rate and lateral-acceleration fields and their units."""
    g.add_argument(
        "--heading",
        default=None,
        metavar="TOPIC:FIELD",
        help="bag: the heading from a field, at the pose's times (default unit rad, "
        "convention enu: REP 103)",
    )
    g.add_argument("--heading-unit", choices=["rad", "deg"], default=None, help="bag: of --heading")
    g.add_argument(
        "--heading-convention",
        choices=["enu", "compass"],
        default=None,
        help="bag: of --heading (enu: 0 = east, counter-clockwise; compass: 0 = north, clockwise)",
    )
    g.add_argument(
        "--yaw-rate",
        default=None,
        metavar="TOPIC:FIELD",
        help="bag: the yaw rate from a field instead of an Imu topic (default unit rad/s)",
    )
    g.add_argument(
        "--yaw-rate-unit", choices=["rad/s", "deg/s"], default=None, help="bag: of --yaw-rate"
    )
    g.add_argument(
        "--lateral-acceleration",
        default=None,
        metavar="TOPIC:FIELD",
        help="bag: the lateral acceleration [m/s², positive left] from a field",
    )


def bag_options(args: argparse.Namespace) -> BagOptions:
    """The bag flags (``--pose-topic`` ...) as :class:`graphcal.BagOptions`."""
    return BagOptions(**{f.name: getattr(args, f.name) for f in dataclasses.fields(BagOptions)})


def _given(args: argparse.Namespace, names) -> list[str]:
    """The flags (``--pose-topic``) of the options ``names`` given on the command line (an
    option left out is ``None``)."""
    return [f"--{name.replace('_', '-')}" for name in names if getattr(args, name) is not None]


def check_recording_options(args: argparse.Namespace, path: Path) -> None:
    """Refuse, in one line, a recording option that does not apply to ``path``: any of them
    with a drive-log CSV (its rate and rows are its own), a bag's topic and field flags with a
    streams manifest (its sections name the columns); before any work is done."""
    bag_flags = [f.name for f in dataclasses.fields(BagOptions)]
    if not is_recording(path):
        given = _given(args, ["rate", "max_gap", *bag_flags])
        if given:
            raise GraphcalError(
                f"{' '.join(given)} {'apply' if len(given) > 1 else 'applies'} to a streams "
                f"manifest or a ROS bag, not to the drive-log CSV {path} (its rows are "
                f"already on one time grid, its columns named); remove "
                f"{'them' if len(given) > 1 else 'it'}"
            )
    elif path.suffix.lower() in MANIFEST_SUFFIXES:
        given = _given(args, bag_flags)
        if given:
            raise GraphcalError(
                f"{', '.join(given)} {'apply' if len(given) > 1 else 'applies'} to a ROS bag, "
                f"not to the streams manifest {path}: its sections name the files and columns "
                f"(graphcal import --help-manifest); remove {'them' if len(given) > 1 else 'it'}"
            )


def recording_keywords(args: argparse.Namespace) -> dict[str, object]:
    """The recording options as keywords of :func:`graphcal.open_log`."""
    return {"rate": args.rate, "max_gap": args.max_gap, "bag": bag_options(args)}


#: The settings' keys the options set (``--min-yaw-rate`` sets ``segments.min_yaw_rate``).
_OPTION_KEYS = {
    "segment_length": "segments.length",
    "segment_stride": "segments.stride",
    "min_yaw_rate": "segments.min_yaw_rate",
    "yaw_statistic": "segments.yaw_statistic",
    "validation_length": "segments.validation_length",
    "batches": "batches.count",
    "seed": "batches.seed",
    "batch_solve": "batches.joint_solve",
}


def settings_from_args(args: argparse.Namespace) -> Settings:
    """Settings: the paper's defaults, then ``--config FILE``, then explicit options. A value
    out of range is named by the option that set it (``--min-yaw-rate``, not
    ``segments.min_yaw_rate``)."""
    given = {name: getattr(args, name, None) for name in _OPTION_KEYS}
    given["batches"] = given["batches"] or None  # --batches 0 is the whole method's
    sections: dict[str, dict] = {"segments": {}, "batches": {}}
    for name, key in _OPTION_KEYS.items():
        section, field = key.split(".")
        sections[section][field] = given[name]
    try:
        return configure_settings(
            getattr(args, "config", None),
            getattr(args, "vehicle", None),
            **sections,
            defect_model=not getattr(args, "no_defect_model", False),
            paper_exact=getattr(args, "paper_exact", False),
        )
    except GraphcalError as exc:
        message = str(exc)
        for name, key in _OPTION_KEYS.items():
            if given[name] is not None and message.startswith(key):
                flag = _given(args, [name])[0]
                raise GraphcalError(f"{flag} {given[name]}:{message[len(key) :]}") from exc
        raise
