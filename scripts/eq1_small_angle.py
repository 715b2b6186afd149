"""The paper's small-angle eq. (1) against graphcal's rigid-body form, on rigid-car drives.

    python scripts/eq1_small_angle.py [--length-km 24] [--seeds 0 1]

graphcal moves the centre of gravity by v / cos(beta) (``graphcal.model.sideslip_stretch``);
the paper writes v. On drives of ``graphcal.simulate.drive`` (a rigid car, its sideslip
logged) this calibrates each drive with ``--method whole`` twice — as graphcal does and with
the stretch set to 1 — and prints each parameter's error over the σ graphcal reports, and
c_e's error in mm (docs/method.md, "Eq. 1 for a rigid body").
"""

from __future__ import annotations

import argparse

import numpy as np

import graphcal.model as model
from graphcal.evaluation import Truth, evaluate
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.simulate.drive import simulate_drive


def errors_over_sigma(drive, small_angle: bool) -> tuple[np.ndarray, float]:
    """``(4,)`` error / σ of each parameter and c_e's error [m] of one whole-log solve."""
    rigid = model.sideslip_stretch
    if small_angle:
        model.sideslip_stretch = lambda inputs: np.ones(np.shape(inputs)[:-1])
    try:
        run = run_calibration(drive.measured, method="whole", workers=1)
    finally:
        model.sideslip_stretch = rigid
    error = evaluate(run, Truth(drive.theta_true)).theta_error
    return error / np.sqrt(np.diag(run.covariance)), float(error[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=24.0, help="drive length [km]")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="drive seeds")
    args = parser.parse_args()
    print("| seed | eq. (1) | c_e e/σ | c_d e/σ | t_r e/σ | d e/σ | c_e error [mm] |")
    print("|---|---|---|---|---|---|---|")
    for seed in args.seeds:
        drive = simulate_drive(args.length_km, seed)
        for label, small in (("rigid body (graphcal)", False), ("small angle (paper)", True)):
            z, c_e = errors_over_sigma(drive, small)
            cells = " | ".join(f"{v:+.1f}" for v in z)
            print(f"| {seed} | {label} | {cells} | {1e3 * c_e:+.3f} |", flush=True)


if __name__ == "__main__":
    main()
