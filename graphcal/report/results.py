"""Result files of a calibration run: ``calibration.json``, ``validation.csv`` and PNG figures.

Everything is computed before the first file is written, and each file is written atomically,
so an interrupted or failed run never leaves a half-written result.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import gtsam
import numpy as np
import pandas as pd

from graphcal import __version__
from graphcal.files import atomic_save_figure, atomic_write_csv, atomic_write_text
from graphcal.model import PARAMETER_NAMES, THETA_NOMINAL
from graphcal.pipeline.run import CalibrationRun
from graphcal.report.figures import route_figure, trajectory_figure, validation_figure
from graphcal.report.tables import error_table, theta_table
from graphcal.units import DISPLAY_UNITS, to_display


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


def results_document(run: CalibrationRun) -> dict:
    """The content of ``calibration.json`` (SI values; display units in ``theta_display``)."""
    s = run.settings
    doc: dict = {
        "theta": _named(run.theta),
        "theta_units": {"c_e": "m", "c_d": "m", "t_r": "m", "d": "s^2 (m per m/s^2)"},
        "theta_display": {
            f"{n} [{u}]": float(v)
            for n, u, v in zip(PARAMETER_NAMES, DISPLAY_UNITS, to_display(run.theta), strict=True)
        },
        "theta_nominal": _named(THETA_NOMINAL),
        "method": "batch Levenberg-Marquardt over all selected segments (paper section 4.1)",
        "log": {
            "file": run.log.source,
            "samples": len(run.log),
            "dt_s": run.log.dt,
            "duration_s": float(run.log.t[-1] - run.log.t[0]),
            "distance_m": float(run.log.travelled_distance()[-1]),
        },
        "segments": {
            "calibration": len(run.segments),
            "selected": len(run.selected),
            "validation": len(run.validation),
        },
        "solve": {
            "iterations": run.calibration.iterations,
            "initial_error": run.calibration.initial_error,
            "final_error": run.calibration.final_error,
        },
        "validation_error_m": {
            name: {
                "median": float(np.median(e)),
                "p75": float(np.percentile(e, 75)),
                "max": float(np.max(e)),
            }
            for name, e in run.validation_errors.items()
        },
        "settings": {
            "segment_length_m": s.segment_length,
            "segment_stride_m": s.segment_stride,
            "min_yaw_rate_rad_s": s.min_yaw_rate,
            "yaw_statistic": s.yaw_statistic,
            "yaw_window_s": s.yaw_window,
            "validation_length_m": s.validation_length,
            "theta_initial": _named(s.batch.theta_initial),
            "theta_prior_sigmas": _named(s.batch.theta_prior_sigmas),
            "pose_weights": list(s.batch.pose_weights),
            "position_sigma_m": s.batch.position_sigma,
            "estimate_start_poses": s.batch.estimate_start_poses,
            "max_iterations": s.batch.max_iterations,
        },
        "versions": {"graphcal": __version__, "gtsam": getattr(gtsam, "__version__", "unknown")},
    }
    if run.theta_true is not None:
        doc["theta_true"] = _named(run.theta_true)
        doc["theta_error"] = _named(run.theta - run.theta_true)
    return _finite(doc)


def summary_text(run: CalibrationRun) -> str:
    """The human-readable summary printed by the CLI."""
    rows = {"nominal": THETA_NOMINAL, "calibrated": run.theta}
    if run.theta_true is not None:
        rows["true"] = run.theta_true
    return f"{theta_table(rows)}\n\n{error_table(run.validation_errors)}"


def write_results(run: CalibrationRun, out_dir: str | os.PathLike[str]) -> list[Path]:
    """Write ``calibration.json``, ``validation.csv`` and the figures into ``out_dir``."""
    out = Path(out_dir)
    document = json.dumps(results_document(run), indent=2, allow_nan=False) + "\n"
    table = pd.DataFrame(
        {
            "segment": np.arange(len(run.validation)),
            "start_t_s": run.log.t[run.validation_segments.start],
            "end_t_s": run.log.t[run.validation_segments.stop],
            **{f"error_{name}_m": e for name, e in run.validation_errors.items()},
        }
    )
    figures = {
        "route.png": route_figure(run),
        "validation.png": validation_figure(run),
        "trajectory.png": trajectory_figure(run),
    }
    written = [
        atomic_write_text(out / "calibration.json", document),
        atomic_write_csv(table, out / "validation.csv"),
    ]
    written += [atomic_save_figure(fig, out / name) for name, fig in figures.items()]
    return written
