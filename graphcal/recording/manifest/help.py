"""Every key of a streams manifest with its default, as ``graphcal import --help-manifest``
prints it: the documentation of :mod:`graphcal.recording.manifest.manifest`."""

from __future__ import annotations

import inspect

from graphcal.recording.manifest import manifest


def manifest_help() -> str:
    """The documentation of every streams-manifest key with its default."""
    return inspect.cleandoc(manifest.__doc__ or "")
