"""Calibrate the drive log or recording at a path, as ``graphcal calibrate`` does: open it
(:func:`graphcal.recording.open_log.open_log`), run the calibration, and carry an import's doubts
into the run's warnings."""

from __future__ import annotations

import dataclasses
import os

from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun, Method
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.progress import Progress, reports_progress, say
from graphcal.recording.importer import BagOptions, ImportedLog
from graphcal.recording.open_log import open_log


@reports_progress
def calibrate_file(
    path: str | os.PathLike[str],
    settings: Settings,
    method: Method = "joint",
    *,
    rate: float | None = None,
    max_gap: float | None = None,
    bag: BagOptions | None = None,
    progress: Progress | None = None,
    workers: int = 1,
) -> tuple[CalibrationRun, ImportedLog | None]:
    """Calibrate theta from the log at ``path`` (a drive-log CSV, or a recording imported in
    memory: ``rate`` [Hz], ``max_gap`` [s] and ``bag`` as in
    :func:`~graphcal.recording.open_log.open_log`); returns the run and the import (or ``None``).

    Segments shorter than ``settings.segments.length`` make the log too short; a recording's
    import warnings come first in the run's warnings.

    Raises:
        GraphcalError: the log cannot be read or calibrated.
    """
    log, imported = open_log(
        path,
        settings.vehicle,
        min_distance=settings.segments.length,
        rate=rate,
        max_gap=max_gap,
        bag=bag,
    )
    what = "imported" if imported else "loaded"
    distance = log.travelled_distance(settings.vehicle.theta_nominal[0])[-1]
    say(f"{what} {path}: {len(log)} samples, {distance:.0f} m")
    if imported is not None:
        for line in imported.lines():
            say(line)
    run = run_calibration(log, settings, method, workers=workers)
    if imported is not None and imported.warnings:  # the import's doubts go with the result
        run = dataclasses.replace(run, warnings=(*imported.warnings, *run.warnings))
    return run, imported
