"""Benchmarks of graphcal's foundation: simulate, write, load, segment and integrate.

    python scripts/bench.py [--length-km 24] [--repeats 3] [--out bench.json]

Prints a table and writes ``bench.json`` with, per item, the median wall time over the repeats
and the peak memory the process had after it (``ru_maxrss``). Timing belongs here, never in
the tests.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from graphcal.data.drive_log import load_drive_log
from graphcal.data.segments import gather_segments, select_segments, split_segments
from graphcal.model import integrate, integrate_with_jacobians
from graphcal.simulate.drive import simulate_drive, write_synthetic_drive


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    """Median wall time [s] of ``fn`` over ``repeats`` calls, and its last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("bench.json"))
    args = parser.parse_args(argv)

    rows: list[dict] = []

    def record(name: str, seconds: float, note: str = "") -> None:
        rows.append({"item": name, "median_s": seconds, "peak_mb": _peak_mb(), "note": note})
        print(f"{name:<44} {seconds:9.4f} s  {_peak_mb():8.0f} MB  {note}", flush=True)

    print(f"graphcal foundation benchmark, {args.length_km:g} km, median of {args.repeats}")
    seconds, drive = timed(lambda: simulate_drive(args.length_km, seed=0), args.repeats)
    record("simulate drive (in memory)", seconds, f"{len(drive.measured)} samples")
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "drive.csv"
        seconds, _ = timed(lambda: write_synthetic_drive(drive, csv), args.repeats)
        record(
            "write drive CSV + truth + sidecar",
            seconds,
            f"{csv.stat().st_size / 1e6:.1f} MB per CSV",
        )
        seconds, log = timed(lambda: load_drive_log(csv), args.repeats)
        record("load + validate drive CSV", seconds)
    seconds, segments = timed(lambda: split_segments(log, 150.0, stride=25.0), args.repeats)
    record("split into 150 m segments, 25 m stride", seconds, f"{len(segments)} segments")
    seconds, selected = timed(lambda: select_segments(log, segments), args.repeats)
    record("select by mean |yaw rate| > 0.15 rad/s", seconds, f"{len(selected)} selected")
    data = gather_segments(log, selected)
    theta = np.array([1.985, 1.2e-3, 1.585, 1.5e-3])
    steps = int(data.n_steps.sum())
    seconds, _ = timed(lambda: integrate(data.poses[:, 0], data.inputs, theta), args.repeats)
    record("integrate all selected segments", seconds, f"{steps} steps, {steps / seconds:.3g}/s")
    seconds, _ = timed(
        lambda: integrate_with_jacobians(data.poses[:, 0], data.inputs, theta), args.repeats
    )
    record("integrate + Jacobians (start, theta)", seconds)

    args.out.write_text(
        json.dumps(
            {
                "length_km": args.length_km,
                "repeats": args.repeats,
                "python": sys.version.split()[0],
                "items": rows,
            },
            indent=2,
        )
    )
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
