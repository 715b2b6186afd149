"""Where ``graphcal simulate`` may write: never over a file graphcal did not write.

``simulate --out FILE.csv`` writes ``FILE.csv``, ``FILE_truth.csv`` and the sidecar
``FILE.json``; ``--streams DIR`` the streams, a manifest, ``truth.json`` and bags into DIR;
``--fleet DIR`` a tree of drives and ``fleet_truth.csv``. Each replaces its own earlier
output (a sidecar or ``truth.json`` whose ``generator`` names graphcal), as ``import`` and
``calibrate`` do, and refuses anything else before it simulates (issue 44: a user's
``mine.csv`` and ``gnss.csv`` were overwritten, exit 0).
"""

from __future__ import annotations

import os
from pathlib import Path

from graphcal.errors import GraphcalError
from graphcal.files import graphcal_json


def drive_files(csv_path: str | os.PathLike[str]) -> list[Path]:
    """The files ``simulate --out CSV`` writes: the CSV, its truth and its sidecar."""
    path = Path(csv_path)
    return [path, path.with_name(f"{path.stem}_truth.csv"), path.with_name(f"{path.stem}.json")]


def check_simulate_output(
    out: str | os.PathLike[str] | None = None,
    streams: str | os.PathLike[str] | None = None,
    fleet: str | os.PathLike[str] | None = None,
) -> None:
    """Raise :class:`GraphcalError` (one line) if the given output (``--out`` CSV,
    ``--streams`` directory or ``--fleet`` directory) would overwrite files graphcal did not
    write; checked before anything is simulated."""
    if out is not None:
        _check_drive(Path(out))
    for flag, directory, mark in (("--streams", streams, "truth.json"), ("--fleet", fleet, None)):
        if directory is not None:
            _check_directory(flag, Path(directory), mark)


def _check_drive(out: Path) -> None:
    if out.is_dir():
        raise GraphcalError(f"--out {out}: is a directory; give the drive-log CSV's path")
    files = drive_files(out)
    if any(path.exists() for path in files) and graphcal_json(files[-1]) is None:
        raise GraphcalError(
            f"--out {out}: would overwrite a file graphcal did not write (a drive graphcal "
            f"wrote has its {files[-1].name} beside it); choose another path or remove it"
        )


def _check_directory(flag: str, directory: Path, mark: str | None) -> None:
    """A directory output: new, empty or graphcal's own (its ``mark`` file graphcal's JSON;
    a fleet's: drives graphcal wrote and its ``fleet_truth.csv``)."""
    if directory.exists() and not directory.is_dir():
        raise GraphcalError(f"{flag} {directory}: exists and is not a directory")
    if not directory.is_dir() or not any(directory.iterdir()):
        return
    if mark is not None:
        ours = graphcal_json(directory / mark) is not None
    else:
        sidecars = list(directory.glob("*/*.json"))
        ours = (directory / "fleet_truth.csv").is_file() and all(
            graphcal_json(path) is not None for path in sidecars
        )
    if not ours:
        raise GraphcalError(
            f"{flag} {directory}: holds files graphcal did not write; "
            "choose a new or empty directory"
        )
