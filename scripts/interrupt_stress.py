"""Ctrl-C at random moments, on a loaded machine (issue 44's acceptance).

Sends SIGINT to the process group of a graphcal command after a random delay, with busy
loops running beside it, and checks what a user expects: exit 130 within 5 s, one line
(``graphcal: interrupted``), no traceback, nothing half-written in the output. Commands:
calibrate (defaults; ``--batches 1000 --workers 2``; a 24 km ``--defects all`` drive),
import, fleet and simulate.

    python scripts/interrupt_stress.py --n 200 --seed 0      # about 15 minutes

Prints one line per interrupt that broke an expectation and a summary table.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GRAPHCAL = [sys.executable, "-m", "graphcal.cli"]


def _busy(stop: float) -> None:
    while time.time() < stop:
        pass


def _prepare(work: Path) -> dict[str, list[str]]:
    """The inputs the commands read (made once) and each command, writing into ``OUT``."""
    big = work / "big.csv"
    subprocess.run(
        [*GRAPHCAL, "simulate", "--length-km", "24", "--defects", "all", "--seed", "3",
         "--out", str(big)],
        check=True, capture_output=True,
    )  # fmt: skip
    streams = work / "streams"
    subprocess.run(
        [*GRAPHCAL, "simulate", "--length-km", "4", "--streams", str(streams), "--seed", "2"],
        check=True, capture_output=True,
    )  # fmt: skip
    fleet = work / "fleet"
    subprocess.run(
        [*GRAPHCAL, "simulate", "--fleet", str(fleet), "--vehicles", "2", "--days", "2",
         "--length-km", "2"],
        check=True, capture_output=True,
    )  # fmt: skip
    sample = str(ROOT / "data" / "sample_drive.csv")
    return {
        "calibrate": [*GRAPHCAL, "calibrate", sample, "--out", "OUT"],
        "calibrate-1000": [
            *GRAPHCAL,
            "calibrate",
            sample,
            "--batches",
            "1000",
            "--workers",
            "2",
            "--out",
            "OUT",
        ],
        "calibrate-24km": [*GRAPHCAL, "calibrate", str(big), "--out", "OUT"],
        "import": [*GRAPHCAL, "import", str(streams / "manifest.toml"), "--out", "OUT/log.csv"],
        "fleet": [*GRAPHCAL, "fleet", str(fleet), "--out", "OUT", "--workers", "2"],
        "simulate": [*GRAPHCAL, "simulate", "--length-km", "30", "--out", "OUT/drive.csv"],
    }


def _half_written(out: Path) -> list[str]:
    """Files an interrupted command left that a user could take for a result."""
    if not out.exists():
        return []
    return sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())


def interrupt_once(command: list[str], out: Path, delay: float) -> list[str]:
    """Run ``command``, SIGINT its process group after ``delay`` [s]; what broke."""
    if out.exists():
        shutil.rmtree(out)
    if any("OUT/" in part for part in command):
        out.mkdir(parents=True)
    argv = [part.replace("OUT", str(out)) for part in command]
    process = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, text=True
    )
    try:
        process.wait(timeout=delay)
        return []  # finished before the interrupt: nothing to check
    except subprocess.TimeoutExpired:
        pass
    sent = time.perf_counter()
    os.killpg(process.pid, signal.SIGINT)
    try:
        _, stderr = process.communicate(timeout=5.0)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
        return ["no exit within 5 s"]
    took = time.perf_counter() - sent
    broken = []
    if process.returncode == 0:
        return []  # it finished between the last check and the signal
    if process.returncode != 130:
        broken.append(f"exit {process.returncode}")
    lines = [ln for ln in stderr.splitlines() if ln.strip() and not ln.startswith("[")]
    if "Traceback" in stderr or "Exception" in stderr:
        broken.append("traceback: " + stderr.strip().splitlines()[-1][:200])
    if lines and not lines[-1].startswith("graphcal: interrupted"):
        broken.append(f"last line {lines[-1][:120]!r}")
    left = _half_written(out)
    if "fleet" in command:  # a fleet keeps the logs it finished (it resumes): no temp files
        left = [f for f in left if ".tmp" in f or f.startswith(".")]
    if process.returncode == 130 and left:
        broken.append(f"left {left[:3]}")
    if took > 5.0:
        broken.append(f"{took:.1f} s to exit")
    return broken


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=200, help="interrupts (200)")
    parser.add_argument("--seed", type=int, default=0, help="random delays' seed (0)")
    parser.add_argument("--max-delay", type=float, default=12.0, help="longest delay [s] (12)")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    work = Path(tempfile.mkdtemp(prefix="graphcal-interrupts-"))
    try:
        commands = _prepare(work)
        names = sorted(commands)
        counts = {name: [0, 0] for name in names}
        stop = time.time() + 24 * 3600
        loops = [multiprocessing.Process(target=_busy, args=(stop,)) for _ in range(2)]
        for loop in loops:
            loop.start()
        try:
            for i in range(args.n):
                name = names[int(rng.integers(len(names)))]
                delay = float(rng.uniform(0.3, args.max_delay))
                broken = interrupt_once(commands[name], work / "out", delay)
                counts[name][0] += 1
                if broken:
                    counts[name][1] += 1
                    print(f"{i}: {name} at {delay:.2f} s: {'; '.join(broken)}", flush=True)
        finally:
            for loop in loops:
                loop.terminate()
        print("| command | interrupts | broken |\n|---|---|---|")
        for name in names:
            print(f"| {name} | {counts[name][0]} | {counts[name][1]} |")
        return int(any(b for _, b in counts.values()))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
