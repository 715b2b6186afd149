"""Open a drive log by path, whatever it is: a drive-log CSV, or a recording (a streams
manifest, its directory, a ROS bag or an MCAP file) imported in memory.

What ``graphcal calibrate``, ``graphcal check`` and a fleet's task do with a log argument.
"""

from __future__ import annotations

import os
from pathlib import Path

from graphcal.log.drive_log import DriveLog
from graphcal.log.load import load_drive_log
from graphcal.recording.importer import BagOptions, ImportedLog, import_recording, is_recording
from graphcal.vehicle import VehicleProfile


def recording_path(text: str | os.PathLike[str]) -> Path:
    """A log or recording argument as a path: a directory holding ``manifest.toml`` (as
    ``graphcal simulate --streams DIR`` writes) is that recording, unless it is a ROS 2 bag."""
    path = Path(text)
    manifest = path / "manifest.toml"
    if path.is_dir() and manifest.is_file() and not (path / "metadata.yaml").exists():
        return manifest
    return path


def open_log(
    path: str | os.PathLike[str],
    vehicle: VehicleProfile,
    *,
    min_distance: float = 0.0,
    rate: float | None = None,
    max_gap: float | None = None,
    bag: BagOptions | None = None,
) -> tuple[DriveLog, ImportedLog | None]:
    """The drive log at ``path`` and, for a recording, its import (else ``None``).

    Args:
        path: a drive-log CSV, or a streams manifest, ROS bag or MCAP file (imported in
            memory: :func:`~graphcal.recording.importer.import_recording`).
        vehicle: its nominal theta (SI) and ``reverses`` check the log's plausibility.
        min_distance: shortest acceptable travelled distance [m].
        rate, max_gap, bag: a recording's drive-log rate [Hz], masking gap [s] and bag
            topics (defaults: the manifest's, else detected).

    Raises:
        GraphcalError: one line naming the file and what is wrong with it.
    """
    nominal = vehicle.theta_nominal
    if is_recording(path):
        imported = import_recording(
            path,
            rate=rate,
            max_gap=max_gap,
            bag=bag,
            nominal=nominal,
            min_distance=min_distance,
            reverses=vehicle.reverses,
        )
        return imported.log, imported
    log = load_drive_log(
        path, min_distance=min_distance, nominal=nominal, reverses=vehicle.reverses
    )
    return log, None
