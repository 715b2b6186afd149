"""The parts of a partitioned graph shared out among forked worker processes.

The optimizer asks every part the same thing at once through :class:`PartWorkers`' typed
methods; each becomes a request (a small picklable dataclass that knows which
:class:`~graphcal.graph.optimization.part_group.PartGroup` method answers it), sent to every worker
and answered by this process's own group meanwhile. The per-part answers are combined in part
order, so the results do not depend on the number of workers.
"""

from __future__ import annotations

import itertools
import multiprocessing
import multiprocessing.context
import signal
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np

from graphcal.errors import exception_reason
from graphcal.graph.optimization.part_group import PartGroup
from graphcal.graph.optimization.values import Portable, copy_value, restore
from graphcal.progress import silence


@dataclass(frozen=True)
class Errors:
    """Each part's error at its values (:meth:`PartGroup.errors`)."""

    def apply(self, group: PartGroup) -> list[float]:
        return group.errors()


@dataclass(frozen=True)
class Eliminate:
    """Each part eliminated at damping ``lam`` (:meth:`PartGroup.eliminate`)."""

    lam: float | None
    keep: bool = True

    def apply(self, group: PartGroup) -> list[tuple[np.ndarray, np.ndarray]]:
        return group.eliminate(self.lam, self.keep)


@dataclass(frozen=True)
class Step:
    """Each part's step given the shared one (:meth:`PartGroup.step`)."""

    shared_step: dict[int, np.ndarray]

    def apply(self, group: PartGroup) -> list[float]:
        return group.step(self.shared_step)


@dataclass(frozen=True)
class TryStep:
    """Each part's candidate values (and error, with ``evaluate``; :meth:`PartGroup.try_step`)."""

    evaluate: bool

    def apply(self, group: PartGroup) -> list[float]:
        return group.try_step(self.evaluate)


@dataclass(frozen=True)
class Accept:
    """Each part moved to its candidate values (:meth:`PartGroup.accept`)."""

    def apply(self, group: PartGroup) -> None:
        group.accept()


@dataclass(frozen=True)
class Release:
    """Each part's eliminations, steps and candidates dropped (:meth:`PartGroup.release`)."""

    def apply(self, group: PartGroup) -> None:
        group.release()


@dataclass(frozen=True)
class Stop:
    """The worker's parts' local values, and the worker ends."""

    def apply(self, group: PartGroup) -> list[dict[int, Portable]]:
        return group.local_values()


Request = Errors | Eliminate | Step | TryStep | Accept | Release | Stop


class _RemoteGroup:
    """A :class:`PartGroup` served by a forked process (it inherits the group, Python
    factors included, without pickling); requests are sent, then answers received, so that
    several groups work at once."""

    def __init__(self, group: PartGroup, context: multiprocessing.context.BaseContext):
        self.size = len(group.parts)
        parent, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, group), daemon=True)
        self.process.start()
        child.close()
        self.connection = parent

    def send(self, request: Request) -> None:
        self.connection.send(request)

    def receive(self) -> Any:
        status, value = self.connection.recv()
        if status == "error":
            raise RuntimeError(value)
        return value

    def end(self) -> None:
        """End the process without a word from it (an interrupted run: it may be gone)."""
        self.process.kill()
        self.process.join()
        self.connection.close()

    def stop(self) -> list[dict[int, Portable]]:
        """End the process; returns its parts' local values."""
        self.send(Stop())
        values = self.receive()
        self.process.join()
        self.connection.close()
        return values


def _serve(connection, group: PartGroup) -> None:
    """A worker's loop: answer requests until :class:`Stop`. Ctrl-C ends the worker without
    a word (:func:`~graphcal.pipeline.solvers.parallel.quiet_worker`'s reason), and the worker
    reports no progress: its parent does."""
    silence()
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    while True:
        request = connection.recv()
        if isinstance(request, Stop):
            connection.send(("ok", request.apply(group)))
            return
        try:
            connection.send(("ok", request.apply(group)))
        except Exception as exc:  # reported to the optimizer, which raises it
            connection.send(("error", f"{exception_reason(exc)}"))


def _balanced_runs(sizes: list[int], count: int) -> list[tuple[int, int]]:
    """``count`` contiguous runs ``[a, b)`` of items with about equal total size."""
    bounds = np.cumsum([0, *sizes])
    targets = bounds[-1] * np.arange(1, count) / count
    cuts = [0, *np.searchsorted(bounds, targets).tolist(), len(sizes)]
    cuts = sorted(set(min(max(c, 0), len(sizes)) for c in cuts))
    return [(a, b) for a, b in itertools.pairwise(cuts) if b > a]


class PartWorkers:
    """Every part of a graph (``everything``), worked on in this process, or once
    :meth:`share_out` asked for workers, in this process (:attr:`local`) and forked ones."""

    def __init__(self, everything: PartGroup):
        self.everything = everything
        self.local = everything  # the parts this process works on (all, unless shared out)
        self._remote: list[_RemoteGroup] = []
        self._pending = 0  # workers asked for and not started yet

    @property
    def active(self) -> bool:
        """Workers were asked for (started or not)."""
        return bool(self._remote or self._pending)

    def share_out(self, workers: int) -> None:
        """Share the parts among this process and ``workers - 1`` forked processes at the
        first request (contiguous runs of parts, balanced by factor count)."""
        self._pending = workers

    def _start(self) -> None:
        workers, self._pending = self._pending, 0
        everything = self.everything
        runs = _balanced_runs([p.graph.size() for p in everything.parts], workers)
        context = multiprocessing.get_context("fork")
        groups = [
            PartGroup(everything.parts[a:b], everything.shared, everything.dims) for a, b in runs
        ]
        self._remote = [_RemoteGroup(g, context) for g in groups[1:]]
        self.local = groups[0]

    def stop(self, shared_values: gtsam.Values) -> None:
        """End the workers; their parts get back their local values and ``shared_values``."""
        self._pending = 0
        remote, self._remote = self._remote, []
        at = len(self.local.parts)
        self.local = self.everything
        for worker in remote:
            mine = self.everything.parts[at : at + worker.size]
            for part, values in zip(mine, worker.stop(), strict=True):
                for key, value in values.items():
                    restore(part.values, key, value)
                for key in self.everything.shared:  # this copy still has the old ones
                    copy_value(part.values, shared_values, key)
            at += worker.size

    def abandon(self) -> None:
        """End the workers at once, their parts' values lost (an interrupted run: Ctrl-C
        has ended them already, and asking for their values would fail on a closed pipe)."""
        self._pending = 0
        remote, self._remote = self._remote, []
        self.local = self.everything
        for worker in remote:
            worker.end()

    def _ask(self, request: Request) -> list:
        """``request`` of every group (the workers' at once), per-part answers in part order."""
        if self._pending:
            self._start()
        for worker in self._remote:
            worker.send(request)
        failure: Exception | None = None
        try:
            answers = list(request.apply(self.local) or [])
        except Exception as exc:  # raised below, once every worker's answer is read
            failure, answers = exc, []
        for worker in self._remote:  # every worker's answer is read, so the pipes stay in step
            try:
                answers += worker.receive() or []
            except RuntimeError as exc:
                failure = failure or exc
        if failure is not None:
            raise failure
        return answers

    def errors(self) -> list[float]:
        """Each part's error at its values."""
        return self._ask(Errors())

    def eliminate(
        self, lam: float | None, keep: bool = True
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each part's reduced system and shared Hessian diagonal (:meth:`PartGroup.eliminate`;
        without ``keep``, nothing is kept for a step)."""
        return self._ask(Eliminate(lam, keep))

    def step(self, shared_step: dict[int, np.ndarray]) -> list[float]:
        """Each part's predicted decrease for the shared step (:meth:`PartGroup.step`)."""
        return self._ask(Step(shared_step))

    def try_step(self, evaluate: bool = True) -> list[float]:
        """Each part's error after the step (:meth:`PartGroup.try_step`)."""
        return self._ask(TryStep(evaluate))

    def accept(self) -> None:
        """Every part moved to its candidate values."""
        self._ask(Accept())

    def release(self) -> None:
        """Every part's eliminations, steps and candidates dropped (memory)."""
        self._ask(Release())
