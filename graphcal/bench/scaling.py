"""Benchmark item (k): the whole-log calibration at several drive lengths, how its time
grows with the length, and the command line end to end at the longest.

Each length is a synthetic city drive (``simulate_drive(length, seed)``, in memory) calibrated
by ``run_calibration(log, Settings(), "whole", workers=...)`` in a child process, so that its
peak memory is its own (the workers' peak beside it). The exponent ``b`` of
``time ∝ length^b`` is the slope of a least-squares line through ``(log length, log time)``:
1 is linear, 2 quadratic.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

_CHILD = """
import json, resource, sys, time
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.configuration.settings import Settings
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


#: Runs a command and prints its wall time and the largest peak resident memory of it and
#: its descendants (a fresh process: its children's peaks are theirs alone).
_TIMED = """
import json, resource, subprocess, sys, time
start = time.perf_counter()
done = subprocess.run(sys.argv[1:], capture_output=True, text=True)
print(json.dumps({
    "seconds": time.perf_counter() - start,
    "returncode": done.returncode,
    "stderr": done.stderr[-2000:],
    "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
}))
"""


def _timed_command(command: list[str]) -> dict:
    """Wall time [s] and peak memory [MB] (the largest process of it) of ``command``."""
    done = subprocess.run(
        [sys.executable, "-c", _TIMED, *command], capture_output=True, text=True, check=False
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if result["returncode"] != 0:
        raise RuntimeError(f"{' '.join(command)} failed: {result['stderr']}")
    return {"seconds": result["seconds"], "peak_mb": result["peak_mb"]}


def end_to_end_at(length_km: float, seed: int, workers: int) -> dict:
    """``graphcal calibrate DRIVE.csv --method whole`` from the command line, timed from the
    start of the process to its end (imports, loading, figures and files included): on the
    CSV alone, as a real log comes, and beside its sidecar and truth, where the run also
    compares with the truth and computes the Cramér–Rao bound."""
    graphcal = [sys.executable, "-m", "graphcal.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        synthetic = Path(tmp) / "synthetic" / "drive.csv"
        synthetic.parent.mkdir()
        subprocess.run(
            [*graphcal, "simulate", "--length-km", f"{length_km:g}", "--seed", str(seed),
             "--out", str(synthetic)],
            capture_output=True, check=True,
        )  # fmt: skip
        alone = Path(tmp) / "real" / "drive.csv"
        alone.parent.mkdir()
        shutil.copyfile(synthetic, alone)
        out = {"length_km": length_km, "seed": seed, "workers": workers}
        for name, csv in (("csv_alone", alone), ("with_truth", synthetic)):
            command = [
                *graphcal, "calibrate", str(csv), "--method", "whole", "--workers",
                str(workers), "--out", str(csv.parent / "results"),
            ]  # fmt: skip
            out[name] = _timed_command(command)
    return out


def growth_exponent(lengths: list[float], seconds: list[float]) -> float:
    """Slope of ``log(seconds)`` over ``log(lengths)`` (least squares)."""
    return float(np.polyfit(np.log(lengths), np.log(seconds), 1)[0])


def scaling_item(lengths_km: tuple[float, ...], workers: int, seed: int = 5) -> dict:
    """The whole-log calibration at every length of ``lengths_km`` (one child process each),
    the fitted exponent of its time, and the command line end to end at the longest."""
    runs = [whole_log_at(length, seed, workers) for length in lengths_km]
    exponent = None
    if len(runs) >= 2:
        exponent = growth_exponent([r["length_km"] for r in runs], [r["seconds"] for r in runs])
    end_to_end = end_to_end_at(max(lengths_km), seed, workers) if lengths_km else None
    return {
        "workers": workers,
        "seed": seed,
        "runs": runs,
        "exponent": exponent,
        "end_to_end": end_to_end,
    }
