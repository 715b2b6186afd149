"""Atomic file writes: every result file appears whole or not at all.

Each helper writes to a temporary file in the target directory and renames it into place
(``os.replace`` is atomic on POSIX and Windows), so an interrupted run leaves no half-written
file behind.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import IO, Any

from graphcal.interrupt import raise_if_interrupted

_UMASK = os.umask(0)
os.umask(_UMASK)


def _atomic(path: str | os.PathLike[str], write: Callable[[IO[Any]], None], mode: str) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode, **({"newline": ""} if "b" not in mode else {})) as handle:
            write(handle)
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give result files normal modes
        raise_if_interrupted()  # a Ctrl-C dropped while writing: nothing appears
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return _atomic(path, lambda handle: handle.write(text), "w")


def atomic_write_chunks(path: str | os.PathLike[str], chunks: Iterable[bytes]) -> Path:
    """Write the byte strings ``chunks`` one after another to ``path`` atomically (a large
    file made a part at a time, never whole in memory)."""

    def write(handle: IO[Any]) -> None:
        for chunk in chunks:
            handle.write(chunk)

    return _atomic(path, write, "wb")


def atomic_write_csv(frame: Any, path: str | os.PathLike[str]) -> Path:
    """Write a pandas DataFrame as CSV (full float precision, no index) atomically."""
    return _atomic(
        path, lambda handle: frame.to_csv(handle, index=False, float_format="%.17g"), "w"
    )


def atomic_save_figure(figure: Any, path: str | os.PathLike[str], dpi: int = 120) -> Path:
    """Save a matplotlib figure as PNG atomically."""
    return _atomic(path, lambda handle: figure.savefig(handle, format="png", dpi=dpi), "wb")


def staging_directory(beside: Path) -> Path:
    """A new empty directory beside ``beside`` (named after it, hidden) with the mode a
    ``mkdir`` under the user's umask gives: what a result set is written into before it is
    renamed into place (``mkdtemp`` makes 0700 whatever the umask)."""
    staging = Path(tempfile.mkdtemp(prefix=f".{beside.name}.new-", dir=beside.parent))
    os.chmod(staging, 0o777 & ~_UMASK)
    return staging


def graphcal_json(path: str | os.PathLike[str], made_by: str = "") -> dict | None:
    """The JSON object at ``path`` if graphcal wrote it (its ``generator`` is ``graphcal
    VERSION COMMAND``, with ``made_by`` in the command where given: ``"import"``,
    ``"simulate"``); else ``None``: no such file, not JSON, or another program's."""
    try:
        meta = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(meta, dict):
        return None
    name, _, rest = str(meta.get("generator", "")).partition(" ")
    command = rest.partition(" ")[2]  # after the version
    return meta if name == "graphcal" and made_by in command else None
