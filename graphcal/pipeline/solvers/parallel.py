"""Run independent tasks in worker processes, in order, with progress.

Results come back in task order whatever the number of workers, and every task is a pure
function of its arguments, so the output of a run does not depend on ``workers``.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from graphcal.interrupt import raise_if_interrupted
from graphcal.progress import say, silence

R = TypeVar("R")

#: Seconds a broken pool's workers get to end before their exit codes are read.
WORKER_EXIT_WAIT = 5.0


def default_workers() -> int:
    """One worker per available core."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def map_tasks(
    function: Callable[..., R],
    tasks: Sequence[tuple[Any, ...]],
    workers: int = 1,
    label: str = "tasks",
    report: bool = True,
    fork: bool = False,
) -> list[R]:
    """``[function(*task) for task in tasks]``, in ``workers`` processes when more than one.

    ``function`` must be importable (module level) and its arguments picklable. With
    ``report``, progress is said about every 10 % and at the end, with the elapsed time;
    with ``fork``, the workers are forked (they inherit the caller's memory as it is when
    they start), whatever the platform's default start method.
    """
    start = time.perf_counter()
    total = len(tasks)
    step = max(1, total // 10)

    def progress(done: int) -> None:
        if report and (done % step == 0 or done == total):
            elapsed = time.perf_counter() - start
            eta = elapsed / done * (total - done) if done else 0.0
            say(f"{label}: {done}/{total} ({elapsed:.0f} s, about {eta:.0f} s left)")

    results: list[R] = []
    if workers <= 1 or total <= 1:
        for task in tasks:
            results.append(function(*task))
            progress(len(results))
        return results
    chunk = max(1, total // (workers * 8))
    ctrl_c = multiprocessing.RawValue("b", 0)  # set by a worker that Ctrl-C ends
    context = multiprocessing.get_context("fork") if fork else None
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=context, initializer=quiet_worker, initargs=(ctrl_c,)
    )
    try:
        for result in pool.map(_call, _with(function, tasks), chunksize=chunk):
            raise_if_interrupted()  # a Ctrl-C dropped while the pool forked its workers
            results.append(result)
            progress(len(results))
    except BrokenProcessPool:
        if _ended_by_ctrl_c(pool, ctrl_c):  # the pool broke first, the parent's SIGINT next
            _abandon(pool)
            raise KeyboardInterrupt from None
        _abandon(pool)
        raise
    except BaseException:  # Ctrl-C in the parent: end the workers, do not wait on the pipe
        _abandon(pool)
        raise
    pool.shutdown(wait=True)
    return results


def _abandon(pool: ProcessPoolExecutor) -> None:
    """End ``pool`` without waiting for its work: its workers killed, its queued tasks
    cancelled, and the thread that feeds them into the pipe not joined at exit. Waiting, as
    ``with`` does, hung for good on an interrupt under load: the feeder thread blocked
    writing megabytes of tasks into a pipe no worker read any more, and the interpreter
    waited for it at exit (issue 44)."""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        if process.is_alive():
            process.kill()
    call_queue = getattr(pool, "_call_queue", None)
    if call_queue is not None:
        call_queue.cancel_join_thread()
    pool.shutdown(wait=False, cancel_futures=True)


def _ended_by_ctrl_c(pool: ProcessPoolExecutor, ctrl_c: Any) -> bool:
    """Whether a worker of the broken ``pool`` died of SIGINT (Ctrl-C reached it before the
    parent noticed its own: under load the pool's breakage can come first, and the run
    must still end as an interrupt, exit 130, not a crash): its flag ``ctrl_c`` set
    (:func:`quiet_worker`), or its exit code. The flag is what tells where the workers'
    exit codes are gone — a host process that reaps its children as they end (SIGCHLD
    ignored, as under the full test suite) leaves none to read. Waits up to a few seconds
    for the workers to end."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    deadline = time.monotonic() + WORKER_EXIT_WAIT
    for process in processes:
        process.join(timeout=max(0.0, deadline - time.monotonic()))
    if ctrl_c.value:
        return True
    return any(process.exitcode == -signal.SIGINT for process in processes)


def quiet_worker(ctrl_c: Any = None) -> None:
    """A worker process says nothing: its progress is the parent's to report
    (:func:`graphcal.progress.silence`), and its Ctrl-C ends it without a word: the terminal
    sends SIGINT to every process of the command, and the parent alone says ``graphcal:
    interrupted`` (workers that raised KeyboardInterrupt printed ~140 lines of tracebacks,
    and the parent saw a broken pipe, not the interrupt: exit 1). With a shared ``ctrl_c``
    flag the worker sets it first, then dies of the signal as before (a worker inside a long
    GTSAM call does so when the call returns; on the parent's own Ctrl-C it is killed)."""
    silence()
    if ctrl_c is None:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
    else:
        signal.signal(signal.SIGINT, lambda signum, frame: _die_of_ctrl_c(ctrl_c))


def _die_of_ctrl_c(ctrl_c: Any) -> None:
    """Set the pool's ``ctrl_c`` flag, then end of SIGINT (exit code −SIGINT)."""
    ctrl_c.value = 1
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    os.kill(os.getpid(), signal.SIGINT)


def _with(function: Callable[..., R], tasks: Iterable[tuple[Any, ...]]):
    return ((function, task) for task in tasks)


def _call(item: tuple[Callable[..., R], tuple[Any, ...]]) -> R:
    function, task = item
    return function(*task)
