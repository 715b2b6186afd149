"""Benchmark item (k): the whole-log calibration at several drive lengths, and how its time
grows with the length.

Each length is a synthetic city drive (``simulate_drive(length, seed)``, in memory) calibrated
by ``run_calibration(log, Settings(), "whole", workers=...)`` in a child process, so that its
peak memory is its own (the workers' peak beside it). The exponent ``b`` of
``time ∝ length^b`` is the slope of a least-squares line through ``(log length, log time)``:
1 is linear, 2 quadratic.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

_CHILD = """
import json, resource, sys, time
from graphcal.pipeline.run import run_calibration
from graphcal.pipeline.settings import Settings
from graphcal.simulate.drive import simulate_drive
length, seed, workers = float(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
log = simulate_drive(length, seed=seed).measured
start = time.perf_counter()
run = run_calibration(log, Settings(), "whole", workers=workers)
seconds = time.perf_counter() - start
print(json.dumps({
    "seconds": seconds,
    "samples": len(log.t),
    # VmHWM, not ru_maxrss: Linux keeps ru_maxrss across exec, so a child of a large
    # benchmark process would report the parent's peak.
    "peak_mb": next(int(line.split()[1]) for line in open("/proc/self/status")
                    if line.startswith("VmHWM")) / 1024,
    "worker_peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    "iterations": run.whole.iterations,
}))
"""


def whole_log_at(length_km: float, seed: int, workers: int) -> dict:
    """Time [s] and peak memory [MB] of the whole-log calibration of a ``length_km`` drive,
    in a child process."""
    command = [sys.executable, "-c", _CHILD, str(length_km), str(seed), str(workers)]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"whole-log calibration at {length_km} km failed: {done.stderr}")
    return {"length_km": length_km, **json.loads(done.stdout.strip().splitlines()[-1])}


def growth_exponent(lengths: list[float], seconds: list[float]) -> float:
    """Slope of ``log(seconds)`` over ``log(lengths)`` (least squares)."""
    return float(np.polyfit(np.log(lengths), np.log(seconds), 1)[0])


def scaling_item(lengths_km: tuple[float, ...], workers: int, seed: int = 5) -> dict:
    """The whole-log calibration at every length of ``lengths_km`` (one child process each)
    and the fitted exponent of its time."""
    runs = [whole_log_at(length, seed, workers) for length in lengths_km]
    exponent = None
    if len(runs) >= 2:
        exponent = growth_exponent([r["length_km"] for r in runs], [r["seconds"] for r in runs])
    return {"workers": workers, "seed": seed, "runs": runs, "exponent": exponent}
