"""``graphcal simulate --vehicle ROBOT``: a robot's runs and spins as motion-capture poses and
encoder counts."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graphcal import GraphcalError, load_vehicle
from graphcal.cli.options import timed_progress
from graphcal.cli.simulate_streams import write_streams_and_bag

if TYPE_CHECKING:
    from graphcal import RobotSettings, VehicleProfile


def simulate_robot_command(args: argparse.Namespace, theta_true: np.ndarray | None) -> int:
    """``simulate --vehicle ROBOT``: a robot's runs and spins as motion-capture poses and
    encoder counts (``--streams DIR``, optionally ``--bag``) or a drive-log CSV (``--out``)."""
    from graphcal import simulate_robot, theta_true_for, write_synthetic_drive

    vehicle = load_vehicle(args.vehicle)
    if not vehicle.reverses:
        raise GraphcalError(
            f"--vehicle {args.vehicle}: simulate drives robots that turn on the spot; this "
            "profile does not (reverses = false): leave --vehicle out to simulate the car"
        )
    _check_robot_options(args)
    robot = _robot_settings(args, vehicle)
    theta = theta_true_for(vehicle) if theta_true is None else theta_true
    say = timed_progress()
    sim = simulate_robot(args.seed, args.runs, robot, theta)
    say(
        f"simulated {vehicle.name}: {args.runs} runs, {sim.total_distance:.1f} m, "
        f"{sim.drive.measured.t[-1]:.0f} s"
    )
    try:
        if args.out is not None:
            written = write_synthetic_drive(sim.drive, args.out)
        else:
            written = write_streams_and_bag(sim, Path(args.streams), args.bag, mocap=True)
    except OSError as exc:
        raise GraphcalError(f"cannot write {exc.filename or args.out}: {exc.strerror}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def _check_robot_options(args: argparse.Namespace) -> None:
    """Refuse the car's options, and want one of ``--out`` or ``--streams``."""
    unused = [
        f"--{name.replace('_', '-')}"
        for name in ("fleet", "defects", "length_km")
        if getattr(args, name) is not None
    ]
    if unused or args.route != "city":
        raise GraphcalError(
            f"--vehicle simulates a robot's runs; {', '.join(unused) or '--route'} "
            "applies to the car (use --runs)"
        )
    if (args.out is None) == (args.streams is None):
        raise GraphcalError("simulate --vehicle needs one of --out FILE.csv or --streams DIR")


def _robot_settings(args: argparse.Namespace, vehicle: VehicleProfile) -> RobotSettings:
    """The robot's :class:`graphcal.RobotSettings`: the profile's, with the noise options."""
    from graphcal import RobotSettings

    overrides: dict[str, object] = {"reversing": args.reversing}
    if args.position_noise is not None:
        overrides["position_noise"] = args.position_noise
    if args.heading_noise_deg is not None:
        overrides["heading_noise"] = float(np.deg2rad(args.heading_noise_deg))
    try:
        return RobotSettings.from_vehicle(vehicle, **overrides)
    except ValueError as exc:
        raise GraphcalError(f"--vehicle {args.vehicle}: {exc}") from None
