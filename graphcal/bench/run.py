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
  the whole-log solution (:mod:`graphcal.pipeline.joint_batches`), per batch;
* (m) fleet throughput on Dask with 1 and 2 workers and Dask's overhead per log
  (:mod:`graphcal.bench.fleet`).

Ratios are taken within one run, never against figures from another machine.
"""

from __future__ import annotations

import dataclasses
import gc
import json
import resource
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.bench.can_import import can_import_item
from graphcal.bench.fleet import fleet_item
from graphcal.bench.importing import import_item
from graphcal.bench.localization import solve_smoothing
from graphcal.bench.naive import build_naive_graph, naive_optimizer, solve_naive
from graphcal.bench.options import resolve_bench_options
from graphcal.bench.scaling import scaling_item
from graphcal.data.drive_log import DriveLog, load_drive_log
from graphcal.data.segments import (
    SegmentData,
    gather_segments,
    make_batches,
    select_segments,
    split_segments,
)
from graphcal.graph import keys
from graphcal.graph.builder import build_segment_graph
from graphcal.graph.covariance import marginal_covariance
from graphcal.graph.graph_spec import shared_keys
from graphcal.graph.segment_solve import solve_segment_graph
from graphcal.graph.solve import solve_lm
from graphcal.localization.online import run_online
from graphcal.model import integrate, integrate_with_jacobians
from graphcal.pipeline.batch_calibration import calibrate_batch
from graphcal.pipeline.input_estimation import estimate_inputs
from graphcal.pipeline.joint import (
    JointSettings,
    calibrate_joint,
    solve_joint,
    without_defect_model,
)
from graphcal.pipeline.joint_batches import solve_joint_batches
from graphcal.pipeline.run import run_calibration
from graphcal.pipeline.settings import BatchingSettings, Settings
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive


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


def run_benchmarks(
    length_km: float = 24.0,
    repeats: int = 3,
    workers: int = 2,
    naive_iterations: int = 2,
    pipeline_batches: int = 20,
    agreement_segments: int = 3,
    import_hours: float = 3.0,
    scaling_km: tuple[float, ...] = (),
    fleet_vehicles: int = 0,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Run every item; return ``{"config": ..., "items": [...], "agreement": ...}``."""
    say = progress or (lambda _line: None)
    rows: list[dict[str, Any]] = []

    def record(name: str, seconds: float, **extra: Any) -> None:
        row = {"item": name, "median_s": seconds, "peak_mb": peak_memory_mb(), **extra}
        rows.append(row)
        note = ", ".join(
            f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in extra.items()
        )
        say(f"{name:<46} {seconds:10.4f} s  {row['peak_mb']:7.0f} MB  {note}")

    seconds, drive = timed(lambda: simulate_drive(length_km, seed=0), repeats)
    record("simulate drive (in memory)", seconds, samples=len(drive.measured))
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "drive.csv"
        seconds, _ = timed(lambda: write_synthetic_drive(drive, csv), repeats)
        record("write drive CSV + truth + sidecar", seconds)
        seconds, log = timed(lambda: load_drive_log(csv), repeats)
        record("load + validate drive CSV", seconds)
    seconds, segments = timed(lambda: split_segments(log, 150.0), repeats)
    record("split into 150 m segments", seconds, segments=len(segments))
    seconds, selected = timed(lambda: select_segments(log, segments), repeats)
    record("select by mean |yaw rate| > 0.15 rad/s", seconds, selected=len(selected))
    data = gather_segments(log, selected)
    theta = drive.theta_true
    seconds, _ = timed(lambda: integrate(data.poses[:, 0], data.inputs, theta), repeats)
    record("integrate all selected segments", seconds, steps=int(data.n_steps.sum()))
    seconds, _ = timed(
        lambda: integrate_with_jacobians(data.poses[:, 0], data.inputs, theta), repeats
    )
    record("integrate + Jacobians (start, theta)", seconds)

    settings = Settings()
    step1 = settings.calibration  # held start, the paper's Step 1
    batch = make_batches(len(selected), min(9, len(selected)), 1, seed=0)[0]
    one = data.take(batch)
    steps = int(one.n_steps.sum())

    seconds, result = timed(lambda: calibrate_batch(one, step1), repeats)
    graphcal_s = seconds / max(1, result.iterations)
    record(
        "(b) graphcal batch solve",
        seconds,
        iterations=result.iterations,
        per_iteration_s=graphcal_s,
        python_factors=len(one),
    )

    poses0, inputs0 = one.segment(0)
    seconds, _ = timed(
        lambda: estimate_inputs(poses0, inputs0, theta, settings.staged.step2), repeats
    )
    record("(c) input estimation, one segment", seconds, steps=len(inputs0))

    seconds, joint = timed(lambda: calibrate_joint(one, settings.joint), repeats)
    record("(d) graphcal joint batch solve", seconds, iterations=joint.iterations, steps=steps)

    # (a) last of the single solves: its thousands of Python factor objects slow every later
    # allocation (garbage-collector scans) until they are freed.
    naive = build_naive_graph(one, step1)
    optimizer = naive_optimizer(naive, naive_iterations)
    per_iteration = []
    for _ in range(naive_iterations):
        start = time.perf_counter()
        optimizer.iterate()
        per_iteration.append(time.perf_counter() - start)
    naive_s = statistics.median(per_iteration)
    record(
        "(a) naive per-step graph, LM, per iteration",
        naive_s,
        python_factors=naive.graph.size() - 1,
        steps=steps,
    )

    del naive, optimizer
    gc.collect()
    speedup = naive_s / graphcal_s

    # Agreement: both formulations to convergence on the first whole segments of the batch
    # (cut-down segments leave t_r unobservable with a held start).
    small = one.take(np.arange(min(agreement_segments, len(one))))
    exact = calibrate_batch(small, step1).theta
    approx, naive_iterations_used = solve_naive(small, step1)
    relative = float(np.linalg.norm(approx - exact) / np.linalg.norm(exact))
    say(f"(a) vs (b) converged on {len(small)} whole segments: |dtheta|/|theta| = {relative:.2e}")
    gc.collect()

    pipeline = Settings(batches=BatchingSettings(count=pipeline_batches))
    for method in ("staged", "joint"):
        start = time.perf_counter()
        run = run_calibration(log, pipeline, method, workers=workers)
        record(
            f"(e) {method} pipeline",
            time.perf_counter() - start,
            batches=len(run.batches),
            workers=workers,
        )

    segmented = segmented_items(record, data, repeats)
    batch_study = batch_study_items(record, data, max(pipeline_batches, 100), workers)
    defect_ratio = whole_log_items(record, log, repeats)
    localization = localization_items(record, repeats)
    importing = None
    if import_hours > 0:
        importing = import_item(import_hours)
        record(
            f"(h) graphcal import of a {importing['recording_hours']:.1f} h recording",
            importing["seconds"],
            **{k: v for k, v in importing.items() if k != "seconds"},
        )
    can_import = can_import_item(import_hours) if import_hours > 0 else None
    if can_import is not None:
        record(
            f"(h) graphcal import of a {can_import['recording_hours']:.1f} h CAN log + DBC",
            can_import["seconds"],
            **{k: v for k, v in can_import.items() if k != "seconds"},
        )

    scaling = None
    if scaling_km:
        scaling = scaling_item(tuple(scaling_km), workers)
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
            say(f"(k) time grows as length^{scaling['exponent']:.2f}")
        end_to_end = scaling["end_to_end"]
        if end_to_end is not None:
            for name, label in (("csv_alone", "CSV alone"), ("with_truth", "with its truth")):
                entry = end_to_end[name]
                record(
                    f"(k) graphcal calibrate --method whole, {end_to_end['length_km']:g} km, "
                    f"{label}",
                    entry["seconds"],
                    workers=workers,
                    process_peak_mb=entry["peak_mb"],
                )

    fleet = None
    if fleet_vehicles > 0:
        fleet = fleet_item(fleet_vehicles)
        for workers in (1, 2):
            entry = fleet[f"workers_{workers}"]
            record(
                f"(m) fleet of {fleet['logs']} logs on Dask, {workers} worker(s)",
                entry["seconds"],
                logs_per_minute=entry["logs_per_minute"],
                task_mean_s=entry["task_mean_s"],
                overhead_per_log_s=entry["overhead_per_log_s"],
            )
        say(
            f"(m) fleet: 2 workers over 1 {fleet['scaling_2_over_1']:.2f}x; local cluster "
            f"start and stop {fleet['cluster_start_stop_s']:.1f} s"
        )

    return {
        "config": {
            "length_km": length_km,
            "repeats": repeats,
            "workers": workers,
            "naive_iterations": naive_iterations,
            "pipeline_batches": pipeline_batches,
            "import_hours": import_hours,
            "scaling_km": list(scaling_km),
            "fleet_vehicles": fleet_vehicles,
            "python": sys.version.split()[0],
        },
        "items": rows,
        "naive_over_graphcal_per_iteration": speedup,
        "defect_model_over_plain_whole_log": defect_ratio,
        "segmented": segmented,
        "batch_study": batch_study,
        "scaling": scaling,
        "fleet": fleet,
        "localization": localization,
        "import": importing,
        "import_can": can_import,
        "agreement": {
            "segments": len(small),
            "steps": int(small.n_steps.sum()),
            "relative_theta_difference": relative,
            "naive_iterations": naive_iterations_used,
            "theta_segment_formulation": exact.tolist(),
            "theta_naive_formulation": approx.tolist(),
        },
    }


def segmented_items(record: Callable[..., None], data: SegmentData, repeats: int) -> dict[str, Any]:
    """(j) The joint solve of all selected segments with its covariance (the defaults' graph:
    theta, time offset, lever arm, heading biases), as one graph under GTSAM's
    Levenberg–Marquardt optimizer with GTSAM's marginals (the formulation before issue 14),
    and segment by segment (:mod:`graphcal.graph.partitioned`) in one and two processes, one
    after the other; returns the ratios and the largest relative theta and covariance
    differences to the single graph."""
    spec = JointSettings().graph_spec()
    shared = shared_keys(spec)

    def single_graph() -> tuple[np.ndarray, np.ndarray]:
        built = build_segment_graph(data, spec)
        result, _ = solve_lm(built.graph, built.values, 50, 1e-7, "single graph")
        covariance = marginal_covariance(built.graph, result, shared, "single graph")
        return np.asarray(result.atVector(keys.THETA)), covariance[:4, :4]

    single_s, (theta, covariance) = timed(single_graph, repeats)
    record("(j) whole-log joint solve, one graph (GTSAM LM)", single_s, segments=len(data))
    out: dict[str, Any] = {"segments": len(data), "single_graph_s": single_s}
    for workers in (1, 2):
        seconds, solution = timed(
            lambda w=workers: solve_segment_graph(data, spec, 50, 1e-7, "segmented", workers=w),
            repeats,
        )
        scale = np.sqrt(np.outer(np.diag(covariance), np.diag(covariance)))
        theta_difference = float(np.max(np.abs(solution.theta - theta) / np.abs(theta)))
        covariance_difference = float(np.max(np.abs(solution.covariance - covariance) / scale))
        record(
            f"(j) whole-log joint solve, segment by segment, {workers} process(es)",
            seconds,
            over_single=seconds / single_s,
            theta_rel_difference=theta_difference,
            covariance_rel_difference=covariance_difference,
        )
        out[f"segmented_{workers}_s"] = seconds
        out[f"single_over_segmented_{workers}"] = single_s / seconds
        out[f"theta_rel_difference_{workers}"] = theta_difference
        out[f"covariance_rel_difference_{workers}"] = covariance_difference
    return out


def batch_study_items(
    record: Callable[..., None], data: SegmentData, count: int, workers: int
) -> dict[str, Any]:
    """(l) The joint batch study of ``count`` batches of 9: solved one batch after the other
    (``"exact"``, the formulation before issue 14, timed on the first ``min(count, 10)``)
    and from the segments' systems at the whole-log solution (``"linearized"``, all
    ``count``), each per batch; with the largest theta difference in the exact solves' σ."""
    settings = dataclasses.replace(JointSettings(), robust_threshold=0.0, slip="off")
    batches = make_batches(len(data), min(9, len(data)), count, seed=0)
    start = time.perf_counter()
    _, values = solve_joint(data, settings, workers)
    whole_s = time.perf_counter() - start
    start = time.perf_counter()
    linearized = solve_joint_batches(data, batches, settings, "linearized", values, workers)
    linearized_s = (time.perf_counter() - start) / len(batches)
    few = batches[: min(len(batches), 10)]
    start = time.perf_counter()
    exact = solve_joint_batches(data, few, settings, "exact", workers=workers)
    exact_s = (time.perf_counter() - start) / len(few)
    difference = max(
        (
            float(np.max(np.abs(lin.theta - ex.theta) / np.sqrt(np.diag(ex.covariance))))
            for lin, ex in zip(linearized, exact, strict=False)
            if lin is not None and ex is not None
        ),
        default=None,
    )
    record("(l) joint batch, solved on its own (exact)", exact_s, batches=len(few))
    record(
        "(l) joint batch, from the segments' systems",
        linearized_s,
        batches=len(batches),
        exact_over_linearized=exact_s / linearized_s,
        max_theta_difference_sigma=difference,
        whole_log_solve_s=whole_s,
    )
    return {
        "batches": len(batches),
        "exact_per_batch_s": exact_s,
        "linearized_per_batch_s": linearized_s,
        "whole_log_solve_s": whole_s,
        "exact_over_linearized": exact_s / linearized_s,
        "max_theta_difference_sigma": difference,
    }


def whole_log_items(record: Callable[..., None], log: DriveLog, repeats: int) -> float:
    """(i) The whole-log solve (the recommended theta) of ``log`` with the defect model (the
    defaults) and without it (``--no-defect-model``), one after the other; returns the ratio
    of their median times (issue 13 asks at most 1.5 on a clean 24 km drive)."""
    settings = Settings()
    plain = dataclasses.replace(settings, joint=without_defect_model(settings.joint))
    plain_s, _ = timed(lambda: run_calibration(log, plain, "whole"), repeats)
    record("(i) whole-log solve, no defect model", plain_s)
    model_s, _ = timed(lambda: run_calibration(log, settings, "whole"), repeats)
    ratio = model_s / plain_s
    record("(i) whole-log solve, defect model (default)", model_s, over_plain=ratio)
    return ratio


def localization_items(
    record: Callable[..., None],
    repeats: int,
    length_km: float = 4.0,
    seed: int = 7,
) -> dict[str, Any]:
    """Items (f)–(g): the smoothing example with each odometry factor kind, and the online
    update; returns the ratios measured in this run."""
    drive = simulate_drive(length_km, seed=seed)
    log, theta = drive.measured, drive.theta_true
    solves, medians = {}, {}
    for kind, estimate in (
        ("reintegrating", False),
        ("between", False),
        ("reintegrating", True),
        ("preintegrated", True),
    ):
        label = f"{kind}, theta {'variable' if estimate else 'fixed'}"
        seconds, solved = timed(
            lambda k=kind, e=estimate: solve_smoothing(log, k, theta, e), repeats
        )
        solves[label], medians[label] = solved, seconds
        record(
            f"(f) smoothing {length_km:g} km, {label}",
            seconds,
            iterations=solved.iterations,
            keyframes=len(solved.states),
        )
    seconds, python_driven = timed(
        lambda: solve_smoothing(log, "preintegrated", theta, True, driver="python"), repeats
    )
    medians["python-driven"] = seconds
    record(
        f"(f) smoothing {length_km:g} km, preintegrated, theta variable, LM driven from Python",
        seconds,
        iterations=python_driven.iterations,
        keyframes=len(python_driven.states),
    )
    fixed_old, fixed_new = solves["reintegrating, theta fixed"], solves["between, theta fixed"]
    var_old = solves["reintegrating, theta variable"]
    var_new = solves["preintegrated, theta variable"]
    difference = np.linalg.norm(fixed_old.states[:, :2] - fixed_new.states[:, :2], axis=1)
    online = run_online(simulate_drive(3.5, seed=11).measured)
    record(
        "(g) online fixed-lag update (3.5 km)",
        float(np.median(online.update_seconds)),
        mean_update_ms=float(online.update_seconds.mean() * 1e3),
        ms_per_drive_second=online.seconds_per_drive_second() * 1e3,
    )
    return {
        "keyframes": len(fixed_new.states),
        "theta_fixed_reintegrating_over_between": medians["reintegrating, theta fixed"]
        / medians["between, theta fixed"],
        "theta_fixed_max_position_difference_m": float(difference.max()),
        "theta_variable_reintegrating_over_preintegrated": medians["reintegrating, theta variable"]
        / medians["preintegrated, theta variable"],
        "theta_variable_max_theta_difference": (var_old.theta - var_new.theta).tolist(),
        "theta_variable_gtsam_lm_over_python_lm": medians["preintegrated, theta variable"]
        / medians["python-driven"],
        "python_lm_theta_difference": (python_driven.theta - var_new.theta).tolist(),
        "online_mean_update_ms": float(online.update_seconds.mean() * 1e3),
        "online_ms_per_drive_second": online.seconds_per_drive_second() * 1e3,
    }


def run_from_options(args: Any, progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the benchmark with the options of :func:`graphcal.cli.bench.add_arguments`
    (sizes resolved by :func:`~graphcal.bench.options.resolve_bench_options`); returns the
    report (write it with :func:`write_report`)."""
    sizes = resolve_bench_options(args)
    if getattr(args, "only_import", False):
        return {
            "config": {"import_hours": sizes["import_hours"], "python": sys.version.split()[0]},
            "import": import_item(sizes["import_hours"]),
            "import_can": can_import_item(sizes["import_hours"]),
        }
    report = run_benchmarks(workers=args.workers, progress=progress, **sizes)
    report["config"]["quick"] = bool(getattr(args, "quick", False))
    return report


def write_report(report: dict[str, Any], path: str | Path) -> None:
    """Write the benchmark report as JSON."""
    Path(path).write_text(json.dumps(report, indent=2) + "\n")
