"""Reading a drive-log CSV (:mod:`graphcal.log.drive_log` is the format): the file found,
decompressed whatever its name, parsed, validated (:mod:`graphcal.log.validation`) and
completed from the sidecar an import wrote beside it."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import numpy as np
import pandas as pd

from graphcal.errors import exception_reason
from graphcal.files import graphcal_json
from graphcal.log.checks import check_repeated
from graphcal.log.drive_log import DriveLog, DriveLogError
from graphcal.log.validation import validate_frame
from graphcal.model import THETA_NOMINAL

T = TypeVar("T")


#: Leading bytes of compressed files, and the pandas name of each compression.
_COMPRESSED = {
    b"\x1f\x8b": "gzip",
    b"BZh": "bz2",
    b"\xfd7zXZ\x00": "xz",
    b"PK\x03\x04": "zip",
    b"\x28\xb5\x2f\xfd": "zstd",
}


def _compression(path: Path) -> str | None:
    """The compression of ``path`` by its leading bytes (whatever its name), or ``None``."""
    with open(path, "rb") as handle:
        head = handle.read(6)
    return next((kind for magic, kind in _COMPRESSED.items() if head.startswith(magic)), None)


def _header(path: Path, compression: str | None) -> list[str]:
    """The raw column names of the first line, before pandas renames repeated ones."""
    frame = pd.read_csv(path, nrows=0, compression=compression, skipinitialspace=True)
    names = [str(c).strip() for c in frame.columns]
    # pandas has already renamed repeats to "name.1"; read the line itself for the truth.
    first = pd.read_csv(
        path, nrows=1, header=None, compression=compression, dtype=str, skipinitialspace=True
    )
    raw = [str(c).strip() for c in first.iloc[0].tolist()]
    return raw if len(raw) == len(names) else names


def _header_of(path: Path) -> tuple[str | None, list[str]]:
    compression = _compression(path)
    return compression, _header(path, compression)


def readable_csv(source: str, read: Callable[[], T]) -> T:
    """``read()``, with a file that cannot be read or parsed as CSV as one-line errors."""
    try:
        return read()
    except OSError as exc:
        raise DriveLogError(
            f"{source}: cannot read ({exc.strerror or exc}); check the file"
        ) from exc
    except (
        pd.errors.ParserError,
        pd.errors.EmptyDataError,
        UnicodeDecodeError,
        EOFError,
        ValueError,
    ) as exc:
        first = exception_reason(exc)
        raise DriveLogError(
            f"{source}: not a readable CSV ({first}); export the log as CSV"
        ) from exc


def load_drive_log(
    path: str | os.PathLike[str],
    min_distance: float = 0.0,
    *,
    nominal: np.ndarray = THETA_NOMINAL,
    reverses: bool = False,
) -> DriveLog:
    """Read and validate a drive-log CSV (see the module docstring for the format).

    The file may be compressed (gzip, bz2, xz, zip, zstd), whatever its name.

    Args:
        path: CSV file with a header row.
        min_distance: shortest acceptable travelled distance [m] (e.g. one segment length).
        nominal: the vehicle's nominal theta ``[c_e, c_d, t_r, d]`` (SI; default: the
            paper's car), which turns wheel rotations into distance and yaw for the checks
            (``VehicleProfile.theta_nominal``).
        reverses: wheels turning backwards are motion (``VehicleProfile.reverses``: a robot
            spinning on the spot or reversing); ``False`` (a car) refuses negative rotations.

    Raises:
        DriveLogError: with one line naming the file, the column and the first bad line.
    """
    source = str(path)
    path = Path(path)
    if path.is_dir():
        inside = sorted(p.name for p in path.glob("*.csv"))[:3]
        hint = f" (it holds {', '.join(inside)})" if inside else ""
        raise DriveLogError(
            f"{source}: is a directory, not a drive-log CSV{hint}; give the CSV file's path"
        )
    if not path.is_file():
        raise DriveLogError(f"{source}: no such file; check the path")
    compression, names = readable_csv(source, lambda: _header_of(path))
    check_repeated(names, source)
    if len(names) == 1:  # before the full read, which would warn about ragged rows
        for separator, label in (
            (";", "semicolons"),
            ("\t", "tabs"),
            ("|", "bars"),
            (" ", "spaces"),
        ):
            if separator in names[0] and "," not in names[0]:
                raise DriveLogError(
                    f"{source}: the header '{names[0][:60]}' is one column: the file is "
                    f"separated by {label}, not commas; export it with ',' between columns "
                    "and '.' as the decimal point"
                )
    # index_col=False: a trailing comma on data rows must not shift the columns.
    frame = readable_csv(
        source,
        lambda: pd.read_csv(
            path, engine="c", skipinitialspace=True, index_col=False, compression=compression
        ),
    )
    frame.columns = [str(c).strip() for c in frame.columns]
    log = validate_frame(frame, source, min_distance, nominal=nominal, reverses=reverses)
    return dataclasses.replace(log, **_from_import_sidecar(path))


def _from_import_sidecar(path: Path) -> dict:
    """What the ``<stem>.json`` sidecar that ``graphcal import`` wrote beside the CSV says
    that the CSV cannot: the wheels' tick resolution (``ticks_per_revolution``; counts
    interpolated onto the grid are no longer whole and cannot be found again), whether
    ``ay`` came from the wheels or the heading (``ay_from_wheels``, ``ay_from_heading``) and
    the white noise of the wheel rates
    before they were resampled (``wheel_noise_rev_per_step``). Empty without such a sidecar."""
    meta = graphcal_json(path.with_name(f"{path.stem}.json"), made_by="import")
    if meta is None:
        return {}
    found: dict = {}
    ticks = meta.get("ticks_per_revolution")
    if isinstance(ticks, int | float) and not isinstance(ticks, bool) and ticks >= 1:
        found["tick_resolution"] = 1.0 / float(ticks)
    for derived in ("ay_from_wheels", "ay_from_heading"):
        if meta.get(derived) is True:
            found[derived] = True
    noise = meta.get("wheel_noise_rev_per_step")
    if isinstance(noise, int | float) and not isinstance(noise, bool) and noise > 0:
        found["wheel_noise"] = float(noise)
    return found
