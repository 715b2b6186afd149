"""The result directory as a set: checked before the run, replaced whole at its end.

A calibration writes several files (``calibration.json``, CSV tables, figures). They belong
together, so:

* :func:`check_output_directory` runs before any computation: the directory must be new,
  empty or an earlier graphcal result set, and its place writable — a user learns of a typo
  in ``--out`` in a second, not after minutes of calibration;
* :func:`replace_result_set` writes the new set into a hidden temporary directory beside the
  target and swaps it in at the end. An interrupted run leaves the previous complete set (or
  nothing), never a mix, and files of an earlier run that this run does not produce (e.g. a
  staged run's ``wheel_rotations.png`` under a joint result) do not survive.

A directory holding anything else is refused rather than replaced: graphcal never deletes a
file it did not write.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from graphcal.errors import GraphcalError

#: Every file name a result set can hold.
RESULT_FILES = frozenset(
    {
        "calibration.json",
        "validation.csv",
        "batches.csv",
        "route.png",
        "validation.png",
        "trajectory.png",
        "parameters.png",
        "batch_intervals.png",
        "wheel_rotations.png",
    }
)


def is_result_set(path: Path) -> bool:
    """True if ``path`` is a directory holding an earlier graphcal result set and nothing else."""
    names = {entry.name for entry in path.iterdir()}
    return "calibration.json" in names and names <= RESULT_FILES


def check_output_directory(path: str | os.PathLike[str]) -> Path:
    """Check that results can be written to ``path``; return it as a ``Path``.

    Raises:
        GraphcalError: one line, if ``path`` is a file, a directory with other content, or in
            a place that cannot be written.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise GraphcalError(f"--out {out}: exists and is not a directory; name a directory")
    if out.is_dir() and any(out.iterdir()) and not is_result_set(out):
        foreign = sorted(e.name for e in out.iterdir() if e.name not in RESULT_FILES)
        shown = ", ".join(foreign[:3]) + (" …" if len(foreign) > 3 else "")
        raise GraphcalError(
            f"--out {out}: the directory holds files graphcal did not write ({shown}); "
            "name a new or empty directory (an earlier graphcal result directory is replaced)"
        )
    existing = out.parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise GraphcalError(f"--out {out}: {existing} is not a directory; name another place")
    try:
        probe = tempfile.mkdtemp(prefix=".graphcal-probe-", dir=existing)
    except OSError as exc:
        raise GraphcalError(
            f"--out {out}: cannot write in {existing} ({exc.strerror or exc}); "
            "name a writable place"
        ) from exc
    os.rmdir(probe)
    return out


def replace_result_set(
    path: str | os.PathLike[str], write: Callable[[Path], list[Path]]
) -> list[Path]:
    """Write a result set with ``write(directory)`` into a temporary directory beside ``path``
    and move it into place, replacing an earlier set as a whole; returns the final paths.

    If anything fails or the run is interrupted, the earlier set stays as it was and the
    temporary directory is removed.
    """
    out = Path(path)
    check_output_directory(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.new-", dir=out.parent))
    retired: Path | None = None
    try:
        written = write(staging)
        if out.exists():
            retired = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
            os.rename(out, retired / out.name)
        os.rename(staging, out)
    except BaseException:
        if retired is not None and not out.exists():
            os.rename(retired / out.name, out)  # put the earlier set back
        shutil.rmtree(staging, ignore_errors=True)
        if retired is not None:
            shutil.rmtree(retired, ignore_errors=True)
        raise
    if retired is not None:
        shutil.rmtree(retired, ignore_errors=True)
    return [out / p.relative_to(staging) for p in written]
