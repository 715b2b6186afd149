"""A fleet run: every log calibrated as a Dask task, results written as they arrive.

* **Where**: a ``LocalCluster`` of ``options.workers`` single-threaded processes on this machine, or
  any running Dask scheduler by address (``tcp://HOST:8786``), whose workers must have
  graphcal installed and see the logs' paths.
* **Resumable**: each log's result is written atomically to ``OUT/logs/VEHICLE/DAY.json``
  with its key (:func:`graphcal.fleet.task.result_key`); a run skips every log whose result
  on disk has the key it would compute, so an interrupted run loses nothing that finished.
  A result lost with its worker (the process died), or a failure that is not the log's own
  (a path the worker cannot see, a bug), is reported but not written, so the next run tries
  again.
* **Ctrl-C**: the workers never take it; the run stops at its next check, closes the
  cluster quietly and raises ``KeyboardInterrupt`` naming how to resume
  (:mod:`graphcal.fleet.interrupt`).
* **Isolated failures**: a log that cannot be calibrated gives its one-line reason in its
  row of ``fleet.csv`` and does not stop the others.
* Then per vehicle, changes and the current theta (:mod:`graphcal.fleet.history`), and the
  fleet report (:mod:`graphcal.fleet.report`).
"""

from __future__ import annotations

import json
import logging
import os
import re
import time
import warnings
from collections.abc import Collection
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.errors import GraphcalError, first_line
from graphcal.files import atomic_write_text
from graphcal.fleet.history import (
    CHANGE_ALPHA,
    DayEstimate,
    VehicleHistory,
    flag_fleet_outliers,
    vehicle_history,
)
from graphcal.fleet.interrupt import (
    WORKER_PRELOAD,
    DeferredInterrupt,
    quiet_dask,
    sigint_blocked,
)
from graphcal.fleet.report import summary_lines, write_fleet_report
from graphcal.fleet.sources import FleetLog, discover_fleet
from graphcal.fleet.task import calibrate_fleet_log, content_hash, failed_result, result_key
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.configuration.settings_file import load_vehicle
from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle
from graphcal.progress import Progress, reports_progress, say

#: How often [s] a run waiting for results checks for Ctrl-C.
POLL_SECONDS = 0.1
#: How long [s] closing the local cluster waits for its workers before ending them.
CLOSE_SECONDS = 10.0


@dataclass(frozen=True)
class FleetRun:
    """A fleet run's outcome.

    Attributes:
        results: per log (vehicle, day order), the task's result dict
            (:func:`graphcal.fleet.task.calibrate_fleet_log`).
        histories: per vehicle, its days, changes, current theta and flags.
        computed, reused: logs tried in this run, and results kept from an earlier one
            (whether they failed or not).
        failed: logs whose calibration failed (in this run or kept).
        seconds: wall time of the run.
        written: the report files.
        failed_now: of ``failed``, those tried in this run.
    """

    results: list[dict[str, Any]]
    histories: list[VehicleHistory]
    computed: int
    reused: int
    failed: int
    seconds: float
    written: list[Path]
    failed_now: int = 0

    def summary(self) -> list[str]:
        """The lines a fleet operator reads at the end: the logs calibrated now, kept and
        failed, each log in one of the three (a failed log was counted as calibrated now)."""
        failed_kept = self.failed - self.failed_now
        head = (
            f"{len(self.results)} logs of {len(self.histories)} vehicles: "
            f"{self.computed - self.failed_now} calibrated now, "
            f"{self.reused - failed_kept} kept from an earlier run, "
            f"{self.failed} failed ({self.seconds:.0f} s)"
        )
        failed = [
            f"{r['vehicle']}/{r['day']}: failed: {r['reason']}"
            for r in self.results
            if r["status"] != "ok"
        ]
        return [head, *failed, *summary_lines(self.histories)]


@dataclass(frozen=True)
class FleetOptions:
    """How a fleet run goes.

    Attributes:
        workers: worker processes of the local cluster (ignored with ``scheduler``).
        scheduler: address of a running Dask scheduler, or ``None`` for a local cluster.
        alpha: false-alarm probability of each day's change test.
        keep: settings a vehicle's ``vehicle.toml`` or manifest profile must not override.
        bar: a tqdm progress bar over the logs instead of a progress line per log.
    """

    workers: int = 2
    scheduler: str | None = None
    alpha: float = CHANGE_ALPHA
    keep: Collection[str] = ()
    bar: bool = False


@reports_progress
def run_fleet(
    source: str | os.PathLike[str],
    out: str | os.PathLike[str],
    settings: Settings | None = None,
    options: FleetOptions = FleetOptions(),
    progress: Progress | None = None,
) -> FleetRun:
    """Calibrate every log of ``source`` (:func:`graphcal.fleet.sources.discover_fleet`)
    into ``out`` (see the module docstring).

    Args:
        settings: the run's settings (a vehicle's ``vehicle.toml`` or manifest profile is
            applied on top, keeping the settings named in ``options.keep``).
        options: the cluster, the change test's alpha, the bar (:class:`FleetOptions`).
        progress: gets progress lines.

    Raises:
        GraphcalError: for a bad source, an unwritable ``out`` or an unreachable scheduler.
    """
    started = time.perf_counter()
    settings = settings or Settings()
    out = Path(out)
    if out.exists() and not out.is_dir():  # before minutes of computation, not after
        raise GraphcalError(f"--out {out} is a file; give a directory (new or an earlier run's)")
    logs = discover_fleet(source)
    paths: dict[Path, FleetLog] = {}
    for log in logs:
        other = paths.setdefault(result_path(out, log), log)
        if other is not log:
            raise GraphcalError(
                f"{other.vehicle}/{other.day} and {log.vehicle}/{log.day} would share a result "
                "file; rename one (names keep letters, digits, '.', '_' and '-')"
            )
    per_log = _settings_per_log(logs, settings, options.keep)
    say(f"{len(logs)} logs of {len({log.vehicle for log in logs})} vehicles in {source}")
    keys = [result_key(content_hash(log.path), s) for log, s in zip(logs, per_log, strict=True)]
    results: list[dict[str, Any] | None] = [
        _kept(result_path(out, log), key) for log, key in zip(logs, keys, strict=True)
    ]
    pending = [i for i, r in enumerate(results) if r is None]
    reused = len(logs) - len(pending)
    if reused:
        say(f"{reused} logs already calibrated with these settings: kept")
    with DeferredInterrupt() as interrupt:
        try:
            if pending:
                with _client(options.workers, options.scheduler) as client:
                    interrupt.check()
                    say(f"calibrating {len(pending)} logs on {_describe(client)}")
                    tasks = list(zip(logs, per_log, keys, strict=True))
                    calibrated = _calibrate(client, out, (tasks, pending), options.bar, interrupt)
                    for i, result in calibrated:
                        results[i] = result
            interrupt.check()
        except KeyboardInterrupt:
            kept = sum(r is not None and not r.get("retry") for r in results)
            raise KeyboardInterrupt(
                f"{kept} of {len(logs)} logs' results kept in {out / 'logs'}; run the same "
                "command again to calibrate the others"
            ) from None
        final = [r for r in results if r is not None]
        histories = _histories(final, options.alpha)
        try:
            written = write_fleet_report(final, histories, out)
        except OSError as exc:
            raise GraphcalError(f"cannot write the fleet report to {out}: {exc}") from exc
    failed = sum(r["status"] != "ok" for r in final)
    failed_now = sum(results[i] is not None and results[i]["status"] != "ok" for i in pending)
    seconds = time.perf_counter() - started
    return FleetRun(final, histories, len(pending), reused, failed, seconds, written, failed_now)


def result_path(out: Path, log: FleetLog) -> Path:
    """Where a log's result lives: ``OUT/logs/VEHICLE/DAY.json`` (names made file-safe)."""
    return out / "logs" / _safe(log.vehicle) / f"{_safe(log.day)}.json"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", name) or "_"


def _kept(path: Path, key: str) -> dict[str, Any] | None:
    """The result at ``path`` if it has ``key`` (and reads), else ``None``."""
    try:
        result = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return result if isinstance(result, dict) and result.get("key") == key else None


def _settings_per_log(
    logs: list[FleetLog], settings: Settings, keep: Collection[str]
) -> list[Settings]:
    cache: dict[Path, Settings] = {}
    out = []
    for log in logs:
        if log.profile is None:
            out.append(settings)
            continue
        if log.profile not in cache:
            try:
                cache[log.profile] = apply_vehicle(settings, load_vehicle(log.profile), keep=keep)
            except (GraphcalError, ValueError) as exc:
                raise GraphcalError(f"{log.profile}: {first_line(str(exc))}") from exc
        out.append(cache[log.profile])
    return out


@contextmanager
def _client(workers: int, scheduler: str | None):
    """A Dask client of a new local cluster or of the scheduler at ``scheduler``."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise GraphcalError(
            'graphcal fleet needs Dask: pip install -e ".[fleet]" (dask[distributed], tqdm)'
        ) from exc
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=30)
        except (OSError, TimeoutError) as exc:
            raise GraphcalError(
                f"cannot reach the Dask scheduler at {scheduler}: {first_line(str(exc))}"
            ) from exc
        with client:
            yield client
        return
    # The workers never see Ctrl-C (graphcal.fleet.interrupt). Dask's own words stay out of
    # the user's terminal: its scheduler's HTTP server moving off a busy port 8787 (another
    # cluster's) and the workers' lost heartbeats once Ctrl-C closed the scheduler; a task
    # that fails is reported per log (failed_result).
    with sigint_blocked(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Port .* is already in use")
        cluster = LocalCluster(
            n_workers=max(1, workers),
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.CRITICAL,
            preload=[WORKER_PRELOAD],
        )
    with ExitStack() as quiet, ExitStack() as stack:  # quiet outlasts the closing
        stack.callback(cluster.close, timeout=CLOSE_SECONDS)
        client = stack.enter_context(Client(cluster))
        try:
            yield client
        except BaseException:  # interrupted or failed: stop the workers without Dask's logs
            quiet.enter_context(quiet_dask())
            client.cancel(list(client.futures))
            raise


def _describe(client) -> str:
    count = len(client.scheduler_info().get("workers", {}))
    return f"{count} Dask worker{'s' if count != 1 else ''} ({client.scheduler.address})"


def _calibrate(
    client,
    out: Path,
    work: tuple[list[tuple[FleetLog, Settings, str]], list[int]],
    bar: bool,
    interrupt: DeferredInterrupt,
):
    """Submit the pending logs (``work``: every log's ``(log, settings, key)`` and the indices
    of those pending); yield ``(index, result)`` as each finishes, after writing it. Checks
    ``interrupt`` every :data:`POLL_SECONDS` (raises ``KeyboardInterrupt``)."""
    from distributed import as_completed

    tasks, pending = work
    logs = [log for log, _, _ in tasks]
    per_log = [settings for _, settings, _ in tasks]
    keys = [key for _, _, key in tasks]

    futures = {
        client.submit(calibrate_fleet_log, logs[i], per_log[i], keys[i], pure=False): i
        for i in pending
    }
    meter = _meter(len(futures), bar)
    try:
        for future in _as_finished(as_completed(futures), interrupt):
            i = futures[future]
            try:
                result = future.result()
            except Exception as exc:  # the worker died or the task was lost: retried next run
                result = failed_result(logs[i], keys[i], f"task lost: {first_line(str(exc))}")
            else:
                try:
                    text = json.dumps(result, indent=1, allow_nan=False)
                except ValueError:  # a non-finite number: never written
                    result = failed_result(logs[i], keys[i], "non-finite result")
                else:
                    if not result.get("retry"):
                        _write(result_path(out, logs[i]), text)
            yield i, result
            meter(result)
    finally:
        meter(None)


def _as_finished(finished, interrupt: DeferredInterrupt):
    """The futures of ``finished`` (a Dask ``as_completed``) as they finish, checking
    ``interrupt`` in between."""
    while not finished.is_empty():
        interrupt.check()
        batch = finished.next_batch(block=False)
        if not batch:
            time.sleep(POLL_SECONDS)
        yield from batch


def _write(path: Path, text: str) -> None:
    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise GraphcalError(f"cannot write {path}: {exc.strerror or exc}") from exc


def _meter(total: int, bar: bool):
    """A callable advanced once per finished log (``None``: close)."""
    if bar:
        from tqdm import tqdm

        progress_bar = tqdm(total=total, unit="log", desc="fleet")

        def advance(result):
            if result is None:
                progress_bar.close()
                return
            progress_bar.update(1)
            if result["status"] != "ok":
                progress_bar.write(f"{result['vehicle']}/{result['day']}: {result['reason']}")

        return advance
    done = [0]
    step = max(1, total // 10)

    def report(result):
        if result is None:
            return
        done[0] += 1
        if result["status"] != "ok":
            say(f"{result['vehicle']}/{result['day']}: failed: {result['reason']}")
        if done[0] % step == 0 or done[0] == total:
            say(f"fleet: {done[0]}/{total} logs")

    return report


def _histories(results: list[dict[str, Any]], alpha: float) -> list[VehicleHistory]:
    by_vehicle: dict[str, list[dict[str, Any]]] = {}
    for r in results:
        by_vehicle.setdefault(r["vehicle"], []).append(r)
    histories = []
    for vehicle in sorted(by_vehicle):
        rows = sorted(by_vehicle[vehicle], key=lambda r: r["day"])
        days = [
            DayEstimate(
                r["day"],
                np.asarray(r["posterior_theta"], float),
                np.asarray(r["posterior_covariance"], float),
                np.asarray(r["prior_mean"], float),
                np.asarray(r["prior_sigmas"], float),
            )
            for r in rows
            if r["status"] == "ok" and r.get("trusted") is not False  # a σ to test against
        ]
        history = vehicle_history(vehicle, days, alpha)
        for r in rows:
            if r["status"] != "ok":
                history.flags.append(f"{r['day']}: calibration failed: {r['reason']}")
            elif r.get("trusted") is False:
                history.flags.append(
                    f"{r['day']}: calibration not trusted, left out of the change test"
                )
        histories.append(history)
    flag_fleet_outliers(histories)
    return histories
