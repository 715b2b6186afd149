"""The content of ``calibration.json``: theta with its uncertainty and verdicts, the log and
segments, the statistics of each step or method over the batches, the validation errors,
and what the run found or was told (trust, estimated sensor errors, noise, warnings,
settings, versions), section by section.
"""

from __future__ import annotations

import math

import numpy as np

from graphcal import __version__
from graphcal.evaluation import Evaluation
from graphcal.factors import pose_sigmas
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.report.tables import (
    PAPER_IQR_REDUCTION,
    Z95,
    iqr_reduction,
    step_statistics,
)
from graphcal.units import DISPLAY_UNITS, to_display


def _degrees(radians: float | None) -> float | None:
    """``radians`` in degrees, ``None`` kept."""
    return None if radians is None else float(np.degrees(radians))


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

    Every estimated parameter has its posterior value under the weak prior, its marginal σ and
    95 % interval; ``status`` says how well the data determined it (``calibrated``; ``not
    calibrated: weakly determined ...``; ``not calibrated: not observable ...``). One the
    vehicle profile holds has the nominal and no σ. Staged runs have no covariance of the
    recommended theta (a median over batches); their entries carry the value and the method.
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
        entry["sigma"] = sigma
        entry["ci95"] = [entry["value"] - Z95 * sigma, entry["value"] + Z95 * sigma]
        if run.observability.calibrated[i]:
            entry["status"] = verdict
        elif run.observability.held[i]:
            entry["status"] = f"{verdict}: not estimated; the value is the nominal"
            entry["sigma"] = None
            del entry["ci95"]
        elif run.observability.weakly_determined[i]:
            entry["status"] = (
                "not calibrated: weakly determined (the data's information about it is at "
                "least the reference prior's); the estimate with its σ"
            )
        else:
            entry["status"] = (
                "not calibrated: not observable from this drive; the estimate stays near the "
                "prior, with about its σ"
            )
            entry["prior_sigma"] = float(run.settings.joint.theta_prior_sigmas[i])
        # the σ the data give it over the reference sigma its verdict is judged against
        entry["sigma_over_reference_sigma"] = float(run.observability.sigma_ratio[i])
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
        **_theta_section(run),
        "parameters": parameter_summary(run, evaluation),
        "method": run.method,
        "log": _log_section(run),
        "segments": {
            "calibration": len(run.segments),
            "selected": len(run.selected),
            "validation": len(run.validation),
        },
        "steps": stats,
        "uncertainty": uncertainty_summary(run, evaluation),
        "validation_error_m": _validation_section(run, evaluation),
    }
    if run.batches is not None:
        doc["batches"] = _batches_section(run)
    if run.staged is not None:
        doc["iqr_reduction_percent"] = {
            "step1_to_step5": iqr_reduction(stats["step1"], stats["step5"]),
            "paper": PAPER_IQR_REDUCTION,
        }

    if evaluation is not None:
        doc["theta_true"] = _named(evaluation.theta_true)
        doc["theta_error"] = _named(evaluation.theta_error)
    if run.observability is not None and run.observability.degenerate:
        _mark_not_calibrated(doc, run.observability.not_calibrated)
    doc.update(_findings_sections(run))
    doc["warnings"] = list(run.warnings)
    doc["settings"] = run.settings.to_dict()
    doc["versions"] = {"graphcal": __version__, "gtsam": _gtsam_version()}
    return _finite(doc)


def _theta_section(run: CalibrationRun) -> dict:
    """The run's theta (SI), its units, in display units, and the nominal theta."""
    return {
        "theta": _named(run.theta),
        "theta_units": THETA_UNITS,
        "theta_display": {
            f"{n} [{u}]": float(v)
            for n, u, v in zip(PARAMETER_NAMES, DISPLAY_UNITS, to_display(run.theta), strict=True)
        },
        "theta_nominal": _named(run.settings.vehicle.theta_nominal),
    }


def _log_section(run: CalibrationRun) -> dict:
    """The log's file, samples, sample period [s], duration [s] and distance [m] (with the
    nominal c_e)."""
    return {
        "file": run.log.source,
        "samples": len(run.log),
        "dt_s": run.log.dt,
        "duration_s": float(run.log.t[-1] - run.log.t[0]),
        "distance_m": float(run.log.travelled_distance(run.settings.vehicle.theta_nominal[0])[-1]),
    }


def _validation_section(run: CalibrationRun, evaluation: Evaluation | None) -> dict:
    """E_p [m] of each theta (:func:`validation_summary`) and the median E_p of each step's
    batches."""
    return {
        **validation_summary(run, evaluation),
        "per_step_median": {
            step: float(np.nanmedian(e)) if np.isfinite(e).any() else None
            for step, e in run.batch_errors.items()
        },
    }


def _batches_section(run: CalibrationRun) -> dict:
    """The batches' count and size, and per step or method how many (and which) failed and
    how many were excluded, per reason."""
    return {
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
            name: {reason: int((reasons == reason).sum()) for reason in sorted(set(reasons) - {""})}
            for name, reasons in run.batch_excluded.items()
        },
    }


def _mark_not_calibrated(doc: dict, not_calibrated: list[str]) -> None:
    """List the parameters the data did not determine (their numbers stay: each is its
    estimate with its σ)."""
    doc["not_calibrated"] = not_calibrated


def _findings_sections(run: CalibrationRun) -> dict:
    """What the run found, where it has it: the trust checks, the estimated sensor errors,
    the down-weighted fixes, the noise the whole-log solve weighted the pose with and the
    wheel-slip test."""
    out: dict = {}
    if run.trust is not None:
        out["trust"] = run.trust.to_dict()
    if run.estimated:
        out["estimated"] = {name: e.to_dict() for name, e in run.estimated.items()}
    if run.model_check is not None:
        out["model_check"] = run.model_check.to_dict()
    if run.down_weighted is not None:
        out["down_weighted_fixes"] = run.down_weighted.to_dict()
    if run.whole is not None:
        joint = run.settings.joint
        used = pose_sigmas(joint.pose_weights, joint.position_sigma)
        out["noise"] = {  # what the whole-log solve weighted the pose with, per component
            "position_sigma_m": float(used[0]),
            "heading_sigma_deg": float(np.degrees(used[2])),
            "position_sigma_from_residuals_m": run.whole.position_noise,
            "fix_error_correlation": run.whole.noise.position_correlation,
            "heading_sigma_from_residuals_deg": _degrees(run.whole.noise.heading),
            "heading_error_correlation": run.whole.noise.heading_correlation,
            "wheel_noise_rev": float(joint.wheel_noise),
            "wheel_correction_chi2_per_row": run.whole.noise.wheel_chi2,
            "heading_from_log": bool(joint.heading_noise_from_log),
            "wheel_noise_from_log_rev": run.log.wheel_noise,
        }
    if run.whole is not None and run.whole.slip_test is not None:
        out["wheel_slip"] = {
            "modelled": run.whole.slip_modelled,
            **run.whole.slip_test.to_dict(),
            "false_alarm_rate": run.settings.joint.slip_alpha,
        }
    return out
