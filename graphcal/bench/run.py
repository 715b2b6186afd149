"""The benchmark: graphcal's solves next to the naive GTSAM formulation, in one run.

Items (median wall time over ``repeats``; peak memory of the process after each item):

* foundation: simulate, write, load, segment, integrate;
* (a) the naive formulation of one batch (per-step Python factors between Pose2 variables,
  :mod:`graphcal.bench.naive`), ``gtsam.LevenbergMarquardtOptimizer`` capped at a few
  iterations: seconds per iteration;
* (b) graphcal's batch solve of the same batch (one factor per segment): seconds, and per
  iteration;
* agreement of (a) and (b): both run to convergence on a reduced batch;
* (c) graphcal's input estimation (Steps 2 and 4) per segment;
* (d) graphcal's joint batch solve of the same batch;
* (e) the staged and joint pipelines end to end at a chosen number of batches, with
  ``workers``;
* (f)–(g) the localization factors (:mod:`graphcal.bench.localization`): the smoothing
  example on a 4 km drive with theta fixed (a re-integrating Python factor per interval vs a
  built-in ``BetweenFactorPose2`` from the preintegration: time and trajectory difference)
  and with theta a variable (re-integrating vs preintegrated Python factor), all under
  GTSAM's optimizer; the preintegrated graph again with Levenberg–Marquardt driven from
  Python (what ``smooth_drive`` uses); and the online fixed-lag update;
* (h) ``graphcal import`` of a long recording (GNSS 10 Hz, wheels and IMU 100 Hz as CSV
  streams) in a child process: time and the child's own peak memory
  (:mod:`graphcal.bench.importing`); and of a raw CAN log of a car's bus (~2,000 frames/s,
  candump with a DBC: :mod:`graphcal.bench.can_import`);
* (i) the whole-log solve of the drive with the defect model (the defaults) and without it
  (``--no-defect-model``), and the ratio of their times;
* (j) the joint solve of all selected segments with its covariance as one graph under GTSAM's
  optimizer (the formulation before issue 14) and segment by segment in one and two
  processes, with the differences of theta and covariance;
* (k) the whole-log calibration of drives of several lengths (``--scaling-km``) in child
  processes, and the exponent of its time's growth (:mod:`graphcal.bench.scaling`);
* (l) a joint batch of the batch study solved on its own and from the segments' systems at
  the whole-log solution (:mod:`graphcal.pipeline.methods.joint_batches`), per batch;
* (m) fleet throughput on Dask with 1 and 2 workers and Dask's overhead per log
  (:mod:`graphcal.bench.fleet`);
* (n) ``graphcal calibrate`` with defaults on each recording the suite holds (the real car's
  four forms, the real robot, the sample drive), end to end: wall time, peak memory, the
  whole-log solves and their iterations (:mod:`graphcal.bench.recordings`).

Ratios are taken within one run, never against figures from another machine. :data:`ITEMS`
holds the items in the order they run; :func:`run_benchmarks` runs them.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from graphcal.bench.batch_items import (
    agreement_item,
    drive_items,
    naive_item,
    pipeline_items,
    segment_items,
    single_solve_items,
)
from graphcal.bench.can_import import can_import_item
from graphcal.bench.fleet import fleet_item
from graphcal.bench.importing import import_item
from graphcal.bench.localization_items import localization_items
from graphcal.bench.options import BenchSizes, resolve_bench_options
from graphcal.bench.recording import BenchRun, Recorder
from graphcal.bench.recordings import recording_items
from graphcal.bench.scaling import scaling_item
from graphcal.bench.whole_log_items import batch_study_items, segmented_items, whole_log_items
from graphcal.progress import Progress, muted

#: The report's entries after ``config`` and ``items``, in their order in the JSON.
REPORT_ENTRIES = (
    "naive_over_graphcal_per_iteration",
    "defect_model_over_plain_whole_log",
    "segmented",
    "batch_study",
    "scaling",
    "fleet",
    "localization",
    "import",
    "import_can",
    "agreement",
    "recordings",
)


def run_benchmarks(
    sizes: BenchSizes | None = None, workers: int = 2, progress: Progress | None = None
) -> dict[str, Any]:
    """Run every item of :data:`ITEMS` at ``sizes`` on ``workers`` processes; return
    ``{"config": ..., "items": [...], "agreement": ...}`` (the entries of
    :data:`REPORT_ENTRIES` after the items)."""
    record = Recorder(progress)
    sizes = sizes or BenchSizes()
    bench = BenchRun(**dataclasses.asdict(sizes), workers=workers, record=record)
    entries: dict[str, Any] = {}
    for item in ITEMS:
        with muted():  # the timed calls' own progress is not the report's
            entries.update(item(bench))
    return {
        "config": _config(bench),
        "items": record.rows,
        **{name: entries[name] for name in REPORT_ENTRIES},
    }


def _config(bench: BenchRun) -> dict[str, Any]:
    """The report's ``config``: the sizes the run had and the Python version."""
    return {
        "length_km": bench.length_km,
        "repeats": bench.repeats,
        "workers": bench.workers,
        "naive_iterations": bench.naive_iterations,
        "pipeline_batches": bench.pipeline_batches,
        "import_hours": bench.import_hours,
        "scaling_km": list(bench.scaling_km),
        "fleet_vehicles": bench.fleet_vehicles,
        "python": sys.version.split()[0],
    }


def segmented_item(bench: BenchRun) -> dict[str, Any]:
    """(j): :func:`~graphcal.bench.whole_log_items.segmented_items` of the selected
    segments."""
    return {"segmented": segmented_items(bench.record, bench.data, bench.repeats)}


def batch_study_item(bench: BenchRun) -> dict[str, Any]:
    """(l): :func:`~graphcal.bench.whole_log_items.batch_study_items` of at least 100
    batches."""
    count = max(bench.pipeline_batches, 100)
    return {"batch_study": batch_study_items(bench.record, bench.data, count, bench.workers)}


def whole_log_item(bench: BenchRun) -> dict[str, Any]:
    """(i): :func:`~graphcal.bench.whole_log_items.whole_log_items` of the log."""
    ratio = whole_log_items(bench.record, bench.log, bench.repeats)
    return {"defect_model_over_plain_whole_log": ratio}


def localization_item(bench: BenchRun) -> dict[str, Any]:
    """(f)–(g): :func:`~graphcal.bench.localization_items.localization_items`."""
    return {"localization": localization_items(bench.record, bench.repeats)}


def import_items(bench: BenchRun) -> dict[str, Any]:
    """(h) ``graphcal import`` of a recording of ``import_hours`` as CSV streams and as a raw
    CAN log with a DBC, each in a child process (none with ``import_hours`` 0)."""
    importing = can_import = None
    if bench.import_hours > 0:
        importing = import_item(bench.import_hours)
        bench.record(
            f"(h) graphcal import of a {importing['recording_hours']:.1f} h recording",
            importing["seconds"],
            **{k: v for k, v in importing.items() if k != "seconds"},
        )
        can_import = can_import_item(bench.import_hours)
        bench.record(
            f"(h) graphcal import of a {can_import['recording_hours']:.1f} h CAN log + DBC",
            can_import["seconds"],
            **{k: v for k, v in can_import.items() if k != "seconds"},
        )
    return {"import": importing, "import_can": can_import}


def scaling_items(bench: BenchRun) -> dict[str, Any]:
    """(k) The whole-log calibration of drives of each length of ``scaling_km`` in child
    processes, the exponent of its time's growth, and ``graphcal calibrate --method whole``
    of the longest end to end (none without lengths)."""
    if not bench.scaling_km:
        return {"scaling": None}
    record, workers = bench.record, bench.workers
    scaling = scaling_item(tuple(bench.scaling_km), workers)
    for run in scaling["runs"]:
        record(
            f"(k) whole-log calibration, {run['length_km']:g} km",
            run["seconds"],
            workers=workers,
            child_peak_mb=run["peak_mb"],
            worker_peak_mb=run["worker_peak_mb"],
            iterations=run["iterations"],
        )
    if scaling["exponent"] is not None:
        record.say(f"(k) time grows as length^{scaling['exponent']:.2f}")
    end_to_end = scaling["end_to_end"]
    if end_to_end is not None:
        for name, label in (("csv_alone", "CSV alone"), ("with_truth", "with its truth")):
            entry = end_to_end[name]
            record(
                f"(k) graphcal calibrate --method whole, {end_to_end['length_km']:g} km, {label}",
                entry["seconds"],
                workers=workers,
                process_peak_mb=entry["peak_mb"],
            )
    return {"scaling": scaling}


def real_recording_items(bench: BenchRun) -> dict[str, Any]:
    """(n) :func:`~graphcal.bench.recordings.recording_items`."""
    return {"recordings": recording_items(bench.record, bench.workers)}


def fleet_items(bench: BenchRun) -> dict[str, Any]:
    """(m) Fleet throughput on Dask with 1 and 2 workers (none with no vehicles)."""
    if bench.fleet_vehicles <= 0:
        return {"fleet": None}
    fleet = fleet_item(bench.fleet_vehicles)
    for workers in (1, 2):
        entry = fleet[f"workers_{workers}"]
        bench.record(
            f"(m) fleet of {fleet['logs']} logs on Dask, {workers} worker(s)",
            entry["seconds"],
            logs_per_minute=entry["logs_per_minute"],
            task_mean_s=entry["task_mean_s"],
            overhead_per_log_s=entry["overhead_per_log_s"],
        )
    bench.record.say(
        f"(m) fleet: 2 workers over 1 {fleet['scaling_2_over_1']:.2f}x; local cluster "
        f"start and stop {fleet['cluster_start_stop_s']:.1f} s"
    )
    return {"fleet": fleet}


#: The benchmark's items in the order they run, each taking the run and returning its
#: entries of the report.
ITEMS: tuple[Callable[[BenchRun], dict[str, Any]], ...] = (
    drive_items,
    segment_items,
    single_solve_items,
    naive_item,
    agreement_item,
    pipeline_items,
    segmented_item,
    batch_study_item,
    whole_log_item,
    localization_item,
    import_items,
    scaling_items,
    fleet_items,
    real_recording_items,
)


def run_bench(args: Any, progress: Progress | None = None) -> dict[str, Any]:
    """Run the benchmark with the options of :func:`graphcal.cli.bench.add_arguments`
    (sizes resolved by :func:`~graphcal.bench.options.resolve_bench_options`); returns the
    report (write it with :func:`write_bench_report`)."""
    sizes = resolve_bench_options(args)
    if getattr(args, "only_import", False):
        return {
            "config": {"import_hours": sizes["import_hours"], "python": sys.version.split()[0]},
            "import": import_item(sizes["import_hours"]),
            "import_can": can_import_item(sizes["import_hours"]),
        }
    if getattr(args, "only_recordings", False):
        record = Recorder(progress)
        recordings = recording_items(record, args.workers)
        config = {"workers": args.workers, "python": sys.version.split()[0]}
        return {"config": config, "items": record.rows, "recordings": recordings}
    report = run_benchmarks(BenchSizes(**sizes), args.workers, progress)
    report["config"]["quick"] = bool(getattr(args, "quick", False))
    return report


def write_bench_report(report: dict[str, Any], path: str | Path) -> None:
    """Write the benchmark report as JSON."""
    Path(path).write_text(json.dumps(report, indent=2) + "\n")
