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

import json
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from graphcal.errors import GraphcalError
from graphcal.files import staging_directory
from graphcal.interrupt import raise_if_interrupted

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
    """True if ``path`` holds an earlier graphcal result set and nothing else: only result
    file names, and a ``calibration.json`` that graphcal wrote (it names graphcal's version)."""
    names = {entry.name for entry in path.iterdir()}
    if "calibration.json" not in names or not names <= RESULT_FILES:
        return False
    try:
        document = json.loads((path / "calibration.json").read_text())
        return isinstance(document["versions"]["graphcal"], str)
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _resolved(path: str | os.PathLike[str]) -> Path:
    """The absolute, symlink-free path of ``path`` (a symlinked directory means its target)."""
    return Path(os.path.realpath(path))


def check_output_directory(path: str | os.PathLike[str]) -> Path:
    """Check that results can be written to ``path``; return it as a ``Path``.

    Raises:
        GraphcalError: one line, if ``path`` is a file, a directory with other content, the
            working directory or one of its parents, a mount point, or in a place that
            cannot be written.
    """
    shown = Path(path)
    out = _resolved(path)
    if out.exists() and not out.is_dir():
        raise GraphcalError(f"--out {shown}: exists and is not a directory; name a directory")
    if out == Path(os.getcwd()) or out in Path(os.getcwd()).parents or os.path.ismount(out):
        raise GraphcalError(
            f"--out {shown}: the working directory, one of its parents or a mount point cannot "
            "be replaced as a result set; name a subdirectory (e.g. results/)"
        )
    if out.is_dir() and any(out.iterdir()) and not is_result_set(out):
        foreign = sorted(e.name for e in out.iterdir() if e.name not in RESULT_FILES)
        listed = ", ".join(foreign[:3]) + (" …" if len(foreign) > 3 else "")
        what = (
            f"files graphcal did not write ({listed})"
            if foreign
            else "a set graphcal did not write"
        )
        raise GraphcalError(
            f"--out {shown}: the directory holds {what}; name a new or empty directory (an "
            "earlier graphcal result directory is replaced)"
        )
    existing = out.parent
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise GraphcalError(f"--out {shown}: {existing} is not a directory; name another place")
    try:
        probe = tempfile.mkdtemp(prefix=".graphcal-probe-", dir=existing)
    except OSError as exc:
        raise GraphcalError(
            f"--out {shown}: cannot write in {existing} ({exc.strerror or exc}); "
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
    out = check_output_directory(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = staging_directory(out)
    # The earlier set is renamed beside itself (same parent: no write access to the set
    # itself needed) and removed only once the new set is in place.
    retired = out.parent / f"{staging.name.replace('.new-', '.old-', 1)}"
    moved = False
    try:
        written = write(staging)
        raise_if_interrupted()  # a Ctrl-C dropped while writing: the earlier set stays
        if out.exists():
            os.rename(out, retired)
            moved = True
        os.rename(staging, out)
    except BaseException:
        if moved and not out.exists():
            os.rename(retired, out)  # put the earlier set back
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if moved:
        shutil.rmtree(retired, ignore_errors=True)
    return [out / p.relative_to(staging) for p in written]
