"""Round trip of a synthetic recording: streams (or a bag) -> import -> calibrate, vs the CSV.

    python scripts/import_round_trip.py [--length-km 24] [--seed 0] [--sources manifest ros2]

For each source, prints the recommended theta's error to the truth in units of its reported
σ, and σ over the σ of calibrating the equivalent 40 Hz drive-log CSV (the same route, truth
and noise levels, `graphcal simulate`), both with the whole-log joint solve. Sources:
``manifest`` (CSV streams: GNSS 10 Hz with heading and sideslip, wheel speeds and IMU at
100 Hz), ``ros1``/``ros2``/``mcap`` (nav_msgs/Odometry with heading and body-frame twist),
``navsatfix`` (a ROS 2 bag with NavSatFix and an INS orientation in the Imu messages, no
sideslip) and ``course`` (the CSV streams without the heading column: the GNSS course,
calibrated with the heading nearly unweighted, as ``graphcal calibrate`` does).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from graphcal.evaluation import Truth, evaluate
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.recording.importer import import_recording
from graphcal.simulate.drive import simulate_drive
from graphcal.simulate.streams import simulate_streams, write_streams

SOURCES = ("manifest", "course", "ros1", "ros2", "mcap", "navsatfix")


def _source_path(source: str, sim, directory: Path) -> Path:
    if source in ("manifest", "course"):
        write_streams(sim, directory)
        manifest = directory / "manifest.toml"
        if source == "course":
            text = manifest.read_text()
            for key in ('heading = "heading"\n', 'heading_unit = "deg"\n'):
                text = text.replace(key, "")
            text = text.replace('heading_convention = "compass"\n', "")
            manifest.write_text(text)
        return manifest
    from graphcal.simulate.bags import write_bag

    if source == "navsatfix":
        return write_bag(sim.recording, directory / "fix", "ros2", pose_message="navsatfix")
    name = {"ros1": "drive.bag", "ros2": "ros2", "mcap": "mcap"}[source]
    path = write_bag(sim.recording, directory / name, source, pose_message="odometry")
    return next(path.glob("*.mcap")) if source == "mcap" else path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--sources", nargs="+", choices=SOURCES, default=list(SOURCES))
    args = parser.parse_args(argv)

    csv_run = run_calibration(
        simulate_drive(args.length_km, args.seed).measured, method="whole", workers=args.workers
    )
    csv_sigma = np.sqrt(np.diag(csv_run.covariance))
    sim = simulate_streams(args.length_km, args.seed)
    header = "  ".join(f"{n:>12}" for n in PARAMETER_NAMES)
    print(f"{args.length_km:g} km, seed {args.seed}; error/σ and σ/σ_CSV per parameter")
    print(f"{'source':<10}  {header}")
    for source in args.sources:
        with tempfile.TemporaryDirectory() as tmp:
            path = _source_path(source, sim, Path(tmp))
            imported = import_recording(path)
        run = run_calibration(imported.log, Settings(), method="whole", workers=args.workers)
        sigma = np.sqrt(np.diag(run.covariance))
        z = evaluate(run, Truth(sim.drive.theta_true)).theta_error / sigma
        cells = "  ".join(
            f"{e:+5.1f}σ {s / c:5.2f}" for e, s, c in zip(z, sigma, csv_sigma, strict=True)
        )
        print(f"{source:<10}  {cells}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
