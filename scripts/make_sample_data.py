"""Regenerate the shipped sample drive: ``data/sample_drive.csv``, its truth and its sidecar.

    python scripts/make_sample_data.py

A 4 km synthetic city drive at the paper's noise levels (seed 3); deterministic, so running it
again reproduces the committed files byte for byte.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from graphcal.simulate.drive import simulate_drive, write_synthetic_drive

SAMPLE = Path(__file__).resolve().parent.parent / "data" / "sample_drive.csv"


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args(argv)
    drive = simulate_drive(length_km=4.0, seed=3)
    for path in write_synthetic_drive(drive, SAMPLE):
        print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
