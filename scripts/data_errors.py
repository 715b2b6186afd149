"""Gross data errors a user's log may hold, each made in a drive log and calibrated as a user
would (``graphcal calibrate``, defaults): what graphcal says, its exit status and how long
it took. A data error should be named in one line (exit 2) or undone (exit 0, the truth
recovered), never calibrated silently nor iterated on for long.

    python scripts/data_errors.py                  # the sample drive
    python scripts/data_errors.py LOG [--only NAME ...]

Prints one row per error: exit status, seconds, and the error line or the calibrated c_e,
c_d and validation error.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
ROWS_LATE_10_S = 400  # 10 s at the sample drive's 40 Hz


def _late(frame: pd.DataFrame, seconds: float) -> pd.DataFrame:
    """The wheels logged ``seconds`` late: row k holds the rotation of row k − lag, the rows
    before the first wheel sample cut."""
    dt = float(np.median(np.diff(frame["t"])))
    lag = round(seconds / dt)
    late = frame.copy()
    late[["n_rl", "n_rr"]] = np.roll(frame[["n_rl", "n_rr"]].to_numpy(), lag, axis=0)
    return late.iloc[lag:] if lag > 0 else late.iloc[:lag]


def errors(frame: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The drive-log table ``frame`` with one gross error each, by name."""
    n = len(frame)
    third = slice(n // 3, 2 * n // 3)
    middle = np.zeros(n, bool)
    middle[third] = True

    def with_(**columns) -> pd.DataFrame:
        return frame.assign(**columns)

    frozen = frame[["n_rl", "n_rr"]].to_numpy().copy()
    frozen[third] = frozen[n // 3]
    return {
        "heading flipped over the middle third": with_(
            psi=np.where(middle, frame["psi"] + np.pi, frame["psi"])
        ),
        "heading 29° off throughout": with_(psi=frame["psi"] + 0.5),
        "heading of the other sign": with_(psi=-frame["psi"]),
        "wheels swapped": with_(n_rl=frame["n_rr"], n_rr=frame["n_rl"]),
        "left wheel 1.5x": with_(n_rl=frame["n_rl"] * 1.5),
        "right wheel 0.9x": with_(n_rr=frame["n_rr"] * 0.9),
        "right wheel a copy of the left": with_(n_rr=frame["n_rl"]),
        "wheels frozen over the middle third": with_(n_rl=frozen[:, 0], n_rr=frozen[:, 1]),
        "wheels 10 s late": _late(frame, 10.0),
        "wheels 18 s early": _late(frame, -18.0),
        "px x1.3 (no cos(latitude))": with_(px=frame["px"] * 1.3),
        "px, py swapped": with_(px=frame["py"], py=frame["px"]),
        "positions 500 m off over the middle third": with_(
            px=np.where(middle, frame["px"] + 500.0, frame["px"])
        ),
        "ay of the other sign": with_(ay=-frame["ay"]),
    }


def calibrated(path: Path, out: Path) -> tuple[int, float, str]:
    """``graphcal calibrate path --out out``: exit status, seconds and what it said."""
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "graphcal.cli", "calibrate", str(path), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    seconds = time.perf_counter() - started
    if done.returncode == 2:
        return 2, seconds, done.stderr.strip().splitlines()[-1][:160]
    result = json.loads((out / "calibration.json").read_text())
    theta, errors = result["theta"], result["validation_error_m"]
    said = (
        f"c_e {theta['c_e']:.4f} m, c_d {theta['c_d'] * 1e3:.2f} mm; validation "
        f"{errors['nominal']:.2f} -> {errors['calibrated']:.2f} m"
    )
    return done.returncode, seconds, said


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", nargs="?", default=str(ROOT / "data" / "sample_drive.csv"))
    parser.add_argument("--only", nargs="*", help="the errors to make (by name)")
    args = parser.parse_args(argv)
    frame = pd.read_csv(args.log)
    print("| data error | exit | time | what graphcal said |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as directory:
        for k, (name, broken) in enumerate(errors(frame).items()):
            if args.only and name not in args.only:
                continue
            path = Path(directory) / f"error{k}.csv"
            broken.to_csv(path, index=False, float_format="%.17g")
            status, seconds, said = calibrated(path, Path(directory) / f"out{k}")
            print(f"| {name} | {status} | {seconds:.1f} s | {said} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
