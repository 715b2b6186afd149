"""Verdicts against the prior's width: each recording calibrated (``--method whole``) with
the documented prior sigmas, and with them doubled and halved. The verdicts must not move
(``graphcal.graph.solution.observability`` judges against fixed reference sigmas, not the prior).

    python scripts/prior_width.py       # the sample drive, the car's four forms, the robot
    python scripts/prior_width.py LOG [--vehicle FILE]

Prints one row per recording and prior scale: the verdicts and theta.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from graphcal import open_log
from graphcal.pipeline.configuration.configure import configure_settings
from graphcal.pipeline.end_to_end.run import run_calibration

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT / "data" / "real"
RECORDINGS = [
    (ROOT / "data" / "sample_drive.csv", None),
    (REAL / "comma2k19" / "drive.csv", None),
    (REAL / "comma2k19" / "gnss.toml", None),
    (REAL / "comma2k19" / "gnss_imu.toml", None),
    (REAL / "comma2k19" / "can.toml", None),
    (REAL / "optiodom" / "free" / "manifest.toml", ROOT / "data" / "vehicles" / "mocap_robot.toml"),
]
SCALES = (1.0, 2.0, 0.5)


def verdicts(path: Path, vehicle: Path | None) -> list[tuple[float, dict[str, str], np.ndarray]]:
    """The whole-log run's verdicts and theta at each prior scale of :data:`SCALES`."""
    settings = configure_settings(vehicle=vehicle)
    log, _ = open_log(path, settings.vehicle, min_distance=settings.segments.length)
    out = []
    for scale in SCALES:
        joint = dataclasses.replace(
            settings.joint, theta_prior_sigmas=settings.joint.theta_prior_sigmas * scale
        )
        run = run_calibration(log, dataclasses.replace(settings, joint=joint), "whole")
        out.append((scale, run.verdicts(), run.theta))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", nargs="?", type=Path)
    parser.add_argument("--vehicle", type=Path)
    args = parser.parse_args(argv)
    recordings = RECORDINGS if args.log is None else [(args.log, args.vehicle)]
    moved = 0
    for path, vehicle in recordings:
        rows = verdicts(path, vehicle)
        for scale, found, theta in rows:
            print(
                f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path} ×{scale:g}: "
                f"{found}  theta {np.array2string(theta, precision=5)}"
            )
        moved += any(found != rows[0][1] for _, found, _ in rows)
    print(f"{moved} of {len(recordings)} recordings change a verdict with the prior's width")
    return 1 if moved else 0


if __name__ == "__main__":
    sys.exit(main())
