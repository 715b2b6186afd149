"""Every key of a streams manifest with its default, as ``graphcal import --help-manifest``
prints it: the documentation of :mod:`graphcal.recording.manifest.manifest`."""

from __future__ import annotations

import inspect
import re

from graphcal.recording.manifest import manifest


def manifest_help() -> str:
    """The documentation of every streams-manifest key with its default, as plain text for a
    terminal: the docstring's reStructuredText markup (````key````, ``:mod:`x```, a literal
    block's ``::``) taken out."""
    text = inspect.cleandoc(manifest.__doc__ or "")
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)  # roles: :mod:`x` -> x
    text = re.sub(r"``([^`]+)``", r"\1", text)
    return re.sub(r"::$", ":", text, flags=re.MULTILINE)
