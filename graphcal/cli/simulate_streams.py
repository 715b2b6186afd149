"""``graphcal simulate --streams DIR``: raw GNSS, wheel and IMU streams with a manifest, and
with ``--bag`` a ROS bag or MCAP file of them."""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

from graphcal import GraphcalError, Progress

#: The file or directory ``--bag KIND`` writes in the streams directory.
BAG_NAMES = {"ros1": "drive.bag", "ros2": "drive_ros2", "mcap": "drive_mcap"}


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
    )
    length_km = 24.0 if args.length_km is None else args.length_km
    sim = simulate_streams(length_km, args.seed, theta_true, stream_settings, route=args.route)
    say(f"simulated {length_km:g} km as GNSS, wheel and IMU streams")
    try:
        written = write_streams_and_bag(sim, directory, args.bag)
    except OSError as exc:
        raise GraphcalError(f"cannot write {directory}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def write_streams_and_bag(sim, directory: Path, bag: str | None, mocap: bool = False) -> list:
    """Write ``sim``'s streams and manifest into ``directory`` and, with ``bag``, a bag (the
    pose as a motion-capture ``PoseStamped`` on ``/mocap/pose`` when ``mocap``)."""
    from graphcal import write_streams

    if bag is not None and importlib.util.find_spec("rosbags") is None:
        raise GraphcalError(f'--bag {bag} needs the rosbags package: pip install -e ".[ros]"')
    if directory.exists() and not directory.is_dir():
        raise GraphcalError(f"--streams {directory}: exists and is not a directory")
    written = write_streams(sim, directory)
    if bag is not None:
        from graphcal import write_bag

        pose = {"pose_topic": "/mocap/pose", "pose_message": "posestamped"} if mocap else {}
        written.append(write_bag(sim.recording, directory / BAG_NAMES[bag], bag, **pose))
    return written
