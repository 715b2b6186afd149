"""GNSS-outage benchmark: dead reckoning with nominal, calibrated and true theta.

    python scripts/gnss_outage.py --length-km 24 --out results/outage

Calibrates theta with graphcal (joint solve over all selected segments) on one synthetic city
drive (``--calibration-seed``), then on a *different* drive of the same vehicle (``--seed``)
withholds GNSS for 30, 60 and 120 s at a start every 45 s. Each outage starts from the pose a
20 s GNSS + wheel-odometry smoothing window estimates with that theta and dead-reckons with
the measured wheel signals. Prints the median final and mean position errors as a Markdown
table, checks issue 4's 60 s criterion and writes ``outage_errors.csv``, ``outage.png`` and,
for the first 60 s outage, the truth and the three dead-reckoned paths as TUM files.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from graphcal.files import atomic_save_figure, atomic_write_csv
from graphcal.localization.dead_reckoning import (
    OutageSettings,
    outage_errors,
    outage_table,
    pose_before_outage,
)
from graphcal.log.tum import write_tum
from graphcal.model import THETA_NOMINAL, integrate
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.simulate.drive import simulate_drive

COLOURS = {"nominal": "tab:red", "calibrated": "tab:blue", "true": "tab:green"}


def outage_figure(errors, durations) -> Figure:
    """Box plots of the final position error per outage length and theta."""
    fig = Figure(figsize=(10, 3.8), layout="constrained")
    for i, duration in enumerate(durations):
        ax = fig.add_subplot(1, len(durations), i + 1)
        subset = errors[errors.duration_s == duration]
        names = list(COLOURS)
        data = [subset[subset.theta == n].final_error_m.to_numpy() for n in names]
        parts = ax.boxplot(data, tick_labels=[f"{n} θ" for n in names], patch_artist=True)
        for patch, name in zip(parts["boxes"], names, strict=True):
            patch.set_facecolor(COLOURS[name])
            patch.set_alpha(0.4)
        ax.set_yscale("log")
        ax.set_title(f"{duration:g} s without GNSS")
        ax.grid(axis="y", alpha=0.3, which="both")
        if i == 0:
            ax.set_ylabel("final position error [m]")
    fig.suptitle("Dead reckoning through GNSS outages (city drive)")
    return fig


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--calibration-seed", type=int, default=0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("results/outage"))
    args = parser.parse_args(argv)
    say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731

    calibration_drive = simulate_drive(args.length_km, seed=args.calibration_seed)
    run = run_calibration(
        calibration_drive.measured, Settings(), "whole", progress=say, workers=args.workers
    )
    drive = simulate_drive(args.length_km, seed=args.seed)
    thetas = {"nominal": THETA_NOMINAL, "calibrated": run.theta, "true": drive.theta_true}
    settings = OutageSettings()
    errors = outage_errors(drive.measured, drive.truth, thetas, settings, say)
    table = outage_table(errors)

    print(
        f"\ncalibrated on seed {args.calibration_seed}, outages on seed {args.seed} "
        f"({args.length_km:g} km, {errors.start_t_s.nunique()} outage starts):\n"
    )
    print("| outage | median final error, nominal / calibrated / true θ [m] "
          "| median mean error, nominal / calibrated / true θ [m] |")  # fmt: skip
    print("|---|---|---|")
    for duration in settings.durations_s:
        final = table.loc[duration, "final_error_m"]
        mean = table.loc[duration, "mean_error_m"]
        print(
            f"| {duration:g} s | {final['nominal']:.2f} / {final['calibrated']:.2f} / "
            f"{final['true']:.2f} | {mean['nominal']:.2f} / {mean['calibrated']:.2f} / "
            f"{mean['true']:.2f} |"
        )
    final60 = table.loc[60.0, "final_error_m"]
    checks = [
        ("60 s: calibrated <= 1.2 x true", final60["calibrated"] <= 1.2 * final60["true"]),
        ("60 s: calibrated <= nominal / 3", final60["calibrated"] <= final60["nominal"] / 3),
    ]
    print()
    for label, ok in checks:
        print(f"- [{'x' if ok else ' '}] {label}")

    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_csv(errors, args.out / "outage_errors.csv")
    atomic_save_figure(outage_figure(errors, settings.durations_s), args.out / "outage.png")
    # TUM files of the first 60 s outage, for evo: truth and each theta's dead reckoning.
    start = int(np.searchsorted(drive.measured.t, errors.start_t_s.iloc[0]))
    k = round(60.0 / drive.measured.dt)
    t = drive.measured.t[start : start + k + 1]
    write_tum(args.out / "outage_truth.tum", t, drive.truth.poses[start : start + k + 1])
    for name, theta in thetas.items():
        state = pose_before_outage(drive.measured, start, theta, settings)
        path = integrate(state, drive.measured.inputs[start : start + k], theta)
        write_tum(args.out / f"outage_{name}.tum", t, path, f"dead reckoning, {name} theta")
    say(f"wrote {args.out}")
    return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
