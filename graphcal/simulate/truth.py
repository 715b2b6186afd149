"""The known truth of a synthetic log, as ``graphcal calibrate`` finds it: ``theta_true`` in
a synthetic drive's JSON sidecar (with its noise-free drive, for the Cramér–Rao bound) or in
an imported synthetic recording's manifest. A real log has none."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from graphcal.data.drive_log import load_drive_log
from graphcal.errors import GraphcalError
from graphcal.evaluation import Truth
from graphcal.simulate.drive import read_sidecar, truth_path

if TYPE_CHECKING:
    from graphcal.data.importer import ImportedLog
    from graphcal.pipeline.calibration_run import CalibrationRun
    from graphcal.progress import Progress


def synthetic_truth(
    run: CalibrationRun,
    log_path: str | os.PathLike[str],
    imported: ImportedLog | None,
    progress: Progress,
) -> Truth | None:
    """The truth of the log ``run`` calibrated (at ``log_path``; ``imported`` if it was a
    recording), or ``None`` for a real log; ``progress`` hears where it comes from and why
    there is no Cramér–Rao bound when the noise-free drive is missing or unusable."""
    if imported is not None:
        if imported.truth is None:
            return None
        progress("synthetic recording: comparing with theta_true from its manifest")
        return Truth(imported.truth)
    return _sidecar_truth(run, Path(log_path), progress)


def _sidecar_truth(run: CalibrationRun, log_path: Path, progress: Progress) -> Truth | None:
    """The truth in a synthetic drive's sidecar, or ``None`` for a real log."""
    sidecar = read_sidecar(log_path, len(run.log))
    if sidecar is None:
        return None
    progress("synthetic drive: comparing with theta_true from its sidecar")
    path = truth_path(log_path)
    truth_log = None
    if not path.exists():
        # An imported recording's sidecar carries theta_true but no noise-free drive; only
        # `graphcal simulate` writes one, and only then is its absence worth a word.
        if str(sidecar.get("generator", "")).endswith("simulate"):
            progress(f"no Cramér–Rao bound: the noise-free drive {path} is missing")
    else:
        try:
            truth_log = load_drive_log(path, reverses=run.settings.vehicle.reverses)
        except GraphcalError as exc:
            progress(f"no Cramér–Rao bound: cannot use {path}: {exc}")
    if truth_log is not None and len(truth_log) != len(run.log):
        progress(
            f"no Cramér–Rao bound: {path.name} has {len(truth_log)} samples, the log {len(run.log)}"
        )
        truth_log = None
    return Truth(sidecar["theta_true"], truth_log)
