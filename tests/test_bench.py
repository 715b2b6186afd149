"""The benchmark's baseline: the naive per-step formulation solves the same problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from graphcal.bench.naive import build_naive_graph, solve_naive
from graphcal.log.segments import gather_segments, select_segments, split_segments
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.solvers.batch_calibration import calibrate_batch
from graphcal.simulate.drive import NoiseLevels, simulate_drive


@pytest.mark.slow
def test_naive_per_step_graph_agrees_with_the_segment_formulation():
    # Low noise and a short segment keep the naive graph (365 Python factors) to seconds.
    noise = NoiseLevels(position=0.05, heading=np.deg2rad(0.3), wheel_rotation=0.0001)
    log = simulate_drive(1.5, seed=2, noise=noise).measured
    data = gather_segments(log, select_segments(log, split_segments(log, 80.0)))
    small = data.take([0])
    settings = Settings().calibration  # held start: the paper's Step 1
    naive = build_naive_graph(small, settings)
    assert naive.graph.size() == int(small.n_steps[0]) + 1  # a factor per step, theta prior
    exact = calibrate_batch(small, settings).theta
    approx, iterations = solve_naive(small, settings)
    assert iterations > 3  # it really solved from nominal, not from the answer
    assert np.linalg.norm(approx - exact) / np.linalg.norm(exact) < 1e-6


def test_quick_preset_and_explicit_sizes():
    import argparse

    from graphcal.bench.options import FULL, QUICK, resolve_bench_options
    from graphcal.cli.bench import add_arguments

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert resolve_bench_options(parser.parse_args([])) == FULL
    assert resolve_bench_options(parser.parse_args(["--quick"])) == QUICK
    mixed = resolve_bench_options(parser.parse_args(["--quick", "--repeats", "2"]))
    assert mixed == {**QUICK, "repeats": 2}  # what is given wins over the preset


@pytest.mark.slow
def test_segmented_bench_item_agrees_with_the_single_graph():
    from graphcal.bench.whole_log_items import segmented_items

    log = simulate_drive(3.0, seed=4).measured
    data = gather_segments(log, select_segments(log, split_segments(log, 150.0)))
    rows = []
    report = segmented_items(lambda name, seconds, **extra: rows.append(name), data, 1)
    assert len(rows) == 3 and report["segments"] == len(data)
    for workers in (1, 2):
        assert report[f"theta_rel_difference_{workers}"] < 1e-6
        assert report[f"covariance_rel_difference_{workers}"] < 1e-4


@pytest.mark.slow
def test_scaling_item_fits_the_growth_exponent():
    from graphcal.bench.scaling import growth_exponent, scaling_item

    assert abs(growth_exponent([50, 100, 200], [4.0, 8.0, 16.0]) - 1.0) < 1e-12
    assert abs(growth_exponent([50, 100, 200], [1.0, 4.0, 16.0]) - 2.0) < 1e-12
    report = scaling_item((3.0,), workers=2)
    (run,) = report["runs"]
    assert run["length_km"] == 3.0 and run["seconds"] > 0 and run["iterations"] >= 1
    assert run["samples"] > 1000 and run["peak_mb"] > 0
    assert report["exponent"] is None  # one length: nothing to fit


def test_the_recordings_item_reads_each_whole_log_solve_from_the_progress_lines():
    from graphcal.bench.recordings import solve_iterations

    lines = [
        "[   0.2 s] joint solve over all 44 selected segments",
        "[   5.8 s]   iteration 3: χ²/dof 0.9931, Gauss–Newton (2 s)",
        "[   7.5 s]   3 iterations, χ²/dof 0.99",
        "[   7.6 s] wheels shifted by -75.0 ms; solved again from the shifted log",
        "[  12.0 s]   12 iterations, χ²/dof 1.43",
        "[  12.1 s] joint batches: 100 solved from the segments' systems",
    ]
    assert solve_iterations(lines) == [3, 12]


@pytest.mark.slow
def test_the_sample_drive_calibrates_in_a_few_iterations_per_solve():
    from graphcal.bench.recordings import calibrate_recording

    run = calibrate_recording(("sample_drive.csv",), workers=1)
    assert run["returncode"] == 0
    assert 1 <= run["solves"] <= 3 and max(run["iterations"]) < 10


@pytest.mark.slow
def test_the_simulated_shapes_are_written_where_their_calibration_reads_them(tmp_path):
    """Item (n)'s simulated shapes: each written by ``graphcal simulate`` into the folder,
    and each calibration's recording there (the 24 km and 12 km drives once overwrote one
    another under one name)."""
    from graphcal.bench.recordings import SIMULATED, simulated_recordings

    shapes = simulated_recordings(tmp_path)
    assert [name for name, _ in shapes] == [name for name, _, _ in SIMULATED]
    recordings = [Path(arguments[0]) for _, arguments in shapes]
    assert len(set(recordings)) == len(recordings)
    assert all(r.is_file() and r.parent.is_relative_to(tmp_path) for r in recordings)
