"""``graphcal simulate --streams DIR``: raw GNSS, wheel and IMU streams with a manifest, with
``--bag`` a ROS bag or MCAP file of them, with ``--can`` the wheels and IMU as a CAN log and
its DBC, with ``--nmea`` the GNSS as an NMEA 0183 log."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

from graphcal import GraphcalError, Progress

#: The file or directory ``--bag KIND`` writes in the streams directory.
BAG_NAMES = {"ros1": "drive.bag", "ros2": "drive_ros2", "mcap": "drive_mcap"}
#: The packages that read what ``--can`` and ``--nmea`` write, and the extra that has them.
RAW_LOG_EXTRAS = {
    "--can": (("can", "cantools"), "python-can and cantools", "can"),
    "--nmea": (("pynmea2",), "pynmea2", "nmea"),
}


def check_raw_log_options(args: argparse.Namespace) -> None:
    """Refuse, in one line, ``--can`` and ``--nmea`` with what they cannot go with (a bag, a
    robot, tick counters) or without the extra that reads their logs back."""
    for flag in (flag for flag in RAW_LOG_EXTRAS if getattr(args, flag[2:])):
        if args.bag is not None:
            raise GraphcalError(
                f"{flag} and --bag {args.bag}: a bag holds the streams as ROS messages, not "
                f"as a {flag[2:].upper()} log; remove one"
            )
        if args.vehicle is not None:
            raise GraphcalError(
                f"{flag} writes a car's {'CAN bus' if flag == '--can' else 'GNSS receiver'} "
                f"log; a robot (--vehicle {args.vehicle}) logs motion-capture poses and "
                f"encoder counts: remove {flag}"
            )
        if flag == "--can" and args.wheel_kind_sim == "ticks":
            raise GraphcalError(
                "--can writes the wheel speeds an ABS sends (km/h); --wheel-kind ticks has no "
                "message in its DBC: remove one"
            )
        modules, names, extra = RAW_LOG_EXTRAS[flag]
        if any(importlib.util.find_spec(module) is None for module in modules):
            raise GraphcalError(
                f"{flag} writes a log graphcal reads with {names}, not installed: "
                f'pip install -e ".[{extra}]"'
            )


def simulate_streams_command(
    args: argparse.Namespace, theta_true: np.ndarray, say: Progress
) -> int:
    """``simulate --streams DIR``: raw GNSS, wheel and IMU streams with a manifest."""
    from graphcal import StreamSettings, simulate_streams

    directory = Path(args.streams)
    stream_settings = StreamSettings(
        position_noise=args.position_noise,
        heading_noise=float(np.deg2rad(args.heading_noise_deg)),
        lateral_acceleration_noise=args.ay_noise,
        sideslip_noise=float(np.deg2rad(args.sideslip_noise_deg)),
        wheel_kind=args.wheel_kind_sim or "speed",
        antenna_arm=tuple(args.antenna_arm) if args.antenna_arm is not None else (0.0, 0.0),
    )
    length_km = 24.0 if args.length_km is None else args.length_km
    sim = simulate_streams(length_km, args.seed, theta_true, stream_settings, route=args.route)
    if args.can or args.nmea:
        gnss = "an NMEA log" if args.nmea else "a CSV"
        sensors = "a CAN log" if args.can else "CSVs"
        say(f"simulated {length_km:g} km: GNSS as {gnss}, wheels and IMU as {sensors}")
    else:
        say(f"simulated {length_km:g} km as GNSS, wheel and IMU streams")
    try:
        if args.can or args.nmea:
            written = write_raw_logs_into(sim, directory, can=args.can, nmea=args.nmea)
        else:
            written = write_streams_and_bag(sim, directory, args.bag)
    except OSError as exc:
        raise GraphcalError(f"cannot write {directory}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def write_raw_logs_into(sim, directory: Path, *, can: bool, nmea: bool) -> list:
    """Write ``sim`` into ``directory`` with the wheels and IMU as a CAN log (``can``) and the
    GNSS as an NMEA log (``nmea``): :func:`graphcal.simulate.raw_logs.write_raw_logs`."""
    from graphcal import write_raw_logs

    refuse_a_file(directory)
    return write_raw_logs(sim, directory, can=can, nmea=nmea)


def write_streams_and_bag(sim, directory: Path, bag: str | None, mocap: bool = False) -> list:
    """Write ``sim``'s streams and manifest into ``directory`` and, with ``bag``, a bag (the
    pose as a motion-capture ``PoseStamped`` on ``/mocap/pose`` when ``mocap``)."""
    from graphcal import write_streams

    if bag is not None and importlib.util.find_spec("rosbags") is None:
        raise GraphcalError(f'--bag {bag} needs the rosbags package: pip install -e ".[ros]"')
    refuse_a_file(directory)
    written = write_streams(sim, directory)
    if bag is not None:
        from graphcal import BagTopics, write_bag

        pose = (
            {"topics": BagTopics(pose="/mocap/pose"), "pose_message": "posestamped"}
            if mocap
            else {}
        )
        written.append(write_bag(sim.recording, directory / BAG_NAMES[bag], bag, **pose))
    return written


def refuse_a_file(directory: Path) -> None:
    """Refuse ``--streams DIR`` naming an existing file."""
    if directory.exists() and not directory.is_dir():
        raise GraphcalError(f"--streams {directory}: exists and is not a directory")
