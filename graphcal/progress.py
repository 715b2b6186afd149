"""Progress: one channel for every long step, the logger ``graphcal.progress``.

A step says what it does with :func:`say` (one line of text, an ``INFO`` record); nothing
prints unless someone listens. The public entry points (:func:`graphcal.run_calibration`,
:func:`graphcal.calibrate_file`, :func:`graphcal.run_fleet`, ...) take ``progress=``, a
callable that gets each line of the steps they run (``progress=print``; the CLI prefixes the
elapsed time); a program that configures :mod:`logging` and passes no ``progress=`` gets
the lines as records of ``graphcal.progress``. A step run inside another that is not the
user's concern (a model check's folds, a benchmark's timed calls) runs :func:`muted`, and
worker processes are silenced: their parent reports.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import logging
import threading
from collections.abc import Callable, Iterator
from typing import TypeVar

from graphcal.interrupt import raise_if_interrupted

F = TypeVar("F", bound=Callable)

#: Receives one line of progress text (no newline).
Progress = Callable[[str], None]

#: The channel.
LOGGER = logging.getLogger("graphcal.progress")
if LOGGER.level == logging.NOTSET:  # a level the program set first stays
    LOGGER.setLevel(logging.INFO)

_state = threading.local()  # per thread: how deep inside muted()
_silenced = False  # this process is a worker (silence())


def say(line: str) -> None:
    """Report one line of progress (nothing while :func:`muted`); a Ctrl-C dropped earlier
    ends the run here (:mod:`graphcal.interrupt`)."""
    raise_if_interrupted()
    if not getattr(_state, "muted", 0):
        LOGGER.info(line)


class _ToCallable(logging.Handler):
    """Hands the progress lines of the thread that made it to a callable (its exceptions,
    such as a ``KeyboardInterrupt`` a test raises after the first line, propagate)."""

    def __init__(self, progress: Progress) -> None:
        super().__init__(logging.INFO)
        self.progress = progress
        self.thread = threading.get_ident()

    def emit(self, record: logging.LogRecord) -> None:
        if record.thread == self.thread:  # two runs in two threads hear their own lines
            self.progress(record.getMessage())


@contextlib.contextmanager
def reporting_to(progress: Progress | None) -> Iterator[None]:
    """While inside, this thread's progress lines go to ``progress`` (``None``: nowhere new)
    rather than on to the program's logging; a callable already listening is not added
    twice (an entry point called by another with the same ``progress``)."""
    thread = threading.get_ident()
    listening = any(
        isinstance(h, _ToCallable) and h.progress == progress and h.thread == thread
        for h in LOGGER.handlers
    )
    if progress is None or progress is say or listening:
        yield
        return
    handler = _ToCallable(progress)
    was = LOGGER.propagate, LOGGER.disabled
    LOGGER.addHandler(handler)
    LOGGER.propagate = False  # the lines went where the caller asked: not twice
    LOGGER.disabled = _silenced  # a logging.config that disabled graphcal's loggers
    try:
        yield
    finally:
        LOGGER.removeHandler(handler)
        LOGGER.propagate, LOGGER.disabled = was


@contextlib.contextmanager
def muted() -> Iterator[None]:
    """No progress from this thread while inside (a step whose lines are not the user's
    concern: the folds of a model check, a benchmark's timed calls)."""
    _state.muted = getattr(_state, "muted", 0) + 1
    try:
        yield
    finally:
        _state.muted -= 1


def silence() -> None:
    """No progress from this process (a worker's: its parent reports)."""
    global _silenced
    _silenced = True
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
