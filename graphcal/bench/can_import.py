"""Benchmark item (h), CAN case: ``graphcal import`` of a long raw CAN log with its DBC, time
and peak memory (issue 28: a 3-hour log of a car's whole bus in at most 60 s and 2 GB).

A synthetic drive of ``hours`` hours is sampled as GNSS (10 Hz, a CSV), the rear wheels'
speeds in ``WHEEL_SPEEDS`` at 50 Hz and the IMU in the multiplexed ``KINEMATICS`` at 100 Hz,
on a bus with ~70 unrelated ids: ~2,000 frames/s, 21.6 M frames in 3 hours, written as a
candump log (:mod:`graphcal.simulate.can_log`); the manifest reads the wheels and the IMU
from it with the DBC, and ``graphcal import`` runs in a child process, so that the peak
memory is the import's own.
"""

from __future__ import annotations

import importlib.util
import tempfile
import time
from pathlib import Path

from graphcal.bench.importing import CITY_SPEED_KMH, _child_import


def can_import_item(hours: float = 3.0, seed: int = 7) -> dict | None:
    """Time ``graphcal import`` of an ``hours``-long candump log of a car's bus with its DBC;
    return the item's figures (``None`` without cantools and python-can: the can extra)."""
    if any(importlib.util.find_spec(name) is None for name in ("cantools", "can")):
        return None
    from graphcal.simulate.can_log import (
        CAR_DBC,
        car_traffic,
        manifest_text,
        write_car_candump,
    )
    from graphcal.simulate.streams import StreamSettings, simulate_streams, write_streams

    with tempfile.TemporaryDirectory(prefix="graphcal-bench-can-") as tmp:
        directory = Path(tmp)
        sim = simulate_streams(
            hours * CITY_SPEED_KMH, seed, settings=StreamSettings(wheel_rate=50.0)
        )
        write_streams(sim, directory)  # gnss.csv and truth.json (its CSVs are not read)
        (directory / "car.dbc").write_text(CAR_DBC)
        start = time.perf_counter()
        frames = write_car_candump(sim, directory / "drive.log", car_traffic(), seed=seed)
        write_s = time.perf_counter() - start
        manifest = directory / "can.toml"
        manifest.write_text(
            manifest_text("drive.log", "car.dbc", float(sim.settings.circumference))
        )
        out = directory / "drive.csv"
        seconds, peak = _child_import(manifest, out)
        duration = float(sim.wheels["t"].iloc[-1] - sim.wheels["t"].iloc[0])
        return {
            "seconds": seconds,
            "peak_memory_mb": peak,
            "recording_hours": duration / 3600.0,
            "frames": frames,
            "frames_per_s": frames / duration,
            "wheel_frames": len(sim.wheels),
            "imu_frames": len(sim.imu),
            "log_mb": (directory / "drive.log").stat().st_size / 1e6,
            "log_write_s": write_s,
            "drive_log_mb": out.stat().st_size / 1e6,
        }
