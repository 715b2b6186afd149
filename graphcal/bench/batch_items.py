"""The benchmark's items up to one batch: the foundation, (a)–(e) and the agreement of (a)
and (b) (:mod:`graphcal.bench.run` lists them all).

Each item takes the :class:`~graphcal.bench.recording.BenchRun`, records its rows and
returns its entries of the report (none for most).
"""

from __future__ import annotations

import gc
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from graphcal.bench.naive import build_naive_graph, naive_optimizer, solve_naive
from graphcal.bench.recording import BenchRun, timed
from graphcal.log.load import load_drive_log
from graphcal.log.segments import gather_segments, make_batches, select_segments, split_segments
from graphcal.model import integrate, integrate_with_jacobians
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.solvers.batch_calibration import calibrate_batch
from graphcal.pipeline.solvers.input_estimation import estimate_inputs
from graphcal.pipeline.solvers.joint import calibrate_joint
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive


def drive_items(bench: BenchRun) -> dict[str, Any]:
    """Foundation: simulate the drive, write it as CSV with its truth, load it back."""
    record, repeats = bench.record, bench.repeats
    seconds, drive = timed(lambda: simulate_drive(bench.length_km, seed=0), repeats)
    record("simulate drive (in memory)", seconds, samples=len(drive.measured))
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "drive.csv"
        seconds, _ = timed(lambda: write_synthetic_drive(drive, csv), repeats)
        record("write drive CSV + truth + sidecar", seconds)
        seconds, log = timed(lambda: load_drive_log(csv), repeats)
        record("load + validate drive CSV", seconds)
    bench.drive, bench.log = drive, log
    return {}


def segment_items(bench: BenchRun) -> dict[str, Any]:
    """Foundation: split the log into segments, select them, integrate the selected ones
    (with and without the Jacobians) at the true theta."""
    record, repeats, log = bench.record, bench.repeats, bench.log
    seconds, segments = timed(lambda: split_segments(log, 150.0), repeats)
    record("split into 150 m segments", seconds, segments=len(segments))
    seconds, selected = timed(lambda: select_segments(log, segments), repeats)
    record("select by mean |yaw rate| > 0.15 rad/s", seconds, selected=len(selected))
    data = gather_segments(log, selected)
    theta = bench.drive.theta_true
    seconds, _ = timed(lambda: integrate(data.poses[:, 0], data.inputs, theta), repeats)
    record("integrate all selected segments", seconds, steps=int(data.n_steps.sum()))
    seconds, _ = timed(
        lambda: integrate_with_jacobians(data.poses[:, 0], data.inputs, theta), repeats
    )
    record("integrate + Jacobians (start, theta)", seconds)
    bench.selected, bench.data = selected, data
    return {}


def single_solve_items(bench: BenchRun) -> dict[str, Any]:
    """(b) graphcal's batch solve of a batch of up to 9 selected segments, (c) the input
    estimation of its first segment, (d) its joint batch solve."""
    record, repeats = bench.record, bench.repeats
    settings = Settings()
    step1 = settings.calibration  # held start, the paper's Step 1
    selected = bench.selected
    batch = make_batches(len(selected), min(9, len(selected)), 1, seed=0)[0]
    one = bench.data.take(batch)
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
    theta = bench.drive.theta_true
    seconds, _ = timed(
        lambda: estimate_inputs(poses0, inputs0, theta, settings.staged.step2), repeats
    )
    record("(c) input estimation, one segment", seconds, steps=len(inputs0))

    seconds, joint = timed(lambda: calibrate_joint(one, settings.joint), repeats)
    record("(d) graphcal joint batch solve", seconds, iterations=joint.iterations, steps=steps)
    bench.batch, bench.settings, bench.graphcal_s = one, settings, graphcal_s
    return {}


def naive_item(bench: BenchRun) -> dict[str, Any]:
    """(a) The naive per-step formulation of the batch: LM's time per iteration; returns
    its ratio to (b)'s.

    Last of the single solves: its thousands of Python factor objects slow every later
    allocation (garbage-collector scans) until they are freed."""
    one, iterations = bench.batch, bench.naive_iterations
    naive = build_naive_graph(one, bench.settings.calibration)
    optimizer = naive_optimizer(naive, iterations)
    per_iteration = []
    for _ in range(iterations):
        start = time.perf_counter()
        optimizer.iterate()
        per_iteration.append(time.perf_counter() - start)
    naive_s = statistics.median(per_iteration)
    bench.record(
        "(a) naive per-step graph, LM, per iteration",
        naive_s,
        python_factors=naive.graph.size() - 1,
        steps=int(one.n_steps.sum()),
    )

    del naive, optimizer
    gc.collect()
    return {"naive_over_graphcal_per_iteration": naive_s / bench.graphcal_s}


def agreement_item(bench: BenchRun) -> dict[str, Any]:
    """Agreement of (a) and (b): both formulations to convergence on the first whole
    segments of the batch (cut-down segments leave t_r unobservable with a held start)."""
    one, step1 = bench.batch, bench.settings.calibration
    small = one.take(np.arange(min(bench.agreement_segments, len(one))))
    exact = calibrate_batch(small, step1).theta
    approx, naive_iterations_used = solve_naive(small, step1)
    relative = float(np.linalg.norm(approx - exact) / np.linalg.norm(exact))
    bench.record.say(
        f"(a) vs (b) converged on {len(small)} whole segments: |dtheta|/|theta| = {relative:.2e}"
    )
    gc.collect()
    return {
        "agreement": {
            "segments": len(small),
            "steps": int(small.n_steps.sum()),
            "relative_theta_difference": relative,
            "naive_iterations": naive_iterations_used,
            "theta_segment_formulation": exact.tolist(),
            "theta_naive_formulation": approx.tolist(),
        }
    }


def pipeline_items(bench: BenchRun) -> dict[str, Any]:
    """(e) The staged and joint pipelines end to end, with the run's batches and workers."""
    pipeline = Settings(batches=BatchingSettings(count=bench.pipeline_batches))
    for method in ("staged", "joint"):
        start = time.perf_counter()
        run = run_calibration(bench.log, pipeline, method, workers=bench.workers)
        bench.record(
            f"(e) {method} pipeline",
            time.perf_counter() - start,
            batches=len(run.batches),
            workers=bench.workers,
        )
    return {}
