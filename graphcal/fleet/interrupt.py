"""Ctrl-C during a fleet run: one line from graphcal, nothing from Dask.

A terminal's Ctrl-C sends SIGINT to the whole foreground process group: graphcal's own
process and the local cluster's worker processes. Left to Python's defaults, each worker
prints a ``KeyboardInterrupt`` traceback and graphcal's own process raises it wherever its
main thread happens to be (often inside Dask's code, which logs errors and leaves more
tracebacks while it shuts down). Here:

* the worker processes do not take SIGINT: it is blocked while the local cluster starts
  (the threads and processes started meanwhile inherit the blocked mask) and every worker
  ignores it from its start on (:func:`dask_setup`, a Dask preload — also for a worker the
  nanny restarts later); graphcal's process stops them when it closes the cluster;
* graphcal's process takes the first Ctrl-C as a request (:class:`DeferredInterrupt`): the
  run stops at its next check, cancels what is queued, closes the cluster with Dask's
  logging silenced (:func:`quiet_dask`) and raises ``KeyboardInterrupt`` naming how to
  resume. A second Ctrl-C raises at once.
"""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any

#: This module as a Dask preload of the local cluster's workers.
WORKER_PRELOAD = __name__


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


class DeferredInterrupt:
    """While active (``with``, main thread only): SIGINT sets :attr:`requested` instead of
    raising ``KeyboardInterrupt``; the first one also restores the previous handler, so a
    second Ctrl-C raises at once. Outside the main thread it does nothing (no handler can
    be installed there) and :attr:`requested` stays ``False``."""

    def __init__(self) -> None:
        self.requested = False
        self._previous: Any = None
        self._installed = False

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._previous)

    def check(self) -> None:
        """Raise ``KeyboardInterrupt`` if Ctrl-C was pressed."""
        if self.requested:
            raise KeyboardInterrupt

    def __enter__(self) -> DeferredInterrupt:
        if _main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)
            self._installed = True
        return self

    def __exit__(self, *exc: object) -> None:
        if self._installed and not self.requested:
            signal.signal(signal.SIGINT, self._previous)
        self._installed = False


@contextmanager
def sigint_blocked() -> Iterator[None]:
    """SIGINT blocked in this (main) thread: threads and processes started meanwhile — the
    local cluster's event loop, its nannies' worker processes — inherit the blocked mask
    and never see Ctrl-C; one pressed meanwhile stays pending and is taken when this ends.
    A no-op outside the main thread or where POSIX signal masks do not exist."""
    if not (_main_thread() and hasattr(signal, "pthread_sigmask")):
        yield
        return
    # multiprocessing's resource tracker, launched by the first process a thread starts,
    # unblocks SIGINT in that thread afterwards: launch it now, before the mask is set.
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@contextmanager
def quiet_dask() -> Iterator[None]:
    """Dask's loggers (``distributed``, and ``tornado`` and ``asyncio`` it runs on) silent:
    an interrupted run's shutdown logs errors about connections it is closing itself."""
    loggers = [logging.getLogger(name) for name in ("distributed", "tornado", "asyncio")]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)


def dask_setup(worker: object) -> None:
    """Dask preload hook, run in each local worker process as its worker starts: the
    process ignores SIGINT (Ctrl-C reaches graphcal's own process, which stops the
    workers). Only in the process's main thread (a worker in graphcal's own process would
    run its preload on another thread and is left alone)."""
    if _main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
