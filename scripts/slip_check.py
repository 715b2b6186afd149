"""Slow wheel slip of the model's own kind on a drive log, and what graphcal makes of it.

Each draw scales the wheel rotations ``n_rl``, ``n_rr`` of a drive-log CSV by ``1 + m``,
``m`` a Gauss–Markov process (``--sigma``, ``--time``; the defaults are ``[joint]
unseen_slip_sigma`` and ``unseen_slip_time``) less its distance-weighted mean over the drive,
runs ``graphcal calibrate`` on it and prints c_e's error against ``--truth-ce`` with the σ
reported, and at the end the errors' RMS and mean (e/σ)² (docs/defects.md, "Checked against
slip of the model's own kind").

    python scripts/slip_check.py data/sample_drive.csv --truth-ce 1.985 --draws 30
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from graphcal.simulate.defect_effects import gauss_markov

#: The process is drawn on a grid this coarse [s] and interpolated: slip over minutes.
GRID_S = 1.0


def slip_process(t: np.ndarray, sigma: float, time: float, rng: np.random.Generator) -> np.ndarray:
    """A stationary Gauss–Markov process of ``sigma`` and correlation ``time`` [s] at ``t``
    (the simulator's, :func:`graphcal.simulate.defect_effects.gauss_markov`, on the coarse
    grid, interpolated)."""
    grid = np.arange(t[0], t[-1] + GRID_S, GRID_S)
    values = gauss_markov(len(grid), GRID_S, sigma, time, rng)[:, 0]
    return np.interp(t, grid, values)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("drive", type=Path, help="a drive-log CSV (t, px, py, psi, n_rl, n_rr, …)")
    parser.add_argument("--truth-ce", type=float, required=True, help="the drive's true c_e [m]")
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--sigma", type=float, default=0.002, help="relative σ of the slip")
    parser.add_argument("--time", type=float, default=120.0, help="its correlation time [s]")
    args = parser.parse_args(argv)
    base = pd.read_csv(args.drive)
    travel = 0.5 * (base.n_rl.abs() + base.n_rr.abs()).to_numpy()
    errors, sigmas = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for draw in range(args.draws):
            rng = np.random.default_rng([args.seed, draw])
            m = slip_process(base.t.to_numpy(), args.sigma, args.time, rng)
            m -= np.sum(travel * m) / np.sum(travel)
            drive = base.assign(n_rl=base.n_rl * (1 + m), n_rr=base.n_rr * (1 + m))
            path, out = Path(tmp) / f"drive_{draw}.csv", Path(tmp) / f"out_{draw}"
            drive.to_csv(path, index=False)
            command = [sys.executable, "-m", "graphcal.cli", "calibrate", str(path)]
            command += ["--out", str(out), "--workers", "1", "--batches", "0"]
            done = subprocess.run(command, capture_output=True, text=True)
            if done.returncode != 0:
                print(f"draw {draw}: exit {done.returncode}", flush=True)
                continue
            c_e = json.loads((out / "calibration.json").read_text())["parameters"]["c_e"]
            errors.append(1e3 * (c_e["value"] - args.truth_ce))
            sigmas.append(1e3 * c_e["sigma"])
            print(f"draw {draw}: c_e error {errors[-1]:+.3f} mm, σ {sigmas[-1]:.3f} mm", flush=True)
    e, s = np.array(errors), np.array(sigmas)
    print(
        f"{len(e)} draws: c_e error RMS {np.sqrt(np.mean(e**2)):.3f} mm, median σ "
        f"{np.median(s):.3f} mm, mean (e/σ)² {np.mean((e / s) ** 2):.2f}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
