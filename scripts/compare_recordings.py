"""Time ``graphcal calibrate`` (defaults) on each recording of benchmark item (n) under two
source trees, one after the other for each recording, and print a markdown table.

    git worktree add /tmp/before <commit>
    python scripts/compare_recordings.py --before /tmp/before --after . [--extra drive.csv]

Each run is a child process with ``PYTHONPATH`` on its tree (the recordings are this tree's
``data/``): wall time, exit status, peak memory and the whole-log solves' iterations
(:func:`graphcal.bench.recordings.calibrate_recording`).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from graphcal.bench.recordings import RECORDINGS, calibrate_recording


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True, help="source tree of before")
    parser.add_argument("--after", type=Path, required=True, help="source tree of after")
    parser.add_argument("--extra", nargs="*", default=[], help="more drive-log CSVs")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    recordings = [*RECORDINGS, *((Path(x).name, (str(Path(x).resolve()),)) for x in args.extra)]
    print("| recording | version | wall time | exit | peak | whole-log solves (iterations) |")
    print("|---|---|---|---|---|---|")
    for name, arguments in recordings:
        for version, tree in (("before", args.before), ("after", args.after)):
            os.environ["PYTHONPATH"] = str(tree.resolve())
            run = calibrate_recording(arguments, args.workers)
            print(
                f"| {name} | {version} | {run['seconds']:.1f} s | {run['returncode']} | "
                f"{run['peak_mb']:.0f} MB | {run['iterations']} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
