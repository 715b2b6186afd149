"""A real differential-drive robot in the form its owner has: OptiOdom's runs (motion capture
at 20 Hz, wheel encoders of 2796.8 ticks per revolution) as streams of runs recorded one after
another, with the gaps between them, written to ``data/real/optiodom/``.

    python scripts/real/optiodom.py DATA_DIFF --out data/real/optiodom

``DATA_DIFF`` is ``data/diff`` of https://github.com/sousarbarb/optiodom (MIT, © 2021 Ricardo
B. Sousa; R. B. Sousa, M. R. Petry, P. G. Costa, A. P. Moreira, "OptiOdom: a Generic Approach
for Odometry Calibration of Wheeled Mobile Robots", J Intell Robot Syst 105, 39, 2022). Each
run file there holds, every 50 ms, the robot's pose from OptiTrack (x, y [m], heading [rad],
in a frame that starts at the run's first pose) and the ticks each encoder counted in that
cycle (right, left). The robot (its metadata): 0.084 m wheels, 0.2 m track, encoders of 64
counts per motor revolution behind a 43.7:1 gearbox.

Written:

* ``free/`` — the 7 runs of free driving (Jan 2021: 020120212354, 030120210001,
  030120210006; 4–16 m each, 86 m, turns on the spot): ``pose.csv`` (t, x, y, heading),
  ``wheels.csv`` (t, cumulative ticks of the left and right wheel), ``manifest.toml``; runs
  one after another with :data:`GAP_S` between them, where nothing is logged (the import masks
  the gaps) — what a user calibrates from.
* ``validation/`` — runs of other paths, kept apart for validation (Dec 2020): the 6 circular
  runs of 231220200121 and the 6 square runs of 231220200029, written the same way.
* ``runs.csv`` in each — every run's name, path and time span in the streams.
* ``README.md``, ``LICENSE-optiodom`` — attribution.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd

#: Seconds between two runs in the written streams (nothing logged there).
GAP_S = 10.0
#: Encoder counts per wheel revolution: 64 counts per motor revolution × the 43.7 gearbox.
TICKS_PER_REVOLUTION = 64 * 43.7
#: The runs of each part: experiment directories under DATA_DIFF, all their runs.
PARTS = {
    "free": ["free/020120212354", "free/030120210001", "free/030120210006"],
    "validation": ["circular/231220200121", "square/231220200029"],
}

MANIFEST = """# OptiOdom (MIT, (c) 2021 Ricardo B. Sousa): {what}, runs one after another with gaps.
# Made by scripts/real/optiodom.py
[pose]
file = "pose.csv"
time = "t"
x = "x"
y = "y"
heading = "heading"
heading_unit = "rad"
heading_convention = "enu"

[wheels]
file = "wheels.csv"
time = "t"
rear_left = "left"
rear_right = "right"
kind = "ticks"
ticks_per_revolution = {ticks}
"""


def runs_of(experiment: Path) -> list[Path]:
    """The run files of an experiment directory, in order."""
    return sorted(experiment.glob(f"{experiment.name}_run-[0-9][0-9].csv"))


def concatenated(runs: list[Path]) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """Pose and wheel streams of ``runs`` one after another, :data:`GAP_S` apart, and the
    runs' spans."""
    poses, wheels, spans = [], [], []
    start, left, right = 0.0, 0, 0
    for path in runs:
        t, x, y, heading, ticks_right, ticks_left = pd.read_csv(path, header=None).to_numpy().T
        t = start + t - t[0]
        poses.append(pd.DataFrame({"t": t, "x": x, "y": y, "heading": np.unwrap(heading)}))
        # ticks counted in the cycle ending at each row: the counter is their running sum
        cumulative_left = left + np.cumsum(ticks_left).astype(np.int64)
        cumulative_right = right + np.cumsum(ticks_right).astype(np.int64)
        wheels.append(pd.DataFrame({"t": t, "left": cumulative_left, "right": cumulative_right}))
        spans.append({"run": path.stem, "path": path.parent.parent.name, "t0": t[0], "t1": t[-1]})
        left, right = int(cumulative_left[-1]), int(cumulative_right[-1])
        start = t[-1] + GAP_S
    return pd.concat(poses), pd.concat(wheels), pd.DataFrame(spans)


def write_part(data: Path, experiments: list[str], out: Path, what: str) -> int:
    """One part's streams, manifest and run list; returns the number of runs."""
    runs = [run for experiment in experiments for run in runs_of(data / experiment)]
    pose, wheels, spans = concatenated(runs)
    out.mkdir(parents=True, exist_ok=True)
    pose.to_csv(out / "pose.csv", index=False, float_format="%.5f")
    wheels.to_csv(out / "wheels.csv", index=False, float_format="%.2f")
    spans.to_csv(out / "runs.csv", index=False, float_format="%.2f")
    (out / "manifest.toml").write_text(MANIFEST.format(what=what, ticks=TICKS_PER_REVOLUTION))
    return len(runs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="OptiOdom's data/diff directory")
    parser.add_argument("--out", type=Path, default=Path("data/real/optiodom"))
    parser.add_argument("--license", type=Path, help="OptiOdom's LICENSE")
    args = parser.parse_args(argv)
    free = write_part(args.data, PARTS["free"], args.out / "free", "free runs")
    kept = write_part(args.data, PARTS["validation"], args.out / "validation", "circle and square")
    if args.license is not None:
        shutil.copyfile(args.license, args.out / "LICENSE-optiodom")
    print(f"{args.out}: {free} free runs, {kept} validation runs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
