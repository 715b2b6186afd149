"""Result files of a calibration run: ``calibration.json``, ``batches.csv``,
``validation.csv`` and PNG figures.

Everything is computed before the first file is written, each file is written atomically and
non-finite numbers never reach a file (failed batches are empty cells in ``batches.csv``).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.evaluation import Evaluation
from graphcal.files import atomic_write_chunks, atomic_write_csv, atomic_write_text
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.methods.whole_log_lines import slip_line
from graphcal.report.document import (
    results_document,
    run_statistics,
    uncertainty_summary,
    validation_summary,
)
from graphcal.report.figure_style import trusted, vehicle_length_unit
from graphcal.report.figures import figures
from graphcal.report.rendering import rendered
from graphcal.report.result_set import replace_result_set
from graphcal.report.tables import (
    NOT_OBSERVABLE,
    estimates_table,
    interval_table,
    steps_table,
    theta_table,
    validation_table,
)
from graphcal.units import DEVIATION_SCALE


def batches_frame(run: CalibrationRun, evaluation: Evaluation | None = None) -> pd.DataFrame:
    """One row per batch: its segments and theta (SI) per step or method; empty if failed."""
    assert run.batches is not None
    frame = pd.DataFrame(
        {
            "batch": np.arange(len(run.batches)),
            "segments": [" ".join(map(str, b)) for b in run.batches],
        }
    )
    for step, thetas in run.batch_theta.items():
        for i, name in enumerate(PARAMETER_NAMES):
            frame[f"{step}_{name}"] = thetas[:, i]
        if step in run.batch_covariance:
            for i, name in enumerate(PARAMETER_NAMES):
                frame[f"{step}_sigma_{name}"] = np.sqrt(run.batch_covariance[step][:, i, i])
        if evaluation is not None and step in evaluation.batch_crb:
            crb = evaluation.batch_crb[step]
            for i, name in enumerate(PARAMETER_NAMES):
                frame[f"{step}_crb_sigma_{name}"] = np.sqrt(crb[:, i, i])
        if step in run.batch_excluded:
            frame[f"{step}_excluded"] = run.batch_excluded[step]
        frame[f"{step}_validation_error_m"] = run.batch_errors[step]
    return frame


#: Row name of the run's theta in the summary when a trust check failed (exit status 3).
NOT_TRUSTED_ROW = "estimated (not trusted)"


def not_observable(run: CalibrationRun) -> set[str]:
    """The parameters the run's data did not determine and did not move from the nominal
    (weakly determined ones are estimates, shown as numbers)."""
    o = run.observability
    if o is None:
        return set()
    return {n for n in o.not_calibrated if not o.weakly_determined[PARAMETER_NAMES.index(n)]}


def summary_text(run: CalibrationRun, evaluation: Evaluation | None = None) -> str:
    """The human-readable summary printed by the CLI.

    A run that failed a trust check shows its theta as ``estimated (not trusted)``, never as
    calibrated or recommended.
    """
    truth = None if evaluation is None else evaluation.theta_true
    ours = "calibrated" if trusted(run) else NOT_TRUSTED_ROW
    rows = {"nominal": run.settings.vehicle.theta_nominal, ours: run.theta}
    if truth is not None:
        rows["true"] = truth
    hidden = not_observable(run)
    parts = [theta_table(rows, {ours: hidden})]
    if hidden:
        parts[0] += (
            f"\n{NOT_OBSERVABLE}: not observable from this drive, not calibrated "
            "(calibration.json has its estimate, near the prior, with its σ)"
        )
    if run.estimated:
        parts.append(estimates_table(run.estimated, vehicle_length_unit(run)))
    if run.down_weighted is not None:
        parts.append(run.down_weighted.summary())
    if run.whole is not None and run.whole.slip_test is not None:
        parts.append(slip_line(run.whole, run.settings.joint))
    if run.covariance is not None and run.observability is not None:
        solve = f"joint solve over all {len(run.selected)} selected segments"
        parts.append(
            (
                f"recommended θ: {solve}"
                if trusted(run)
                else f"estimated θ, not trusted (see the warnings below): {solve}"
            )
            + "\n"
            + interval_table(
                run.theta,
                run.covariance,
                run.verdicts(),
                None if evaluation is None else evaluation.crb,
                truth,
                estimated=~run.observability.held,
            )
        )
    if run.staged is not None:
        parts.append(steps_table(run_statistics(run, evaluation), truth is not None))
    elif run.method == "joint" and run.batches is not None:  # a batch study was made
        parts.append(
            steps_table(
                run_statistics(run, evaluation),
                truth is not None,
                steps=("step1", "joint"),
                not_observable=hidden,
            )
        )
    for name, entry in uncertainty_summary(run, evaluation).items():
        parts.append(_uncertainty_line(name, entry))
    errors = validation_summary(run, evaluation)
    parts.append(
        validation_table(
            {ours if k == "calibrated" else k: v for k, v in errors.items()},
            vehicle_length_unit(run),
        )
    )
    if run.warnings:
        parts.append("\n".join(f"warning: {w}" for w in run.warnings))
    return "\n\n".join(parts)


def _uncertainty_line(name: str, entry: dict) -> str:
    """A method's line of the summary: its median per-batch 1σ and, with the truth, its
    NEES and RMSE over the Cramér–Rao bound (``entry``: :func:`uncertainty_summary`'s)."""
    sigma = entry["sigma_per_batch_median"]
    line = (
        f"{name}: per-batch 1σ (median) "
        + ", ".join(
            f"{p} {sigma[p] * DEVIATION_SCALE[i]:.3f}" for i, p in enumerate(PARAMETER_NAMES)
        )
        + " (mm; d in mm·s²/m)"
    )
    if "nees_mean" in entry:
        line += (
            f"; NEES {entry['nees_mean']:.2f} over {entry['nees_batches']} "
            + ("batch " if entry["nees_batches"] == 1 else "batches ")
            + "(4 = consistent)"
        )
    if "crb_sigma" in entry:
        line += "\n" + (
            f"{name}: RMSE / Cramér–Rao bound "
            + ", ".join(f"{p} {entry['rmse_over_crb'][p]:.2f}" for p in PARAMETER_NAMES)
            + " (1 = efficient)"
        )
    return line


def write_results(
    run: CalibrationRun,
    out_dir: str | os.PathLike[str],
    *,
    evaluation: Evaluation | None = None,
    workers: int = 1,
) -> list[Path]:
    """Write ``calibration.json``, ``validation.csv``, ``batches.csv`` and the figures into
    ``out_dir`` as one set (:mod:`graphcal.report.result_set`): an earlier result set there is
    replaced whole, an interrupted write leaves it as it was, and a directory holding other
    files is refused (:class:`~graphcal.errors.GraphcalError`). The figures are drawn in up
    to ``workers`` processes (:func:`~graphcal.report.rendering.rendered`; the same files).

    With an evaluation (synthetic drives) the files carry the truth, errors to it and the
    Cramér–Rao bound.
    """
    out = Path(out_dir)
    document = results_document(run, evaluation=evaluation)
    text = json.dumps(document, indent=2, allow_nan=False) + "\n"
    errors = dict(run.segment_errors)
    if evaluation is not None:
        errors["true"] = evaluation.validation_errors
    validation = pd.DataFrame(
        {
            "segment": np.arange(len(run.validation)),
            "start_t_s": run.log.t[run.validation_segments.start],
            "end_t_s": run.log.t[run.validation_segments.stop],
            **{f"error_{name}_m": e for name, e in errors.items()},
        }
    )
    tables = {"validation.csv": validation}
    if run.batches is not None:
        tables["batches.csv"] = batches_frame(run, evaluation)
    images = rendered(figures(run, evaluation), workers)

    def write(directory: Path) -> list[Path]:
        written = [atomic_write_text(directory / "calibration.json", text)]
        written += [atomic_write_csv(frame, directory / name) for name, frame in tables.items()]
        written += [atomic_write_chunks(directory / name, [png]) for name, png in images.items()]
        return written

    return replace_result_set(out, write)
