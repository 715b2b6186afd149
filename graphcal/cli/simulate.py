"""``graphcal simulate``: a synthetic car drive (a drive-log CSV or raw streams), a robot's
runs (:mod:`graphcal.cli.simulate_robot`) or a fleet (:mod:`graphcal.cli.simulate_fleet`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graphcal import DISPLAY_SCALE, DISPLAY_UNITS, GraphcalError, Progress
from graphcal.cli.arguments import at_least, non_negative, value_option, whole
from graphcal.cli.options import timed_progress
from graphcal.cli.simulate_fleet import add_fleet_options, simulate_fleet_command
from graphcal.cli.simulate_robot import simulate_robot_command
from graphcal.cli.simulate_streams import check_raw_log_options, simulate_streams_command

if TYPE_CHECKING:
    from graphcal import NoiseLevels

NAME = "simulate"
HELP = "write a synthetic drive with known theta"
#: The car simulation's heading noise [deg] unless --heading-noise-deg gives one.
CAR_HEADING_NOISE_DEG = 1.5


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The drive, robot, output, noise, defect and fleet options, in that order."""
    p.add_argument(
        "--length-km",
        type=at_least(0.1, "km"),
        default=None,
        help="route length [km] (24; with --fleet, 4 per day)",
    )
    p.add_argument("--seed", type=whole(0), default=0, help="seed of every random choice (0)")
    p.add_argument(
        "--route",
        choices=["city", "straight"],
        default="city",
        help="city: bends, turns and roundabouts (default); straight: a straight road, where "
        "t_r and d are not observable",
    )
    p.add_argument(
        "--out",
        type=Path,
        default=None,
        help="drive-log CSV to write (+ _truth.csv, .json); required unless --streams DIR "
        "or --fleet DIR",
    )
    _add_robot_options(p)
    _add_stream_options(p)
    p.add_argument(
        "--dt", type=at_least(1e-3, "s"), default=0.025, help="sampling interval [s] (0.025)"
    )
    p.add_argument(
        "--theta-true",
        type=float,
        nargs=4,
        metavar=("C_E", "C_D", "T_R", "D"),
        default=None,
        help=f"true theta in {', '.join(DISPLAY_UNITS)} (1.985 1.2 1.585 1.5; with a robot "
        "--vehicle near its nominal: 0.2639 0.1 0.205 0 for data/vehicles/mocap_robot.toml)",
    )
    _add_noise_options(p)
    _add_defects_option(p)
    add_fleet_options(p)


def _add_robot_options(p: argparse.ArgumentParser) -> None:
    """``--vehicle`` (a robot's profile), ``--runs``, ``--reversing``."""
    value_option(
        p,
        "--vehicle",
        Path,
        "FILE",
        "a robot's profile (reverses = true, e.g. data/vehicles/mocap_robot.toml): drive "
        "a robot instead of the car — runs of 5–15 m, spins on the spot, stops, "
        "motion-capture poses and encoder counts with the profile's noise and resolution",
    )
    p.add_argument(
        "--runs", type=whole(1), default=10, help="with a robot --vehicle: runs to drive (10)"
    )
    p.add_argument(
        "--reversing",
        action="store_true",
        help="with a robot --vehicle: reverse straight back a few metres after every second run",
    )


def _add_stream_options(p: argparse.ArgumentParser) -> None:
    """``--streams DIR`` instead of a CSV, with its ``--wheel-kind``, ``--bag``, ``--can`` and
    ``--nmea``."""
    value_option(
        p,
        "--streams",
        Path,
        "DIR",
        "instead of a drive-log CSV, write raw streams into DIR: GNSS at 10 Hz "
        "(latitude/longitude), rear wheels and IMU at 100 Hz on their own clocks, with "
        "manifest.toml for `graphcal import`",
    )
    p.add_argument(
        "--wheel-kind",
        dest="wheel_kind_sim",
        choices=["speed", "ticks"],
        default=None,
        help="with --streams: wheel speeds in m/s (the ECU's circumference 2.0 m; default) or "
        "cumulative ticks (96 per revolution)",
    )
    p.add_argument(
        "--antenna-arm",
        type=float,
        nargs=2,
        default=None,
        metavar=("AHEAD", "LEFT"),
        help="with --streams: the car's GNSS antenna, a point of its body, this far ahead of "
        "and left of the centre of gravity [m] (0 0)",
    )
    p.add_argument(
        "--bag",
        choices=["ros1", "ros2", "mcap"],
        default=None,
        help="with --streams: also write the streams as a ROS 1 bag, a ROS 2 bag or an MCAP file",
    )
    p.add_argument(
        "--can",
        action="store_true",
        help="with --streams: the wheels (km/h) and the IMU as a car's CAN bus, a raw candump "
        "log (drive.log) with its DBC (car.dbc), instead of wheels.csv and imu.csv; "
        'needs pip install -e ".[can]"',
    )
    p.add_argument(
        "--nmea",
        action="store_true",
        help="with --streams: the GNSS as a receiver's NMEA 0183 log (receiver.nmea: GGA + RMC "
        'at 10 Hz, positions only) instead of gnss.csv; needs pip install -e ".[nmea]"',
    )


def _add_noise_options(p: argparse.ArgumentParser) -> None:
    """The sensors' noise sigmas (position and heading: the profile's with ``--vehicle``)."""
    for flag, default, metavar, text in (
        (
            "--position-noise",
            None,
            "M",
            "position noise sigma [m] (0.2; with --vehicle the profile's)",
        ),
        (
            "--heading-noise-deg",
            None,
            "DEG",
            "heading noise sigma [deg] (1.5; with --vehicle the profile's)",
        ),
        ("--wheel-noise", 0.0005, "REV", "wheel rotation noise sigma [rev] (0.0005)"),
        ("--sideslip-noise-deg", 0.0, "DEG", "sideslip noise sigma [deg] (0)"),
        ("--ay-noise", 0.0, "M_S2", "lateral acceleration noise sigma [m/s²] (0)"),
    ):
        p.add_argument(flag, type=non_negative, default=default, metavar=metavar, help=text)


def _add_defects_option(p: argparse.ArgumentParser) -> None:
    """``--defects LIST``: the defects of real logs to add."""
    from graphcal import DEFECT_NAMES, DEFECTS_IN_ALL

    p.add_argument(
        "--defects",
        default=None,
        metavar="LIST",
        help="add defects of real logs to the drive-log output, comma-separated: "
        f"{', '.join(DEFECT_NAMES)}, or all (= {', '.join(DEFECTS_IN_ALL)}); a name alone takes "
        "its realistic default, name=VALUE sets its size in SI units (gnss10hz/hold: Hz; "
        "outliers: share; outages/dropouts: count; heading_bias: rad/√s; latency: s; "
        "lever_arm: LONG[:LAT] m; ticks: per revolution; slip: relative σ), e.g. "
        "all,latency=0.1 or outliers=0.01,lever_arm=1.5:0.2 (docs/results.md)",
    )


def run(args: argparse.Namespace) -> int:
    """Write a synthetic drive, its noise-free truth and a JSON sidecar."""
    from graphcal import THETA_TRUE_DEFAULT, NoiseLevels, check_simulate_output

    _check_outputs(args)
    check_simulate_output(args.out, args.streams, args.fleet)
    theta_true = _theta_true(args)
    if args.vehicle is not None:
        return simulate_robot_command(args, theta_true)
    if args.reversing:
        raise GraphcalError("--reversing drives a robot: give its profile with --vehicle")
    if theta_true is None:
        theta_true = THETA_TRUE_DEFAULT
    if args.position_noise is None:
        args.position_noise = NoiseLevels.position
    if args.heading_noise_deg is None:
        args.heading_noise_deg = CAR_HEADING_NOISE_DEG
    noise = NoiseLevels(
        position=args.position_noise,
        heading=float(np.deg2rad(args.heading_noise_deg)),
        wheel_rotation=args.wheel_noise,
        sideslip=float(np.deg2rad(args.sideslip_noise_deg)),
        lateral_acceleration=args.ay_noise,
    )
    say = timed_progress()
    defects = _defects(args)
    if args.fleet is not None:
        return simulate_fleet_command(args, say)
    length_km = 24.0 if args.length_km is None else args.length_km
    if args.streams is not None:
        return simulate_streams_command(args, theta_true, say)
    if args.out is None:
        raise GraphcalError("simulate needs --out FILE.csv (or --streams DIR)")
    return _simulate_car(args, length_km, theta_true, noise, defects, say)


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse, in one line, both outputs at once and the options of the streams output
    (``--bag``, ``--wheel-kind``, ``--can``, ``--nmea``) without ``--streams DIR`` or with
    what they cannot go with: before anything is written."""
    if args.streams is not None and args.out is not None:
        raise GraphcalError(
            f"--out {args.out} and --streams {args.streams}: simulate writes one output, a "
            "drive-log CSV (--out) or raw streams with a manifest (--streams), not both; "
            "remove one"
        )
    if args.streams is None:
        for given in (
            f"--bag {args.bag}" if args.bag is not None else None,
            f"--wheel-kind {args.wheel_kind_sim}" if args.wheel_kind_sim is not None else None,
            "--can" if args.can else None,
            "--nmea" if args.nmea else None,
            "--antenna-arm" if args.antenna_arm is not None else None,
        ):
            if given is not None:
                raise GraphcalError(
                    f"{given} applies to --streams DIR (the raw streams and their manifest), "
                    f"not to a drive-log CSV; add --streams DIR or remove {given.split()[0]}"
                )
    if args.antenna_arm is not None and args.vehicle is not None:
        raise GraphcalError(
            f"--antenna-arm places a car's GNSS antenna; a robot (--vehicle {args.vehicle}) "
            "logs the motion-capture pose of its axle: remove --antenna-arm"
        )
    if args.antenna_arm is not None and not np.all(np.isfinite(args.antenna_arm)):
        given = " ".join(f"{value:g}" for value in args.antenna_arm)
        raise GraphcalError(
            f"--antenna-arm {given}: give the antenna's distance ahead of and left of the "
            "centre of gravity in metres, two finite numbers (e.g. --antenna-arm 1.2 0.3)"
        )
    check_raw_log_options(args)


def _theta_true(args: argparse.Namespace) -> np.ndarray | None:
    """``--theta-true`` in SI, checked, or ``None`` when not given."""
    if args.theta_true is None:
        return None
    theta_true = np.asarray(args.theta_true, dtype=float) / DISPLAY_SCALE
    if not (np.all(np.isfinite(theta_true)) and theta_true[0] > 0 and theta_true[2] > 0):
        raise GraphcalError(
            f"--theta-true {' '.join(map(str, args.theta_true))}: c_e and t_r must be "
            f"positive and all values finite ({', '.join(DISPLAY_UNITS)})"
        )
    return theta_true


def _defects(args: argparse.Namespace):
    """``--defects`` parsed (:class:`graphcal.simulate.defects.Defects`), or ``None``."""
    if args.defects is None:
        return None
    if args.streams is not None:
        raise GraphcalError(
            "--defects applies to the drive-log output (--out) for now, not to --streams"
        )
    from graphcal import parse_defects

    try:
        return parse_defects(args.defects)
    except ValueError as exc:
        raise GraphcalError(f"--defects {args.defects}: {exc}") from None


def _simulate_car(
    args: argparse.Namespace,
    length_km: float,
    theta_true: np.ndarray,
    noise: NoiseLevels,
    defects,
    say: Progress,
) -> int:
    """``simulate --out FILE.csv``: the car's drive, with ``--defects``, its truth and sidecar."""
    from graphcal import degrade, simulate_drive, write_synthetic_drive

    drive = simulate_drive(length_km, args.seed, theta_true, noise, args.dt, route=args.route)
    say(f"simulated {len(drive.measured)} samples ({drive.measured.t[-1]:.0f} s)")
    if defects is not None and defects.names:
        try:
            drive = degrade(drive, defects, args.seed)
        except ValueError as exc:
            raise GraphcalError(f"--defects {args.defects}: {exc}") from None
        say(f"added defects: {', '.join(defects.names)}")
    try:
        written = write_synthetic_drive(drive, args.out)
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0
