"""Issue 27's acceptance: a simulated differential-drive robot calibrated with only its
vehicle profile, as a user would run it.

For each seed: ``graphcal simulate --vehicle data/vehicles/mocap_robot.toml --streams DIR``
(10 runs of 5–15 m with spins on the spot, 50 Hz motion capture at 1 mm / 0.2°, 2797-tick
encoders; optionally with reversing or as a ROS 2 bag), then ``graphcal calibrate`` of the
manifest (or the bag) with ``--vehicle`` and nothing else. Reports, per run, the exit status,
trust, each parameter's error over its σ, and t_r's σ.

    python scripts/robot_study.py --seeds 0 1 2 --markdown table.md
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PROFILE = ROOT / "data" / "vehicles" / "mocap_robot.toml"
NAMES = ("c_e", "c_d", "t_r", "d")


def _graphcal(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "graphcal.cli", *args], capture_output=True, text=True
    )


def run_case(seed: int, shape: str, directory: Path) -> dict:
    """Simulate and calibrate one robot recording; ``shape`` is streams, reversing or bag."""
    streams = directory / f"{shape}_{seed}"
    simulate = ["simulate", "--vehicle", str(PROFILE), "--seed", str(seed)]
    simulate += ["--streams", str(streams)]
    if shape == "bag":
        simulate += ["--bag", "ros2"]
    if shape == "reversing":
        simulate += ["--reversing"]
    made = _graphcal(*simulate)
    if made.returncode != 0:
        raise RuntimeError(made.stderr)
    source = streams / "drive_ros2" if shape == "bag" else streams / "manifest.toml"
    out = directory / f"out_{shape}_{seed}"
    calibrated = _graphcal("calibrate", str(source), "--vehicle", str(PROFILE), "--out", str(out))
    row = {"seed": seed, "shape": shape, "exit": calibrated.returncode}
    if calibrated.returncode not in (0, 3):
        row["error"] = calibrated.stderr.strip().splitlines()[-1]
        return row
    result = json.loads((out / "calibration.json").read_text())
    truth = json.loads((streams / "truth.json").read_text())["theta_true"]
    row["trusted"] = result["trust"]["trusted"]
    for name in NAMES:
        entry = result["parameters"][name]
        row[f"{name}_verdict"] = entry["status"]
        row[f"{name}_sigma"] = entry["sigma"]
        row[f"{name}_error"] = result["theta"][name] - truth[name]
    return row


def markdown(rows: list[dict]) -> str:
    """The rows as a table in display units (mm; d in mm·s²/m)."""
    lines = [
        "| seed | recording | exit | trusted | c_e e/σ | c_d e/σ | t_r e/σ | σ t_r [mm] | d |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        if "error" in row:
            lines.append(f"| {row['seed']} | {row['shape']} | {row['exit']} | {row['error']} |")
            continue
        ratios = [row[f"{n}_error"] / row[f"{n}_sigma"] for n in NAMES[:3]]
        lines.append(
            f"| {row['seed']} | {row['shape']} | {row['exit']} | {row['trusted']} | "
            + " | ".join(f"{r:+.2f}" for r in ratios)
            + f" | {row['t_r_sigma'] * 1e3:.3f} | {row['d_verdict'].split(':')[0]} |"
        )
    return "\n".join(lines) + "\n"


def verdict(rows: list[dict]) -> str:
    """The acceptance: every run exit 0 and trusted, c_e, c_d, t_r within 3σ, σ t_r ≤ 1 mm."""
    bad = []
    for row in rows:
        name = f"{row['shape']} seed {row['seed']}"
        if "error" in row or row["exit"] != 0 or not row["trusted"]:
            bad.append(f"{name}: exit {row['exit']}")
            continue
        for n in NAMES[:3]:
            if abs(row[f"{n}_error"]) > 3 * row[f"{n}_sigma"]:
                bad.append(f"{name}: {n} {row[f'{n}_error'] / row[f'{n}_sigma']:+.2f}σ")
        if row["t_r_sigma"] > 1e-3:
            bad.append(f"{name}: σ t_r {row['t_r_sigma'] * 1e3:.2f} mm")
    return "PASS" if not bad else "FAIL: " + "; ".join(bad)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument(
        "--shapes",
        nargs="+",
        default=["streams", "reversing", "bag"],
        choices=["streams", "reversing", "bag"],
    )
    parser.add_argument("--json", type=Path, default=None, help="write the rows as JSON")
    parser.add_argument("--markdown", type=Path, default=None, help="write the table")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as directory:
        rows = [
            run_case(seed, shape, Path(directory)) for shape in args.shapes for seed in args.seeds
        ]
    table = markdown(rows) + f"\nAcceptance: **{verdict(rows)}**\n"
    print(table)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=float))
    if args.markdown:
        args.markdown.write_text(table)
    return 0 if verdict(rows) == "PASS" else 1


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
