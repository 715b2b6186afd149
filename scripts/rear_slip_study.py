"""The rear slip gain and the lever arm of simulated drives logged without their sideslip.

The simulator's antenna sits at the centre of gravity, ``l_r`` ahead of the rear axle, whose
tyres slip at ``−g · a_y``. With the sideslip removed from the log graphcal measures the arm
from the rear axle and estimates ``g``; this prints each drive's arm and gain with their
error to the truth in σ (docs/defects.md, "The rear tyres' slip").

    python scripts/rear_slip_study.py --seeds 1 2 3 4 5 6 --length-km 4
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

import graphcal
from graphcal.pipeline.configuration.settings import BatchingSettings, Settings
from graphcal.simulate.drive import VehicleMotion, simulate_drive


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6])
    parser.add_argument("--length-km", type=float, default=4.0)
    args = parser.parse_args()
    motion = VehicleMotion()
    settings = Settings(batches=BatchingSettings(count=0))
    print("| seed | antenna ahead of the rear axle [m] | e/σ | g [mrad per m/s²] | e/σ |")
    print("|---|---|---|---|---|")
    for seed in args.seeds:
        log = simulate_drive(length_km=args.length_km, seed=seed).measured
        log = dataclasses.replace(log, beta=np.zeros_like(log.beta))
        found = graphcal.run_calibration(log, settings, workers=1).estimated
        arm, gain = found["lever_arm_longitudinal"], found.get("rear_slip_gain")
        arm_error = (arm.value - motion.rear_axle_to_cg) / arm.sigma
        row = f"| {seed} | {arm.value:+.3f} ± {arm.sigma:.3f} | {arm_error:+.1f} |"
        if gain is None:
            print(f"{row} not estimated | — |")
            continue
        gain_error = (gain.value - motion.rear_slip_gain) / gain.sigma
        print(f"{row} {gain.value * 1e3:.2f} ± {gain.sigma * 1e3:.2f} | {gain_error:+.1f} |")


if __name__ == "__main__":
    main()
