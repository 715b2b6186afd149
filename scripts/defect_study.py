"""Each defect of real logs alone and all together: the error graphcal makes, in its own σ,
and whether its truth-free checks distrust the result.

    python scripts/defect_study.py [--length-km 24] [--seeds 2] [--batches 60] [--workers 2]

For every condition (none, each name of ``graphcal.simulate.defects.ALL_NAMES``, all) and
seed: ``simulate_drive`` + ``degrade``, validated and screened as ``graphcal calibrate``
loads a CSV (spikes and frozen fixes masked), the joint method with ``--batches`` batches, then the
recommended theta's error to the truth over its reported σ per parameter, the whole-log
χ²/dof, the largest batch spread ratio and the trust verdict. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from graphcal.data.drive_log import validate_frame
from graphcal.errors import GraphcalError
from graphcal.evaluation import Truth, evaluate
from graphcal.pipeline.run import run_calibration
from graphcal.pipeline.settings import Settings
from graphcal.simulate.defects import ALL_NAMES, degrade, parse_defects
from graphcal.simulate.drive import simulate_drive


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--seeds", type=int, nargs="+", default=[2])
    parser.add_argument("--batches", type=int, default=60)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--conditions", nargs="+", default=["none", *ALL_NAMES, "all"])
    args = parser.parse_args(argv)
    settings = Settings()
    settings = dataclasses.replace(
        settings, batches=dataclasses.replace(settings.batches, count=args.batches)
    )
    print(
        "| defect | seed | c_e | c_d | t_r | d | χ²/dof | max spread | verdict |\n"
        "|---|---|---|---|---|---|---|---|---|"
    )
    for condition in args.conditions:
        for seed in args.seeds:
            drive = simulate_drive(args.length_km, seed)
            if condition != "none":
                drive = degrade(drive, parse_defects(condition), seed)
            try:
                # As `graphcal calibrate` loads a CSV: validated, spikes and frozen fixes masked.
                log = validate_frame(
                    drive.measured.to_dataframe(),
                    f"{condition}, seed {seed}",
                    settings.segments.length,
                )
                run = run_calibration(log, settings, "joint", workers=args.workers)
            except GraphcalError as exc:
                print(f"| {condition} | {seed} | failed: {exc} | | | | | | |", flush=True)
                continue
            sigma = np.sqrt(np.diag(run.covariance))
            z = evaluate(run, Truth(drive.theta_true)).theta_error / sigma
            trust = run.trust
            spread = "–" if trust.spread_ratio is None else f"{np.nanmax(trust.spread_ratio):.1f}"
            verdict = "trusted" if trust.trusted else "**not trusted**"
            cells = " | ".join(f"{v:+.1f}σ" for v in z)
            print(
                f"| {condition} | {seed} | {cells} | {trust.chi2_per_dof:.2f} | {spread} | "
                f"{verdict} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
