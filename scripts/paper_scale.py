"""The paper-scale staged calibration on a synthetic drive, checked against the truth.

    python scripts/paper_scale.py --length-km 24 --batches 1000 --workers 2 --out results/paper

Simulates a drive (seed 0, the paper's noise levels, theta_true away from nominal), runs the
five steps, writes the usual result files into ``--out/staged`` (``--out/joint`` for the
joint method) and prints a Markdown table of the results next to the acceptance bounds
(Step 5 vs Step 1 RMSE and IQR, final theta vs half of Step 1's IQR, validation error vs the
reachable limit).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from graphcal.evaluation import Truth, evaluate
from graphcal.files import atomic_save_figure
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.report.document import run_statistics, uncertainty_summary
from graphcal.report.results import write_results
from graphcal.report.tables import PAPER_IQR_REDUCTION, iqr_reduction
from graphcal.report.theta_figures import box_plots
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS, DISPLAY_SCALE, DISPLAY_UNITS


def report_joint(
    run, evaluation, stats: dict, args: argparse.Namespace, seconds: float, staged=None
) -> int:
    """Print the joint method against the truth, the Cramér–Rao bound and (if given) the
    staged Step 5, with issue 6's acceptance checks."""
    truth = evaluation.theta_true
    uncertainty = uncertainty_summary(run, evaluation)["joint"]
    print(
        f"\n{args.length_km:g} km, {len(run.batches)} batches of {run.batches.shape[1]}, "
        f"{len(run.selected)} selected segments, {args.workers} workers, joint "
        f"({args.batch_solve} batches): "
        f"{seconds / 60:.1f} min\n"
    )
    header = ["parameter", "Step 1 IQR", "joint bias", "joint IQR", "joint RMSE"]
    header += ["staged Step 5 RMSE"] if staged is not None else []
    header += ["CRB (rms)", "RMSE / CRB", "final − true", "final 1σ", "final CRB 1σ"]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    checks = []
    for i, name in enumerate(PARAMETER_NAMES):
        s = DEVIATION_SCALE[i]
        joint, first = stats["joint"][name], stats["step1"][name]
        crb = uncertainty["crb_sigma"][name]
        row = [
            f"{name} [{DEVIATION_UNITS[i]}]",
            f"{first['iqr'] * s:.3f}",
            f"{joint['bias'] * s:+.3f}",
            f"{joint['iqr'] * s:.3f}",
            f"{joint['rmse'] * s:.3f}",
        ]
        if staged is not None:
            step5 = staged["step5"][name]
            row.append(f"{step5['rmse'] * s:.3f}")
            checks.append(
                (f"{name}: joint RMSE <= staged Step 5 RMSE", joint["rmse"] <= step5["rmse"])
            )
        row += [
            f"{crb * s:.3f}",
            f"{joint['rmse'] / crb:.2f}",
            f"{(run.theta[i] - truth[i]) * s:+.3f}",
            f"{np.sqrt(run.covariance[i, i]) * s:.3f}",
            f"{np.sqrt(evaluation.crb[i, i]) * s:.3f}",
        ]
        print("| " + " | ".join(row) + " |")
        checks.append((f"{name}: joint RMSE <= 1.5 x CRB", joint["rmse"] <= 1.5 * crb))
        checks.append(
            (f"{name}: |joint bias| <= 1/4 Step 1 IQR", abs(joint["bias"]) <= first["iqr"] / 4)
        )
    nees = uncertainty["nees_mean"]
    print(f"\nNEES over {uncertainty['nees_batches']} batches: {nees:.2f} (4 = consistent)")
    checks.append(("NEES between 2 and 8", 2.0 <= nees <= 8.0))
    print(
        f"validation error E_p: nominal {run.validation_error('nominal'):.3f} m, median "
        f"joint batch {np.nanmedian(run.batch_errors['joint']):.3f} m, recommended theta "
        f"{run.validation_error('calibrated'):.3f} m, reachable "
        f"{evaluation.reachable_error:.3f} m\n"
    )
    for label, ok in checks:
        print(f"- [{'x' if ok else ' '}] {label}")
    return 0 if all(ok for _, ok in checks) else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--batches", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results/paper_scale"))
    parser.add_argument(
        "--method",
        choices=["staged", "joint", "both"],
        default="staged",
        help="both: staged then joint on the same drive, compared (writes methods.png)",
    )
    parser.add_argument(
        "--batch-solve",
        choices=["linearized", "exact"],
        default="linearized",
        help="joint batches from the segments' systems at the whole-log solution (default) "
        "or one solve per batch",
    )
    args = parser.parse_args(argv)

    drive = simulate_drive(args.length_km, seed=args.seed)
    write_synthetic_drive(drive, args.out / "drive.csv")
    settings = Settings(
        batches=BatchingSettings(count=args.batches, seed=args.seed, joint_solve=args.batch_solve)
    )
    runs, evaluations, stats, seconds = {}, {}, {}, {}
    say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731
    methods = ("staged", "joint") if args.method == "both" else (args.method,)
    for method in methods:
        start = time.perf_counter()
        runs[method] = run_calibration(
            drive.measured, settings, method, progress=say, workers=args.workers
        )
        seconds[method] = time.perf_counter() - start
        truth = Truth(drive.theta_true, drive.truth)
        evaluations[method] = evaluate(runs[method], truth, say, args.workers)
        out = args.out / method  # a result set of its own, beside the drive files
        write_results(runs[method], out, evaluation=evaluations[method])
        stats[method] = run_statistics(runs[method], evaluations[method])
    if args.method == "both":
        estimates = {
            "step1": runs["staged"].batch_estimates("step1"),
            "step5": runs["staged"].batch_estimates("step5"),
            "joint": runs["joint"].batch_estimates("joint"),
        }
        title = f"Estimates over {args.batches} batches: Step 1, staged Step 5, joint"
        atomic_save_figure(box_plots(estimates, title, drive.theta_true), args.out / "methods.png")
        print(f"staged: {seconds['staged'] / 60:.1f} min")
    if "joint" in runs:
        return report_joint(
            runs["joint"],
            evaluations["joint"],
            stats["joint"],
            args,
            seconds["joint"],
            stats.get("staged"),
        )
    run, stats, seconds = runs["staged"], stats["staged"], seconds["staged"]
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
    reachable = evaluations["staged"].reachable_error
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
