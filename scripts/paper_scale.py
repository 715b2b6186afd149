"""The paper-scale staged calibration on a synthetic drive, checked against the truth.

    python scripts/paper_scale.py --length-km 24 --batches 1000 --workers 2 --out results/paper

Simulates a drive (seed 0, the paper's noise levels, theta_true away from nominal), runs the
five steps, writes the usual result files into ``--out`` and prints a Markdown table of the
results next to the acceptance bounds (Step 5 vs Step 1 RMSE and IQR, final theta vs half of
Step 1's IQR, validation error vs the reachable limit).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.run import run_calibration
from graphcal.report.results import run_statistics, write_results
from graphcal.report.tables import PAPER_IQR_REDUCTION, iqr_reduction
from graphcal.settings import BatchingSettings, Settings
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive
from graphcal.units import DEVIATION_SCALE, DISPLAY_SCALE, DISPLAY_UNITS


def report_joint(run, stats: dict, args: argparse.Namespace, seconds: float) -> int:
    """Print the joint method's per-parameter statistics against the truth."""
    truth = run.theta_true
    print(
        f"\n{args.length_km:g} km, {len(run.batches)} batches of {run.batches.shape[1]}, "
        f"{len(run.selected)} selected segments, {args.workers} workers, joint: "
        f"{seconds / 60:.1f} min\n"
    )
    print("| parameter | joint median | joint IQR | joint bias | joint RMSE | recommended − true |")
    print("|---|---|---|---|---|---|")
    for i, name in enumerate(PARAMETER_NAMES):
        e, s = stats["joint"][name], DEVIATION_SCALE[i]
        print(
            f"| {name} [{DISPLAY_UNITS[i]}] | {e['median'] * DISPLAY_SCALE[i]:.5g} "
            f"| {e['iqr'] * s:.3f} | {e['bias'] * s:+.3f} | {e['rmse'] * s:.3f} "
            f"| {(run.theta[i] - truth[i]) * s:+.3f} |"
        )
    print(
        f"\nvalidation error E_p: nominal {run.validation_error('nominal'):.3f} m, median "
        f"joint {np.nanmedian(run.batch_errors['joint']):.3f} m, recommended theta "
        f"{run.validation_error('calibrated'):.3f} m, reachable "
        f"{run.validation_error('true'):.3f} m"
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--batches", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results/paper_scale"))
    parser.add_argument("--method", choices=["staged", "joint"], default="staged")
    args = parser.parse_args(argv)

    drive = simulate_drive(args.length_km, seed=args.seed)
    write_synthetic_drive(drive, args.out / "drive.csv")
    settings = Settings(batches=BatchingSettings(count=args.batches, seed=args.seed))
    start = time.perf_counter()
    run = run_calibration(
        drive.measured,
        settings,
        args.method,
        drive.theta_true,
        lambda line: print(line, file=sys.stderr, flush=True),
        args.workers,
    )
    seconds = time.perf_counter() - start
    write_results(run, args.out, args.workers)

    stats = run_statistics(run)
    if args.method == "joint":
        return report_joint(run, stats, args, seconds)
    first, last = stats["step1"], stats["step5"]
    cut = iqr_reduction(first, last)
    truth = drive.theta_true
    print(
        f"\n{args.length_km:g} km, {len(run.staged.batches)} batches of "
        f"{run.staged.batches.shape[1]}, {len(run.selected)} selected segments, "
        f"{args.workers} workers: {seconds / 60:.1f} min\n"
    )
    print(
        "| parameter | Step 1 median | Step 1 IQR | Step 1 bias | Step 1 RMSE "
        "| Step 5 median | Step 5 IQR | Step 5 bias | Step 5 RMSE | IQR cut (paper) "
        "| recommended − true | ½ Step 1 IQR |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    checks = []
    for i, name in enumerate(PARAMETER_NAMES):
        s = DEVIATION_SCALE[i]
        error = (run.theta[i] - truth[i]) * s
        row = [f"{name} [{DISPLAY_UNITS[i]}]"]
        for step in (first, last):
            entry = step[name]
            row += [
                f"{entry['median'] * DISPLAY_SCALE[i]:.5g}",
                f"{entry['iqr'] * s:.3f}",
                f"{entry['bias'] * s:+.3f}",
                f"{entry['rmse'] * s:.3f}",
            ]
        row += [
            f"{cut[name]:.0f} % ({PAPER_IQR_REDUCTION[name]:.0f} %)",
            f"{error:+.3f}",
            f"{first[name]['iqr'] * s / 2:.3f}",
        ]
        print("| " + " | ".join(row) + " |")
        checks.append(
            (f"{name}: Step 5 RMSE < Step 1 RMSE", last[name]["rmse"] < first[name]["rmse"])
        )
        checks.append(
            (
                f"{name}: |final − true| <= ½ Step 1 IQR",
                abs(run.theta[i] - truth[i]) <= first[name]["iqr"] / 2,
            )
        )
        if name in ("c_e", "d"):
            checks.append(
                (
                    f"{name}: Step 5 IQR <= 50 % of Step 1",
                    last[name]["iqr"] <= 0.5 * first[name]["iqr"],
                )
            )
    reachable = run.validation_error("true")
    step5 = float(np.nanmedian(run.batch_errors["step5"]))
    print(
        f"\nvalidation error E_p: nominal {run.validation_error('nominal'):.3f} m, "
        f"median Step 1 {np.nanmedian(run.batch_errors['step1']):.3f} m, "
        f"median Step 5 {step5:.3f} m, recommended theta "
        f"{run.validation_error('calibrated'):.3f} m, reachable {reachable:.3f} m"
    )
    checks.append(("median Step 5 E_p within 0.1 m of reachable", step5 - reachable <= 0.1))
    print()
    for label, ok in checks:
        print(f"- [{'x' if ok else ' '}] {label}")
    return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
