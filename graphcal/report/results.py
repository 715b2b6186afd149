"""Result files of a calibration run: ``calibration.json``, ``batches.csv``,
``validation.csv`` and PNG figures.

Everything is computed before the first file is written, each file is written atomically and
non-finite numbers never reach a file (failed batches are empty cells in ``batches.csv``).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal import __version__
from graphcal.evaluation import Evaluation
from graphcal.factors import pose_sigmas
from graphcal.files import atomic_save_figure, atomic_write_csv, atomic_write_text
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.run import CalibrationRun, slip_line
from graphcal.report.figure_style import trusted
from graphcal.report.figures import figures
from graphcal.report.result_set import replace_result_set
from graphcal.report.tables import (
    NOT_OBSERVABLE,
    PAPER_IQR_REDUCTION,
    Z95,
    estimates_table,
    interval_table,
    iqr_reduction,
    step_statistics,
    steps_table,
    theta_table,
    validation_table,
)
from graphcal.units import DEVIATION_SCALE, DISPLAY_UNITS, to_display


def _named(theta: np.ndarray) -> dict[str, float]:
    return {n: float(v) for n, v in zip(PARAMETER_NAMES, theta, strict=True)}


def _finite(obj: object) -> object:
    """Replace non-finite floats by ``None`` so no NaN ever reaches a result file."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def _theta_true(evaluation: Evaluation | None) -> np.ndarray | None:
    return None if evaluation is None else evaluation.theta_true


def run_statistics(run: CalibrationRun, evaluation: Evaluation | None = None) -> dict[str, dict]:
    """Per step or method: :func:`step_statistics` of its per-batch thetas (batches left
    out for a failed solve or an unobservable parameter excluded); with an evaluation, also
    bias and RMSE to the truth."""
    truth = _theta_true(evaluation)
    return {name: step_statistics(run.batch_estimates(name), truth) for name in run.batch_theta}


THETA_UNITS = {"c_e": "m", "c_d": "m", "t_r": "m", "d": "s^2 (m per m/s^2)"}


def parameter_summary(run: CalibrationRun, evaluation: Evaluation | None = None) -> dict[str, dict]:
    """Per parameter: value (SI), its standard deviation, 95 % interval and verdict.

    A parameter the data did not determine keeps its prior (nominal) value, has no sigma or
    interval and says so in ``status``. Staged runs have no covariance of the recommended
    theta (a median over batches); their entries carry the value and the method.
    """
    out: dict[str, dict] = {}
    for i, name in enumerate(PARAMETER_NAMES):
        entry: dict = {"value": float(run.theta[i]), "unit": THETA_UNITS[name]}
        if run.covariance is None or run.observability is None:
            entry["status"] = "calibrated (staged: median of Step 5 over the batches)"
            out[name] = entry
            continue
        sigma = float(np.sqrt(run.covariance[i, i]))
        verdict = run.verdicts()[name]
        if run.observability.calibrated[i]:
            entry["status"] = verdict
            entry["sigma"] = sigma
            entry["ci95"] = [entry["value"] - Z95 * sigma, entry["value"] + Z95 * sigma]
        elif run.observability.held[i]:
            entry["status"] = f"{verdict}: not estimated; the value is the nominal"
            entry["sigma"] = None
        else:
            entry["status"] = (
                "not calibrated: not observable from this drive; the value is the prior"
            )
            entry["sigma"] = None
            entry["prior_sigma"] = float(run.settings.joint.theta_prior_sigmas[i])
        entry["sigma_over_prior_sigma"] = float(run.observability.sigma_ratio[i])
        crb = None if evaluation is None else evaluation.crb
        if crb is not None and run.observability.calibrated[i]:
            entry["cramer_rao_sigma"] = float(np.sqrt(crb[i, i]))
        out[name] = entry
    return out


def uncertainty_summary(
    run: CalibrationRun, evaluation: Evaluation | None = None
) -> dict[str, dict]:
    """Per method with covariances: median per-batch sigma (SI) and, given an evaluation, NEES
    and the Cramér–Rao bound.

    ``nees_mean`` is the mean NEES over the batches (4 with 4 parameters when the reported
    covariance matches the actual errors). ``crb_sigma`` is the root mean Cramér–Rao
    variance over the batches that have it (``crb_batches``), the RMSE an efficient method
    reaches; ``rmse_over_crb`` compares the batches' RMSE with it. Excluded batches are left
    out.
    """
    out: dict[str, dict] = {}
    for name, covariances in run.batch_covariance.items():
        good = np.all(np.isfinite(covariances), axis=(1, 2))
        if name in run.batch_excluded:
            good &= run.batch_excluded[name] == ""
        if not good.any():
            continue
        sigmas = np.sqrt(np.diagonal(covariances[good], axis1=1, axis2=2))
        entry: dict = {
            "sigma_per_batch_median": dict(
                zip(PARAMETER_NAMES, map(float, np.median(sigmas, axis=0)), strict=True)
            )
        }
        if evaluation is not None:
            errors = run.batch_theta[name][good] - evaluation.theta_true
            nees = evaluation.batch_nees[name][good]
            entry["nees_mean"] = float(np.mean(nees))
            entry["nees_batches"] = len(nees)
            crb = evaluation.batch_crb.get(name)
            bounded = good & np.all(np.isfinite(crb), axis=(1, 2)) if crb is not None else None
            if bounded is not None and bounded.any():
                variances = np.diagonal(crb[bounded], axis1=1, axis2=2)
                crb_sigma = np.sqrt(np.mean(variances, axis=0))
                entry["crb_batches"] = int(bounded.sum())
                rmse = np.sqrt(np.mean(errors**2, axis=0))
                entry["crb_sigma"] = dict(zip(PARAMETER_NAMES, map(float, crb_sigma), strict=True))
                entry["rmse_over_crb"] = dict(
                    zip(PARAMETER_NAMES, map(float, rmse / crb_sigma), strict=True)
                )
        out[name] = entry
    return out


def validation_summary(
    run: CalibrationRun, evaluation: Evaluation | None = None
) -> dict[str, float]:
    """E_p [m] of nominal, recommended and (when known) true theta."""
    out = {
        "nominal": run.validation_error("nominal"),
        "calibrated": run.validation_error("calibrated"),
    }
    if evaluation is not None:
        out["reachable (true theta)"] = evaluation.reachable_error
    return out


def _gtsam_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("gtsam")
    except PackageNotFoundError:
        return "unknown"


def results_document(run: CalibrationRun, *, evaluation: Evaluation | None = None) -> dict:
    """The content of ``calibration.json`` (SI values; display units in ``theta_display``).

    It depends only on the log, the settings and (for synthetic drives) the evaluation —
    never on the number of workers — so the same inputs give a byte-identical file.
    """
    stats = run_statistics(run, evaluation)
    doc: dict = {
        "theta": _named(run.theta),
        "theta_units": THETA_UNITS,
        "theta_display": {
            f"{n} [{u}]": float(v)
            for n, u, v in zip(PARAMETER_NAMES, DISPLAY_UNITS, to_display(run.theta), strict=True)
        },
        "theta_nominal": _named(run.settings.vehicle.theta_nominal),
        "parameters": parameter_summary(run, evaluation),
        "method": run.method,
        "log": {
            "file": run.log.source,
            "samples": len(run.log),
            "dt_s": run.log.dt,
            "duration_s": float(run.log.t[-1] - run.log.t[0]),
            "distance_m": float(
                run.log.travelled_distance(run.settings.vehicle.theta_nominal[0])[-1]
            ),
        },
        "segments": {
            "calibration": len(run.segments),
            "selected": len(run.selected),
            "validation": len(run.validation),
        },
        "steps": stats,
        "uncertainty": uncertainty_summary(run, evaluation),
        "validation_error_m": {
            **validation_summary(run, evaluation),
            "per_step_median": {
                step: float(np.nanmedian(e)) if np.isfinite(e).any() else None
                for step, e in run.batch_errors.items()
            },
        },
    }
    if run.batches is not None:
        doc["batches"] = {
            "count": len(run.batches),
            "size": int(run.batches.shape[1]),
            "failed": {
                name: int((~np.all(np.isfinite(t), axis=1)).sum())
                for name, t in run.batch_theta.items()
            },
            # Which batches (rows of batches.csv) failed, per step or method.
            "failed_batches": {
                name: np.flatnonzero(~np.all(np.isfinite(t), axis=1)).tolist()
                for name, t in run.batch_theta.items()
                if not np.all(np.isfinite(t))
            },
            "excluded": {
                name: {
                    reason: int((reasons == reason).sum()) for reason in sorted(set(reasons) - {""})
                }
                for name, reasons in run.batch_excluded.items()
            },
        }
    if run.staged is not None:
        doc["iqr_reduction_percent"] = {
            "step1_to_step5": iqr_reduction(stats["step1"], stats["step5"]),
            "paper": PAPER_IQR_REDUCTION,
        }

    if evaluation is not None:
        doc["theta_true"] = _named(evaluation.theta_true)
        doc["theta_error"] = _named(evaluation.theta_error)
    if run.observability is not None and run.observability.degenerate:
        # Only parameters the data determined carry a number outside ``parameters``.
        doc["not_calibrated"] = run.observability.not_calibrated
        for name in run.observability.not_calibrated:
            i = PARAMETER_NAMES.index(name)
            doc["theta_display"][f"{name} [{DISPLAY_UNITS[i]}]"] = None
            if "theta_error" in doc:
                doc["theta_error"][name] = None
    if run.trust is not None:
        doc["trust"] = run.trust.to_dict()
    if run.estimated:
        doc["estimated"] = {name: e.to_dict() for name, e in run.estimated.items()}
    if run.down_weighted is not None:
        doc["down_weighted_fixes"] = run.down_weighted.to_dict()
    if run.whole is not None:
        joint = run.settings.joint
        used = pose_sigmas(joint.pose_weights, joint.position_sigma)
        doc["noise"] = {  # what the whole-log solve weighted the pose with, per component
            "position_sigma_m": float(used[0]),
            "heading_sigma_deg": float(np.degrees(used[2])),
            "position_sigma_from_residuals_m": run.whole.position_noise,
            "heading_from_log": bool(joint.heading_noise_from_log),
        }
    if run.whole is not None and run.whole.slip_statistic is not None:
        doc["wheel_slip"] = {
            "modelled": run.whole.slip_modelled,
            "chi2_drop_per_chunk": run.whole.slip_statistic,
            "detection_threshold": run.settings.joint.slip_detection,
        }
    doc["warnings"] = list(run.warnings)
    doc["settings"] = run.settings.to_dict()
    doc["versions"] = {"graphcal": __version__, "gtsam": _gtsam_version()}
    return _finite(doc)


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


def summary_text(run: CalibrationRun, evaluation: Evaluation | None = None) -> str:
    """The human-readable summary printed by the CLI.

    A run that failed a trust check shows its theta as ``estimated (not trusted)``, never as
    calibrated or recommended.
    """
    truth = _theta_true(evaluation)
    ours = "calibrated" if trusted(run) else NOT_TRUSTED_ROW
    rows = {"nominal": run.settings.vehicle.theta_nominal, ours: run.theta}
    if truth is not None:
        rows["true"] = truth
    hidden = set(run.observability.not_calibrated) if run.observability is not None else set()
    parts = [theta_table(rows, {ours: hidden})]
    if hidden:
        parts[0] += (
            f"\n{NOT_OBSERVABLE}: not observable from this drive, not calibrated "
            "(calibration.json keeps the nominal value and says so)"
        )
    if run.estimated:
        parts.append(estimates_table(run.estimated))
    if run.down_weighted is not None:
        parts.append(run.down_weighted.summary())
    if run.whole is not None and run.whole.slip_statistic is not None:
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
                estimated=run.observability.calibrated,
            )
        )
    if run.staged is not None:
        parts.append(steps_table(run_statistics(run, evaluation), truth is not None))
    elif run.method == "joint":
        parts.append(
            steps_table(
                run_statistics(run, evaluation),
                truth is not None,
                steps=("step1", "joint"),
                not_observable=hidden,
            )
        )
    for name, entry in uncertainty_summary(run, evaluation).items():
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
        parts.append(line)
    errors = validation_summary(run, evaluation)
    parts.append(validation_table({ours if k == "calibrated" else k: v for k, v in errors.items()}))
    if run.warnings:
        parts.append("\n".join(f"warning: {w}" for w in run.warnings))
    return "\n\n".join(parts)


def write_results(
    run: CalibrationRun,
    out_dir: str | os.PathLike[str],
    *,
    evaluation: Evaluation | None = None,
) -> list[Path]:
    """Write ``calibration.json``, ``validation.csv``, ``batches.csv`` and the figures into
    ``out_dir`` as one set (:mod:`graphcal.report.result_set`): an earlier result set there is
    replaced whole, an interrupted write leaves it as it was, and a directory holding other
    files is refused (:class:`~graphcal.errors.GraphcalError`).

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
    images = figures(run, evaluation)

    def write(directory: Path) -> list[Path]:
        written = [atomic_write_text(directory / "calibration.json", text)]
        written += [atomic_write_csv(frame, directory / name) for name, frame in tables.items()]
        written += [atomic_save_figure(fig, directory / name) for name, fig in images.items()]
        return written

    return replace_result_set(out, write)
