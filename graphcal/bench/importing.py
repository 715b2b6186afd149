"""Benchmark item (h): importing a long recording (`graphcal import`), time and peak memory.

A synthetic drive of ``hours`` hours is written as raw streams (GNSS at 10 Hz, rear wheels
and IMU at 100 Hz; :mod:`graphcal.simulate.streams`) and as an MCAP file (nav_msgs/Odometry,
JointState, Imu), then each is imported by ``graphcal import`` in a child process, so that
the peak memory is the import's own.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from graphcal.simulate.streams import simulate_streams, write_streams

#: Mean speed [km/h] of the synthetic city drive (measured: 40.2), to size a drive by duration.
CITY_SPEED_KMH = 41.0

#: The child: ``graphcal import``, then its peak memory. VmHWM is this process's own high-water
#: mark; ``ru_maxrss`` (where /proc is missing) keeps the parent's across a vfork and exec,
#: which the bench parent, holding the simulated recording, exceeds.
_CHILD = """
import resource, sys
from graphcal.cli import main
status = main(sys.argv[1:])
try:
    with open("/proc/self/status") as handle:
        peak = next(int(l.split()[1]) for l in handle if l.startswith("VmHWM:"))
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("PEAK_KIB", peak)
sys.exit(status)
"""


def _child_import(source: Path, out: Path) -> tuple[float, float]:
    """Wall time [s] and peak memory [MB] of ``graphcal import SOURCE --out OUT``, a child."""
    command = [sys.executable, "-c", _CHILD, "import", str(source), "--out", str(out)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"graphcal import failed: {done.stderr.strip()}")
    peak = next(
        int(line.split()[1]) for line in done.stdout.splitlines() if line.startswith("PEAK")
    )
    return seconds, peak / 1024.0


def import_item(hours: float = 3.0, seed: int = 7) -> dict:
    """Time ``graphcal import`` of an ``hours``-long recording as CSV streams and as an MCAP
    file (when rosbags is installed); return the item's figures."""
    with tempfile.TemporaryDirectory(prefix="graphcal-bench-import-") as tmp:
        directory = Path(tmp)
        sim = simulate_streams(hours * CITY_SPEED_KMH, seed)
        write_streams(sim, directory / "streams")
        duration = float(sim.wheels["t"].iloc[-1] - sim.wheels["t"].iloc[0])
        sizes = {
            name: (directory / "streams" / name).stat().st_size / 1e6
            for name in ("gnss.csv", "wheels.csv", "imu.csv")
        }
        out = directory / "drive.csv"
        seconds, peak = _child_import(directory / "streams" / "manifest.toml", out)
        result = {
            "seconds": seconds,
            "peak_memory_mb": peak,
            "recording_hours": duration / 3600.0,
            "gnss_fixes": len(sim.gnss),
            "wheel_samples": len(sim.wheels),
            "imu_samples": len(sim.imu),
            "csv_mb": sum(sizes.values()),
            "drive_log_mb": out.stat().st_size / 1e6,
        }
        if importlib.util.find_spec("rosbags") is None:  # no bags: the CSV figures only
            return result
        from graphcal.simulate.bags import write_bag

        bag = write_bag(sim.recording, directory / "bag", "mcap", pose_message="odometry")
        mcap = next(bag.glob("*.mcap"))
        seconds, peak = _child_import(mcap, directory / "from_bag.csv")
        result["mcap_seconds"] = seconds
        result["mcap_peak_memory_mb"] = peak
        result["mcap_mb"] = mcap.stat().st_size / 1e6
        return result
