"""Each defect of real logs alone and all together: the error graphcal makes, in its own σ,
with the defect model (the defaults) and without it (``--no-defect-model``).

    python scripts/defect_study.py [--length-km 24] [--seeds 0 1 2] [--models after before]
        [--method whole] [--batches 60] [--workers 2] [--joint KEY=VALUE ...] [--jsonl F]

For every condition (``none``, each name of ``graphcal.simulate.defects.DEFECTS_IN_ALL``, ``all``)
and seed: ``simulate_drive`` + ``degrade``, validated and screened as ``graphcal calibrate``
loads a CSV (jumps and frozen fixes masked, isolated spikes flagged), then the method
(``whole`` by default; ``joint`` adds the batches and their NEES), and per parameter the
recommended theta's error to the truth and that error over the σ graphcal reports; the
whole-log χ²/dof, the trust verdict, the sensor estimates, the down-weighted fixes and the
run time. Prints a Markdown row per run; ``--jsonl`` also writes one JSON object per run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time

import numpy as np

from graphcal.errors import GraphcalError
from graphcal.evaluation import Truth, evaluate
from graphcal.log.validation import validate_frame
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.solvers.joint_settings import without_defect_model
from graphcal.simulate.defects import DEFECTS_IN_ALL, degrade, parse_defects
from graphcal.simulate.drive import simulate_drive
from graphcal.units import DEVIATION_SCALE

#: Acceptance limits of issue 13 with all defects together, SI.
ALL_DEFECTS_LIMITS = np.array([0.5e-3, 0.3e-3, 8e-3, 0.2e-3])


def settings_for(model: str, batches: int, joint_overrides: dict[str, float]) -> Settings:
    """The default settings (``after``) or the plain model (``before``), with overrides."""
    settings = Settings()
    joint = settings.joint if model == "after" else without_defect_model(settings.joint)
    joint = dataclasses.replace(joint, **joint_overrides)
    batching = dataclasses.replace(settings.batches, count=batches)
    return dataclasses.replace(settings, joint=joint, batches=batching)


def run_case(
    drive, condition: str, seed: int, model: str, method: str, settings: Settings, workers: int
) -> dict:
    """One calibration of one degraded drive: the numbers of a table row."""
    row = {"condition": condition, "seed": seed, "model": model, "method": method}
    started = time.perf_counter()
    try:
        log = validate_frame(
            drive.measured.to_dataframe(), f"{condition}, seed {seed}", settings.segments.length
        )
        run = run_calibration(log, settings, method, workers=workers)
    except GraphcalError as exc:
        row["failed"] = str(exc)
        return row
    row["seconds"] = time.perf_counter() - started
    sigma = np.sqrt(np.diag(run.covariance))
    evaluation = evaluate(run, Truth(drive.theta_true))
    error = evaluation.theta_error
    row.update(
        error=error.tolist(),
        sigma=sigma.tolist(),
        z=(error / sigma).tolist(),
        chi2_per_dof=run.trust.chi2_per_dof,
        trusted=run.trust.trusted,
        estimated={n: [e.value, e.sigma, e.verdict] for n, e in run.estimated.items()},
        down_weighted=0 if run.down_weighted is None else len(run.down_weighted.rows),
        flagged=0 if log.outlying is None else int(log.outlying.sum()),
        masked_s=0.0 if log.masked is None else float(log.masked.sum() * log.dt),
    )
    if "joint" in evaluation.batch_nees:
        row["nees"] = float(np.nanmean(evaluation.batch_nees["joint"]))
    return row


def markdown(row: dict) -> str:
    """One table row: the error in display units and in σ per parameter, and the checks."""
    head = f"| {row['condition']} | {row['seed']} | {row['model']} |"
    if "failed" in row:
        return f"{head} failed: {row['failed']} | | | | | |"
    cells = " | ".join(
        f"{e * s:+.2f} ({z:+.1f}σ)"
        for e, s, z in zip(row["error"], DEVIATION_SCALE, row["z"], strict=True)
    )
    verdict = "trusted" if row["trusted"] else "not trusted"
    nees = f" NEES {row['nees']:.1f} |" if "nees" in row else ""
    return (
        f"{head} {cells} | {row['chi2_per_dof']:.2f} | {verdict} | {row['seconds']:.0f} s |{nees}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--conditions", nargs="+", default=["none", *DEFECTS_IN_ALL, "all"])
    parser.add_argument("--models", nargs="+", choices=["after", "before"], default=["after"])
    parser.add_argument("--method", choices=["whole", "joint"], default="whole")
    parser.add_argument("--batches", type=int, default=60)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--joint", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--jsonl", help="append one JSON object per run to this file")
    args = parser.parse_args(argv)
    overrides = {k: float(v) for k, v in (item.split("=", 1) for item in args.joint)}
    print(
        "| defect | seed | model | c_e [mm] | c_d [mm] | t_r [mm] | d [mm·s²/m] | χ²/dof | "
        "verdict | time |\n|---|---|---|---|---|---|---|---|---|---|",
        flush=True,
    )
    for condition in args.conditions:
        for seed in args.seeds:
            drive = simulate_drive(args.length_km, seed)
            if condition != "none":
                drive = degrade(drive, parse_defects(condition), seed)
            for model in args.models:
                settings = settings_for(model, args.batches, overrides)
                row = run_case(drive, condition, seed, model, args.method, settings, args.workers)
                row["length_km"] = args.length_km
                print(markdown(row), flush=True)
                if args.jsonl:
                    with open(args.jsonl, "a") as out:
                        out.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
