"""Benchmark item (n): ``graphcal calibrate`` with defaults on each recording the test suite
holds — the real highway car in its four forms, the real robot, the shipped sample drive —
and on simulated shapes the issues name (:data:`SIMULATED`: the 24 km default run, a 12 km
drive with every defect of real logs, wheels 0.3 s late, the skid-steer profile's own
recording), end to end in a child process: wall time, peak memory, exit status and the
whole-log solves with their iterations (from the run's progress lines; the model check's and
batches' solves are not said).

The recordings are read from the source tree's ``data/`` (an installed copy without it
gets no rows); the simulated ones are written by ``graphcal simulate`` into a temporary
directory first (not timed)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

#: The source tree's data folder.
DATA = Path(__file__).resolve().parents[2] / "data"

#: Each recording: its name and the arguments of ``graphcal calibrate`` before ``--out``.
RECORDINGS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("sample drive (synthetic, 4 km)", ("sample_drive.csv",)),
    ("car, fused pose (drive-log CSV)", ("real/comma2k19/drive.csv",)),
    ("car, u-blox + CAN wheel speeds", ("real/comma2k19/gnss.toml",)),
    ("car, u-blox + CAN + IMU", ("real/comma2k19/gnss_imu.toml",)),
    ("car, u-blox + raw CAN log + DBC", ("real/comma2k19/can.toml",)),
    (
        "robot, motion capture, 7 runs",
        ("real/optiodom/free", "--vehicle", "vehicles/mocap_robot.toml"),
    ),
)

#: Each simulated shape: its name, the arguments of ``graphcal simulate`` before ``--out``
#: or ``--streams`` (``{out}``: where it writes), and those of ``graphcal calibrate`` (``{out}``:
#: what it wrote; other relative paths in :data:`DATA`).
SIMULATED: tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...] = (
    (
        "simulated city drive, 24 km (seed 3)",
        ("--length-km", "24", "--seed", "3", "--out", "{out}/city24.csv"),
        ("{out}/city24.csv",),
    ),
    (
        "simulated 12 km, every defect of real logs (seed 3)",
        ("--length-km", "12", "--seed", "3", "--defects", "all", "--out", "{out}/defects12.csv"),
        ("{out}/defects12.csv",),
    ),
    (
        "simulated 4 km, wheels 0.3 s late (seed 3)",
        ("--length-km", "4", "--seed", "3", "--defects", "latency=0.3", "--out", "{out}/late4.csv"),
        ("{out}/late4.csv",),
    ),
    (
        "simulated skid-steer robot, its profile's streams (seed 0)",
        ("--vehicle", str(DATA / "vehicles/skid_steer_robot.toml"), "--streams", "{out}/skid"),
        ("{out}/skid/manifest.toml", "--vehicle", "vehicles/skid_steer_robot.toml"),
    ),
)

#: A whole-log solve's closing progress line: ``[  7.5 s]   3 iterations, χ²/dof 0.99``.
_SOLVE_LINE = re.compile(r"^\[\s*[\d.]+ s\]\s+(\d+) iterations")

#: Runs ``graphcal calibrate`` and prints its wall time, exit status, peak memory (of it and
#: its workers) and its progress lines.
_CHILD = """
import json, resource, subprocess, sys, time
start = time.perf_counter()
done = subprocess.run([sys.executable, "-m", "graphcal.cli", *sys.argv[1:]],
                      capture_output=True, text=True)
print(json.dumps({
    "seconds": time.perf_counter() - start,
    "returncode": done.returncode,
    "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
    "lines": (done.stdout + done.stderr).splitlines(),
}))
"""


def solve_iterations(lines: list[str]) -> list[int]:
    """The iterations of each whole-log solve a run's progress ``lines`` report."""
    return [int(m.group(1)) for line in lines if (m := _SOLVE_LINE.match(line))]


def calibrate_recording(arguments: tuple[str, ...], workers: int) -> dict:
    """``graphcal calibrate`` of the recording of ``arguments`` (paths in :data:`DATA`) with
    ``workers``, in a child process: seconds, exit status, peak MB, the whole-log solves'
    iterations."""
    resolved = [a if a.startswith(("-", "/")) else str(DATA / a) for a in arguments]
    with tempfile.TemporaryDirectory() as tmp:
        command = ["calibrate", *resolved, "--workers", str(workers), "--out", f"{tmp}/out"]
        # In the temporary directory: ``python -m`` puts the working directory first on the
        # path, so from a source tree it would import that tree whatever PYTHONPATH says.
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, *command],
            capture_output=True,
            text=True,
            check=False,
            cwd=tmp,
        )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    iterations = solve_iterations(result.pop("lines"))
    return {**result, "solves": len(iterations), "iterations": iterations}


def simulated_recordings(folder: Path) -> list[tuple[str, tuple[str, ...]]]:
    """Write every shape of :data:`SIMULATED` into ``folder`` with ``graphcal simulate``;
    each one's name and the arguments that calibrate it."""
    out = []
    for name, simulate, calibrate in SIMULATED:
        filled = [a.replace("{out}", str(folder)) for a in simulate]
        subprocess.run(
            [sys.executable, "-m", "graphcal.cli", "simulate", *filled],
            capture_output=True,
            check=True,
            cwd=folder,
        )
        out.append((name, tuple(a.replace("{out}", str(folder)) for a in calibrate)))
    return out


def recording_items(record, workers: int) -> list[dict]:
    """(n): every recording of :data:`RECORDINGS` and :data:`SIMULATED` calibrated with
    defaults, one row each; none when the source tree's data are missing."""
    if not (DATA / "real").is_dir():
        record.say("(n) no recordings: data/ of the source tree not found")
        return []
    with tempfile.TemporaryDirectory() as tmp:
        return _calibrated(record, workers, [*RECORDINGS, *simulated_recordings(Path(tmp))])


def _calibrated(record, workers: int, recordings: list) -> list[dict]:
    out = []
    for name, arguments in recordings:
        run = calibrate_recording(arguments, workers)
        record(
            f"(n) calibrate {name}",
            run["seconds"],
            workers=workers,
            exit=run["returncode"],
            process_peak_mb=run["peak_mb"],
            solves=run["solves"],
            iterations=run["iterations"],
        )
        out.append({"recording": name, **run})
    return out
