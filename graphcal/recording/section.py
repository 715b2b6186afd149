"""One section of a recording's description (``[wheels]`` of a streams manifest): its keys as
plain values and where it was written, with the checked reads every source makes of them.

The sources (:mod:`graphcal.recording.manifest`'s CSV files, :mod:`graphcal.recording.can`,
:mod:`graphcal.recording.nmea`, :mod:`graphcal.recording.imu`) read a :class:`Section`, never
the TOML file: a program can build one from its own configuration, and each error still
names the key the user wrote (``manifest.toml: [wheels] kind = 'rpms' is not known; ...``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.recording.streams import StreamError


@dataclass(frozen=True)
class Section:
    """A section's keys and where they were written.

    Attributes:
        name: the section (``"wheels"``, ``"imu"``, ``"gnss"``, ``"pose"``); ``""`` for the
            top level of a file.
        table: its keys and their values (text, numbers, lists).
        source: the file that holds it, as messages start (``"drive/manifest.toml"``).
        base: the directory relative paths in it are relative to.
    """

    name: str
    table: Mapping[str, Any] = field(default_factory=dict)
    source: str = "<memory>"
    base: Path = Path(".")

    def __contains__(self, key: str) -> bool:
        return key in self.table

    def __iter__(self):
        return iter(self.table)

    def __getitem__(self, key: str) -> Any:
        return self.table[key]

    def get(self, key: str, default: Any = None) -> Any:
        """The raw value of ``key`` (``default`` if absent)."""
        return self.table.get(key, default)

    def has_any(self, keys: Iterable[str]) -> bool:
        """Whether the section holds one of ``keys``."""
        return any(key in self.table for key in keys)

    def where(self, key: str) -> str:
        """``[wheels] kind`` (the key as the user finds it; bare at the top level)."""
        return f"[{self.name}] {key}" if self.name else key

    def declaration(self, key: str, default: str | None = None) -> str:
        """How a unit key reads (``'speed_unit = "m/s"'``), for messages; a key left out says
        its default (``'speed_unit = "m/s" by default'``)."""
        value = self.table.get(key, default)
        text = (
            f"{key} = {value!r}".replace("'", '"') if isinstance(value, str) else f"{key} = {value}"
        )
        return text if key in self.table else f"{text} by default"

    def error(self, what: str) -> StreamError:
        """A one-line :class:`StreamError` about this section's file."""
        return StreamError(f"{self.source}: {what}")

    def resolve(self, name: str) -> Path:
        """A path named in the section, relative to :attr:`base`."""
        path = Path(name).expanduser()
        return path if path.is_absolute() else self.base / path

    def number(self, key: str, default: float | None, positive: bool = False) -> float | None:
        """A numeric key (``default`` if absent), checked finite (and positive)."""
        value = self.table.get(key, default)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"{self.where(key)} must be a number, got {value!r}")
        value = float(value)
        if not np.isfinite(value) or (positive and value <= 0):
            raise self.error(f"{self.where(key)} must be a {'positive ' if positive else ''}number")
        return value

    def choice(self, key: str, options: Iterable[str], default: str | None) -> str:
        """A key whose value is one of ``options`` (``default`` if absent; required if None)."""
        value = self.table.get(key, default)
        known = ", ".join(options)
        if value is None:
            raise self.error(f"[{self.name}] needs {key} (one of {known})")
        if not isinstance(value, str) or value not in options:
            raise self.error(f"[{self.name}] {key} = {value!r} is not known; use one of {known}")
        return value

    def text(self, key: str, required: bool = True) -> str | None:
        """A column, topic or signal name."""
        value = self.table.get(key)
        if value is None:
            if required:
                raise self.error(f"[{self.name}] needs {key} (the column name)")
            return None
        if not isinstance(value, str) or not value:
            raise self.error(f"[{self.name}] {key} must be a column name (text), got {value!r}")
        return value
