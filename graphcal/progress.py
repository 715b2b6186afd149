"""Progress: one channel for every long step, the logger ``graphcal.progress``.

A step says what it does with :func:`say` (one line of text, an ``INFO`` record); nothing
prints unless someone listens. The public entry points (:func:`graphcal.run_calibration`,
:func:`graphcal.calibrate_file`, :func:`graphcal.run_fleet`, ...) take ``progress=``, a
callable that gets each line while they run (``progress=print``; the CLI prefixes the
elapsed time); a program that configures :mod:`logging` gets the lines as records of
``graphcal.progress``. Worker processes stay quiet: the parent reports their progress.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import logging
from collections.abc import Callable, Iterator
from typing import TypeVar

F = TypeVar("F", bound=Callable)

#: Receives one line of progress text (no newline).
Progress = Callable[[str], None]

#: The channel.
LOGGER = logging.getLogger("graphcal.progress")
LOGGER.setLevel(logging.INFO)


def say(line: str) -> None:
    """Report one line of progress."""
    LOGGER.info(line)


class _ToCallable(logging.Handler):
    """Hands each progress line to a callable (its exceptions, such as a ``KeyboardInterrupt``
    a test raises after the first line, propagate)."""

    def __init__(self, progress: Progress) -> None:
        super().__init__(logging.INFO)
        self.progress = progress

    def emit(self, record: logging.LogRecord) -> None:
        self.progress(record.getMessage())

    def handleError(self, record: logging.LogRecord) -> None:
        raise  # a failing callable is the caller's error, not logging's to print


@contextlib.contextmanager
def reporting_to(progress: Progress | None) -> Iterator[None]:
    """While inside, every progress line also goes to ``progress`` (``None``: nowhere new);
    a callable already listening is not added twice (an entry point called by another)."""
    listening = any(isinstance(h, _ToCallable) and h.progress is progress for h in LOGGER.handlers)
    if progress is None or progress is say or listening:
        yield
        return
    handler = _ToCallable(progress)
    LOGGER.addHandler(handler)
    try:
        yield
    finally:
        LOGGER.removeHandler(handler)


def silence() -> None:
    """No progress from this process (a worker's: its parent reports)."""
    LOGGER.disabled = True


def reports_progress(function: F) -> F:
    """An entry point whose ``progress`` argument listens to the channel while it runs
    (:func:`reporting_to`); the steps it calls just :func:`say`."""
    signature = inspect.signature(function)

    @functools.wraps(function)
    def entry(*args, **kwargs):
        progress = signature.bind_partial(*args, **kwargs).arguments.get("progress")
        with reporting_to(progress):
            return function(*args, **kwargs)

    return entry  # type: ignore[return-value]
