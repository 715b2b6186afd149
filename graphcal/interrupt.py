"""Ctrl-C that is never lost: an interrupt is remembered as well as raised.

Python raises a SIGINT's ``KeyboardInterrupt`` wherever the main thread happens to be. Where
that is code whose exceptions Python only prints and drops — a fork's at-fork callback
(logging's ``_releaseLock`` after every fork of a worker), a finalizer, a weakref callback —
the interrupt was lost: ``Exception ignored in: <function _releaseLock …>
KeyboardInterrupt``, and the run went on, wrote its results and exited 0 (issue 44).

While :func:`remembering_interrupts` is active (the command line's run), a SIGINT sets a
flag before it raises; :func:`raise_if_interrupted` raises it again at the run's next
progress line, worker result and file it would write, so an interrupt dropped once still
ends the run before anything is written, and the dropped one's "Exception ignored" traceback
is not printed (``sys.unraisablehook``): the user sees one line, ``graphcal: interrupted``.
Outside it (graphcal as a library) nothing changes.
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

_requested = False


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _handle(signum: int, frame: FrameType | None) -> None:
    global _requested
    _requested = True
    raise KeyboardInterrupt


def _quiet_about_dropped_interrupts(previous):
    """An unraisable-exception hook that says nothing of a dropped ``KeyboardInterrupt``
    (remembered: it ends the run at the next check) and hands every other to ``previous``."""

    def hook(unraisable) -> None:
        if not (_requested and isinstance(unraisable.exc_value, KeyboardInterrupt)):
            previous(unraisable)

    return hook


def interrupted() -> bool:
    """Whether Ctrl-C was pressed while :func:`remembering_interrupts` was active."""
    return _requested


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` (in the main thread) if Ctrl-C was pressed, even where
    its first ``KeyboardInterrupt`` was dropped."""
    if _requested and _main_thread():
        raise KeyboardInterrupt


@contextmanager
def remembering_interrupts() -> Iterator[None]:
    """While inside (main thread only), SIGINT is remembered as well as raised, and one that
    Python drops is not printed; the flag is cleared on entry, the previous handler and
    unraisable hook restored on exit."""
    global _requested
    if not _main_thread():
        yield
        return
    _requested = False
    previous = signal.signal(signal.SIGINT, _handle)
    previous_hook = sys.unraisablehook
    sys.unraisablehook = _quiet_about_dropped_interrupts(previous_hook)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook
