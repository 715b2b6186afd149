"""Writing an import: the drive-log CSV and its JSON sidecar, and the check that the output
overwrites none of the recording's files."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from graphcal.files import atomic_write_text, graphcal_json
from graphcal.log.drive_log import write_drive_log
from graphcal.recording.importer import MANIFEST_SUFFIXES, ImportedLog
from graphcal.recording.streams import StreamError


def sidecar_of(csv_path: str | os.PathLike[str]) -> Path:
    """The ``<stem>.json`` sidecar beside a drive-log CSV (as a synthetic drive's)."""
    path = Path(csv_path)
    return path.with_name(f"{path.stem}.json")


def source_files(source: str | os.PathLike[str]) -> set[Path]:
    """Every file a recording is read from (resolved): the manifest and the files it names,
    or the bag and the files of its directory."""
    path = Path(source)
    files = {path}
    if path.suffix.lower() in MANIFEST_SUFFIXES and path.is_file():
        from graphcal.recording.manifest.manifest import load_manifest

        try:
            manifest = load_manifest(path)
        except StreamError:
            return {path.resolve()}
        for table in (manifest.pose, manifest.wheels, manifest.imu):
            for key in ("file", "nmea", "can", "dbc"):  # a CSV, an NMEA log, a CAN log + DBC
                if table and isinstance(table.get(key), str):
                    files.add(manifest.resolve(table[key]))
        if isinstance(manifest.data.get("truth"), str):
            files.add(manifest.resolve(manifest.data["truth"]))
        if manifest.bag is not None:
            path = manifest.bag
            files.add(path)
    if path.is_dir():
        files.update(path.iterdir())
    return {f.resolve() for f in files}


def check_import_output(source: str | os.PathLike[str], out: str | os.PathLike[str]) -> None:
    """One line if ``out`` (or its sidecar) is a directory (or named as one, ``newdir/``), a
    JSON name, a file the recording is read from, or in a place that cannot be written;
    checked before the import."""
    text = os.fspath(out)
    out = Path(out)
    if out.is_dir() or text.endswith(("/", os.sep)):
        raise StreamError(f"--out {text}: names a directory; give the drive-log CSV's path")
    if out.suffix.lower() == ".json":
        raise StreamError(
            f"--out {out}: the drive log is a CSV and its sidecar is <name>.json; give a .csv path"
        )
    protected = source_files(source)
    for path in (out, sidecar_of(out)):
        if path.resolve() in protected:
            raise StreamError(
                f"--out {out}: would overwrite {path}, a file of the recording; choose another path"
            )
    if (out.exists() or sidecar_of(out).exists()) and not _written_by_graphcal(out):
        raise StreamError(
            f"--out {out}: would overwrite a file graphcal did not write (a drive log graphcal "
            f"wrote has its {sidecar_of(out).name} beside it); choose another path or remove it"
        )
    _check_writable(out)


def _check_writable(out: Path) -> None:
    """One line if no file can be made where ``out`` goes (its nearest existing directory):
    before a long import, not after it."""
    existing = next(p for p in (out.absolute().parent, *out.absolute().parents) if p.exists())
    try:
        fd, probe = tempfile.mkstemp(prefix=".graphcal-probe-", dir=existing)
    except OSError as exc:
        raise StreamError(
            f"--out {out}: cannot write in {existing} ({exc.strerror or exc}); "
            "name a writable place"
        ) from None
    os.close(fd)
    os.unlink(probe)


def _written_by_graphcal(csv_path: Path) -> bool:
    """Whether ``csv_path`` and its sidecar are a drive log graphcal wrote (an import or a
    simulated drive): its sidecar names graphcal as its generator."""
    return graphcal_json(sidecar_of(csv_path)) is not None


def write_import(imported: ImportedLog, csv_path: str | os.PathLike[str]) -> list[Path]:
    """Write the drive-log CSV and its ``<stem>.json`` sidecar (each atomically; the CSV is
    removed again if the sidecar cannot be written, so that nothing is half-written)."""
    csv_path = Path(csv_path)
    sidecar = sidecar_of(csv_path)
    write_drive_log(imported.log, csv_path)
    try:
        atomic_write_text(sidecar, json.dumps(imported.sidecar(), indent=2) + "\n")
    except BaseException:
        csv_path.unlink(missing_ok=True)
        raise
    return [csv_path, sidecar]
