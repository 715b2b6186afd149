"""One fleet log's calibration — the Dask task — and the key that makes a fleet run resumable.

The task runs the whole-log joint calibration (``run_calibration(..., "whole")``: the
recommended theta with its covariance, no batch study) on one process and returns a plain
``dict`` (JSON-ready, SI units), never an exception: a log that cannot be calibrated comes
back with ``status = "failed"`` and its one-line reason, so it does not stop the others.

A result's ``key`` hashes the log's bytes, the settings and graphcal's version: a result
on disk with the same key is the result a new run would compute, and is kept.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from graphcal import __version__
from graphcal.errors import GraphcalError, exception_reason, first_line
from graphcal.fleet.sources import FleetLog
from graphcal.pipeline.configuration.settings import Settings

#: Bytes read at a time while hashing a log.
CHUNK_BYTES = 1 << 20
#: The method of every fleet log: the whole-log joint solve.
FLEET_METHOD = "whole"


def content_hash(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a log's bytes (of every file, with its relative name, for a directory)."""
    path = Path(path)
    digest = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        if path.is_dir():
            digest.update(str(file.relative_to(path)).encode())
        with open(file, "rb") as handle:
            while block := handle.read(CHUNK_BYTES):
                digest.update(block)
    return digest.hexdigest()


def result_key(content: str, settings: Settings) -> str:
    """The key of a log's result: its content hash, the settings and graphcal's version."""
    document = json.dumps(
        {
            "content": content,
            "settings": settings.to_dict(),
            "method": FLEET_METHOD,
            "graphcal": __version__,
        },
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(document.encode()).hexdigest()


def failed_result(log: FleetLog, key: str, reason: str, retry: bool = True) -> dict[str, Any]:
    """A failed log's result with every field of :func:`calibrate_fleet_log` (``None`` where
    there is no value); ``retry`` marks a failure that is not the log's own."""
    out: dict[str, Any] = {
        "vehicle": log.vehicle,
        "day": log.day,
        "path": str(log.path),
        "key": key,
        "status": "failed",
        "reason": reason,
        "theta": None,
        "covariance": None,
        "calibrated": None,
        "verdicts": None,
        "posterior_theta": None,
        "posterior_covariance": None,
        "prior_mean": None,
        "prior_sigmas": None,
        "chi2_per_dof": None,
        "trusted": None,
        "warnings": [],
        "distance_m": None,
        "segments": None,
        "seconds": 0.0,
        "graphcal": __version__,
    }
    if retry:
        out["retry"] = True
    return out


def calibrate_fleet_log(log: FleetLog, settings: Settings, key: str) -> dict[str, Any]:
    """Calibrate one log (in one process) and describe the result; never raises for a bad
    log. Fields: ``vehicle, day, path, key, status ("ok" | "failed"), reason, theta,
    covariance`` (the recommended theta: unobservable parameters held at the prior, as
    ``graphcal calibrate`` reports it), ``calibrated, verdicts, posterior_theta,
    posterior_covariance`` (the whole-log posterior under the weak prior ``prior_mean,
    prior_sigmas``: what day-to-day comparisons use), ``chi2_per_dof, trusted, warnings,
    distance_m, segments, seconds, graphcal`` (SI; ``None`` where a failed log has none);
    ``retry: True`` marks a failure that is not the log's own (an ``OSError``, a bug), which
    is not kept for the next run."""
    start = time.perf_counter()
    out = failed_result(log, key, "", retry=False)
    if not Path(log.path).exists():  # not this log's fault: another machine may see it
        out["reason"] = f"{log.path} not found on the worker that ran it"
        out["retry"] = True
        return out
    try:
        out.update(_calibrate(log, settings))
        out["status"] = "ok"
    except GraphcalError as exc:  # the log itself: the same again on every run
        out["reason"] = exception_reason(exc)
    except Exception as exc:  # the machine (a path it cannot see, memory) or a bug: retried
        out["reason"] = f"{type(exc).__name__}: {first_line(str(exc))}"
        out["retry"] = True
    out["seconds"] = time.perf_counter() - start
    return out


def _calibrate(log: FleetLog, settings: Settings) -> dict[str, Any]:
    from graphcal.pipeline.end_to_end.run import run_calibration
    from graphcal.recording.open_log import open_log

    nominal = settings.vehicle.theta_nominal
    drive, _ = open_log(log.path, settings.vehicle, min_distance=settings.segments.length)
    run = run_calibration(drive, settings, FLEET_METHOD, workers=1)
    if run.whole is None or run.covariance is None or not np.all(np.isfinite(run.covariance)):
        raise GraphcalError("the solve gave no covariance")
    whole = run.whole
    chi2 = whole.chi2_per_dof
    joint = settings.joint
    return {
        "theta": [float(x) for x in run.theta],
        "covariance": np.asarray(run.covariance, float).tolist(),
        "calibrated": [bool(x) for x in run.observability.calibrated],
        "verdicts": run.observability.verdicts(),
        "posterior_theta": [float(x) for x in whole.theta],
        "posterior_covariance": np.asarray(whole.covariance, float).tolist(),
        "prior_mean": [float(x) for x in joint.theta_initial],
        "prior_sigmas": [float(x) for x in joint.theta_prior_sigmas],
        "chi2_per_dof": None if chi2 is None else float(chi2),
        "trusted": None if run.trust is None else bool(run.trust.trusted),
        "warnings": list(run.warnings),
        "distance_m": float(drive.travelled_distance(float(nominal[0]))[-1]),
        "segments": len(run.selected),
    }
