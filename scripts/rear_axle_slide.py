"""How rigid graphcal's simulated car is: the rear axle's sideways velocity.

    python scripts/rear_axle_slide.py [--length-km 12] [--seeds 0 1 2] [--stiffness 160000 inf]

A rigid car's rear axle moves along the heading (a kinematic car: no sideways velocity) or
slips by its tyres' slip angle, proportional to the lateral acceleration (the lateral force
over the rear cornering stiffness). This script measures, on the noise-free truth of
``graphcal.simulate.drive``, the rear axle's velocity across the heading (l_r = 1.35 m
behind the centre of gravity) and its angle to the heading: its RMS and maximum, and its
correlation with the lateral acceleration (a tyre slip) and with the rate of change of the
curvature (a geometric artefact, what the simulator before issue 36 had: 0.061-0.063 m/s
RMS at k = 0). With an infinite stiffness (``inf``) a rigid kinematic car has none. Why it
matters: without a logged heading or sideslip, graphcal models the pose as a rigid body (a
lever arm ahead of a reference that moves along the heading, ``docs/recordings.md``), which
cannot follow a sliding rear axle.
"""

from __future__ import annotations

import argparse

import numpy as np

from graphcal.simulate.drive import VehicleMotion, simulate_drive


def rear_axle_slide(length_km: float, seed: int, stiffness: float) -> dict[str, float]:
    """Statistics of the rear axle's sideways motion in the noise-free simulated drive."""
    motion = VehicleMotion(rear_cornering_stiffness=stiffness)
    truth = simulate_drive(length_km, seed, motion=motion).truth
    l_r = motion.rear_axle_to_cg
    rear = np.column_stack([truth.px - l_r * np.cos(truth.psi), truth.py - l_r * np.sin(truth.psi)])
    velocity = np.gradient(rear, truth.t, axis=0)
    across = -velocity[:, 0] * np.sin(truth.psi) + velocity[:, 1] * np.cos(truth.psi)
    along = velocity[:, 0] * np.cos(truth.psi) + velocity[:, 1] * np.sin(truth.psi)
    moving = along > 1.0
    angle = across[moving] / along[moving]
    curvature_rate = np.gradient(np.gradient(truth.psi, truth.t) / np.maximum(along, 1.0), truth.t)
    return {
        "rms_m_s": float(np.sqrt(np.mean(across**2))),
        "max_m_s": float(np.max(np.abs(across))),
        "angle_rms_deg": float(np.degrees(np.sqrt(np.mean(angle**2)))),
        "corr_lateral_acceleration": float(np.corrcoef(angle, truth.ay[moving])[0, 1]),
        "corr_curvature_rate": float(np.corrcoef(across, curvature_rate)[0, 1]),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--length-km", type=float, default=12.0, help="route length [km]")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="drive seeds")
    parser.add_argument(
        "--stiffness",
        type=float,
        nargs="+",
        default=[VehicleMotion().rear_cornering_stiffness, float("inf")],
        help="rear cornering stiffnesses [N/rad] (inf: kinematic)",
    )
    args = parser.parse_args()
    print(
        "| rear stiffness [kN/rad] | seed | sideways velocity RMS / max [mm/s] "
        "| slip angle RMS [°] | corr. with a_y | corr. with dκ/dt |"
    )
    print("|---|---|---|---|---|---|")
    for stiffness in args.stiffness:
        for seed in args.seeds:
            s = rear_axle_slide(args.length_km, seed, stiffness)
            print(
                f"| {stiffness / 1e3:g} | {seed} "
                f"| {1e3 * s['rms_m_s']:.2f} / {1e3 * s['max_m_s']:.1f} "
                f"| {s['angle_rms_deg']:.2f} | {s['corr_lateral_acceleration']:+.2f} "
                f"| {s['corr_curvature_rate']:+.2f} |"
            )


if __name__ == "__main__":
    main()
