"""Staged vs joint on several synthetic drives: per-batch RMSE and the recommended theta.

    python scripts/compare_methods.py --seeds 0 1 2 --batches 200 --workers 2

For each seed: a 24 km city drive at the paper's noise levels, calibrated with the staged
and the joint method on the same batches. Prints, per seed, the per-batch RMSE of staged
Step 5 and joint next to the per-batch Cramér–Rao bound, the error of each method's
recommended theta (staged: median of Step 5; joint: the solve over all selected segments),
and the RMS of those errors over the seeds (mm; d in mm·s²/m).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from graphcal.evaluation import Truth, evaluate
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.report.document import run_statistics, uncertainty_summary
from graphcal.simulate.drive import simulate_drive
from graphcal.units import DEVIATION_SCALE


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--batches", type=int, default=200)
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    say = lambda line: print(line, file=sys.stderr, flush=True)  # noqa: E731

    final_errors: dict[str, list[np.ndarray]] = {"staged": [], "joint": []}
    header = "| seed | parameter | staged Step 5 RMSE | joint RMSE | per-batch CRB | "
    header += "staged final − true | joint final − true |"
    print(header + "\n|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        drive = simulate_drive(args.length_km, seed=seed)
        settings = Settings(batches=BatchingSettings(count=args.batches, seed=seed))
        runs = {
            method: run_calibration(
                drive.measured, settings, method, progress=say, workers=args.workers
            )
            for method in ("staged", "joint")
        }
        truth = Truth(drive.theta_true, drive.truth)
        evaluations = {m: evaluate(run, truth, say, args.workers) for m, run in runs.items()}
        staged = run_statistics(runs["staged"], evaluations["staged"])
        joint = run_statistics(runs["joint"], evaluations["joint"])
        crb = uncertainty_summary(runs["joint"], evaluations["joint"])["joint"]["crb_sigma"]
        for method, run in runs.items():
            final_errors[method].append(run.theta - drive.theta_true)
        for i, name in enumerate(PARAMETER_NAMES):
            s = DEVIATION_SCALE[i]
            print(
                f"| {seed} | {name} | {staged['step5'][name]['rmse'] * s:.3f} "
                f"| {joint['joint'][name]['rmse'] * s:.3f} | {crb[name] * s:.3f} "
                f"| {final_errors['staged'][-1][i] * s:+.3f} "
                f"| {final_errors['joint'][-1][i] * s:+.3f} |"
            )
    print(f"\nrecommended theta, RMS error over seeds {' '.join(map(str, args.seeds))}:\n")
    print("| parameter | staged | joint |\n|---|---|---|")
    rms = {m: np.sqrt(np.mean(np.square(e), axis=0)) for m, e in final_errors.items()}
    for i, name in enumerate(PARAMETER_NAMES):
        s = DEVIATION_SCALE[i]
        print(f"| {name} | {rms['staged'][i] * s:.3f} | {rms['joint'][i] * s:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
