"""What the benchmark's items share: timing, the report's rows, and the run's sizes and data.

:func:`timed` takes an item's median wall time, :class:`Recorder` keeps a row of the report
per item (with the process's peak memory after it) and says it as a progress line, and
:class:`BenchRun` carries the sizes of one run and what its first items make for the later
ones (the drive, its selected segments, the batch of the single solves).
"""

from __future__ import annotations

import resource
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from graphcal.log.drive_log import DriveLog
from graphcal.log.segments import SegmentData, Segments
from graphcal.pipeline.configuration.settings import Settings
from graphcal.progress import Progress
from graphcal.simulate.drive import SyntheticDrive


def peak_memory_mb() -> float:
    """Peak resident memory of this process so far [MB] (Linux ``ru_maxrss`` is in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Median wall time [s] of ``fn`` over ``repeats`` calls, and its last result."""
    times, result = [], None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


class Recorder:
    """The report's rows, one per item: its name, median time [s], the process's peak
    memory after it [MB] and the item's own numbers; each said as a progress line."""

    def __init__(self, progress: Progress | None = None) -> None:
        self.say: Progress = progress or (lambda _line: None)
        self.rows: list[dict[str, Any]] = []

    def __call__(self, name: str, seconds: float, **extra: Any) -> None:
        row = {"item": name, "median_s": seconds, "peak_mb": peak_memory_mb(), **extra}
        self.rows.append(row)
        note = ", ".join(
            f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in extra.items()
        )
        self.say(f"{name:<46} {seconds:10.4f} s  {row['peak_mb']:7.0f} MB  {note}")


@dataclass
class BenchRun:
    """One run of the benchmark: its sizes (:func:`graphcal.bench.run.run_benchmarks`), the
    recorder, and what the first items make for the later ones — the synthetic drive, its
    loaded log, the selected segments and their data (:func:`~graphcal.bench.batch_items.
    segment_items`), and the batch of the single solves with the settings it is solved with
    and graphcal's time per iteration of it [s] (:func:`~graphcal.bench.batch_items.
    single_solve_items`)."""

    length_km: float
    repeats: int
    workers: int
    naive_iterations: int
    pipeline_batches: int
    agreement_segments: int
    import_hours: float
    scaling_km: tuple[float, ...]
    fleet_vehicles: int
    record: Recorder
    drive: SyntheticDrive | None = None
    log: DriveLog | None = None
    selected: Segments | None = None
    data: SegmentData | None = None
    batch: SegmentData | None = None
    settings: Settings | None = None
    graphcal_s: float = float("nan")
