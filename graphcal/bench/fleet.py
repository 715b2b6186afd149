"""Benchmark item (m): fleet throughput on Dask with 1 and 2 workers, and Dask's overhead.

A synthetic fleet (``vehicles`` × ``days`` drives of ``length_km``, no change) is calibrated
twice from scratch by :func:`graphcal.fleet.run.run_fleet` on a local cluster of 1 and of 2
worker processes. Per run: logs per minute (wall time, cluster start included), the mean
calibration time of a log measured inside its task, and the overhead per log,
``(wall × workers − Σ task time) / logs``: what Dask, hashing and writing add. The start and
stop of an empty local cluster is timed on its own.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any


def fleet_item(vehicles: int, days: int = 2, length_km: float = 4.0) -> dict[str, Any]:
    """Run item (m); returns its measurements (see the module docstring)."""
    from distributed import Client, LocalCluster

    from graphcal.fleet.run import FleetOptions, run_fleet
    from graphcal.simulate.fleet import simulate_fleet

    start = time.perf_counter()
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        with Client(cluster):
            pass
    cluster_start_s = time.perf_counter() - start
    out: dict[str, Any] = {
        "logs": vehicles * days,
        "length_km": length_km,
        "cluster_start_stop_s": cluster_start_s,
    }
    with tempfile.TemporaryDirectory() as tmp:
        source = Path(tmp) / "fleet"
        simulate_fleet(source, vehicles, days, length_km, seed=0)
        for workers in (1, 2):
            start = time.perf_counter()
            run = run_fleet(source, Path(tmp) / f"out{workers}", options=FleetOptions(workers))
            wall = time.perf_counter() - start
            tasks = sum(r["seconds"] for r in run.results)
            logs = len(run.results)
            out[f"workers_{workers}"] = {
                "seconds": wall,
                "logs_per_minute": 60.0 * logs / wall,
                "task_mean_s": tasks / logs,
                "overhead_per_log_s": (wall * workers - tasks) / logs,
                "failed": run.failed,
            }
    out["scaling_2_over_1"] = (
        out["workers_2"]["logs_per_minute"] / out["workers_1"]["logs_per_minute"]
    )
    return out
