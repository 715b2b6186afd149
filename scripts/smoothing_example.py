"""Drop-in example: a Pose2 smoothing graph with 5 Hz GNSS and graphcal's wheel odometry.

    python scripts/smoothing_example.py --length-km 4 --out results/smoothing
        [--defects all] [--sensors-from-calibration]

Simulates a city drive (with ``--defects``, degraded as by ``graphcal simulate --defects``;
or reads ``--log``), builds the graph of
:mod:`graphcal.localization.smoothing` — Pose2 keyframes at each GNSS fix with a GNSS
position factor, a wheel-odometry factor between consecutive keyframes, theta as one
variable under a weak prior — solves it with Levenberg–Marquardt and prints theta with its
95 % interval (and the truth on synthetic drives) and the trajectory's error. The graph has
robust GNSS factors (``--lever-arm-sigma`` makes the antenna's lever arm a variable); with
``--sensors-from-calibration`` the log is first corrected by the wheels' time offset and the
lever arm that graphcal's whole-log calibration estimates (as a localization system would
use its offline calibration), and the graph takes over the calibration's findings about the
wheels: the tick rounding of counted rotations and, if it found slow slip, slip scales, and
starts from its theta
(:func:`graphcal.pipeline.end_to_end.localization_inputs.prepare_localization`).
Writes the smoothed, GNSS and (synthetic) true trajectories as TUM files for evo.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from graphcal.localization.smoothing import SmoothingSettings, smooth_drive
from graphcal.log.load import load_drive_log
from graphcal.log.tum import write_tum
from graphcal.log.validation import validate_frame
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.end_to_end.localization_inputs import prepare_localization
from graphcal.report.tables import Z95
from graphcal.simulate.defects import degrade, parse_defects
from graphcal.simulate.drive import simulate_drive
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS, DISPLAY_SCALE, DISPLAY_UNITS


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", type=Path, default=None, help="drive log (default: simulate)")
    parser.add_argument("--length-km", type=float, default=4.0)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--gnss-rate-hz", type=float, default=5.0)
    parser.add_argument("--out", type=Path, default=Path("results/smoothing"))
    parser.add_argument("--defects", default=None, help="degrade the simulated drive (LIST)")
    parser.add_argument("--sensors-from-calibration", action="store_true")
    parser.add_argument("--lever-arm-sigma", type=float, default=0.0, help="m; 0: not estimated")
    args = parser.parse_args(argv)

    truth = theta_true = None
    if args.log is None:
        drive = simulate_drive(args.length_km, seed=args.seed)
        if args.defects:
            drive = degrade(drive, parse_defects(args.defects), args.seed)
        # Screened as a loaded CSV: jumps and frozen fixes masked, spikes flagged.
        log = validate_frame(drive.measured.to_dataframe(), "simulated", 150.0)
        truth, theta_true = drive.truth, drive.theta_true
    else:
        log = load_drive_log(args.log)
    start = time.perf_counter()
    wheels = {}
    if args.sensors_from_calibration:
        log, wheels, summary = prepare_localization(log)
        print(f"{summary}; {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    smoothing = SmoothingSettings(
        gnss_rate_hz=args.gnss_rate_hz, lever_arm_sigma=args.lever_arm_sigma, **wheels
    )
    result = smooth_drive(log, smoothing)
    seconds = time.perf_counter() - start
    if result.lever_arm is not None:
        arm, arm_cov = result.lever_arm
        arm_sigma = np.sqrt(np.diag(arm_cov))
        print(
            f"lever arm: {arm[0]:+.3f} ± {arm_sigma[0]:.3f} m ahead, {arm[1]:+.3f} ± "
            f"{arm_sigma[1]:.3f} m left"
        )
    print(
        f"{len(result.keyframes)} keyframes at {args.gnss_rate_hz:g} Hz over "
        f"{log.t[-1] - log.t[0]:.0f} s; Levenberg–Marquardt: {result.iterations} iterations, "
        f"{seconds:.1f} s\n"
    )
    sigma = np.sqrt(np.diag(result.covariance))
    print(
        "| parameter | estimate | 95 % interval ± | "
        + ("error | " if truth is not None else "")
        + "verdict |"
    )
    print("|---|---|---|" + ("---|" if truth is not None else "") + "---|")
    verdicts = result.observability.verdicts()
    for i, name in enumerate(PARAMETER_NAMES):
        row = [f"{name} [{DISPLAY_UNITS[i]}; ± {DEVIATION_UNITS[i]}]"]
        if not result.observability.calibrated[i]:  # no number for what the data left open
            row += ["n/o", "-"] + (["-"] if theta_true is not None else [])
            print("| " + " | ".join([*row, verdicts[name]]) + " |")
            continue
        row += [
            f"{result.theta[i] * DISPLAY_SCALE[i]:.5g}",
            f"{Z95 * sigma[i] * DEVIATION_SCALE[i]:.3f}",
        ]
        if theta_true is not None:
            row.append(f"{(result.theta[i] - theta_true[i]) * DEVIATION_SCALE[i]:+.3f}")
        print("| " + " | ".join([*row, verdicts[name]]) + " |")
    args.out.mkdir(parents=True, exist_ok=True)
    write_tum(args.out / "smoothed.tum", result.t, result.states, "graphcal smoothing")
    write_tum(args.out / "gnss.tum", result.t, log.poses[result.keyframes], "measured")
    if truth is not None:
        true_states = truth.poses[result.keyframes]
        write_tum(args.out / "truth.tum", result.t, true_states, "noise-free truth")
        smoothed = np.hypot(*(result.states[:, :2] - true_states[:, :2]).T)
        measured = np.hypot(*(log.poses[result.keyframes, :2] - true_states[:, :2]).T)
        print(
            f"\nposition error RMS: GNSS {np.sqrt(np.mean(measured**2)):.3f} m, smoothed "
            f"{np.sqrt(np.mean(smoothed**2)):.3f} m"
        )
    print(f"wrote smoothed.tum, gnss.tum{', truth.tum' if truth is not None else ''} to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
