"""Options of the benchmark, shared by ``graphcal bench`` and ``scripts/bench.py``."""

from __future__ import annotations

import argparse
from pathlib import Path

from graphcal.arguments import at_least, whole


def add_bench_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the benchmark's options to ``parser``."""
    parser.add_argument(
        "--length-km", type=at_least(1.0, "km"), default=24.0, help="synthetic drive [km] (24)"
    )
    parser.add_argument("--repeats", type=whole(1), default=3, help="repeats per item (median; 3)")
    parser.add_argument(
        "--workers", type=whole(1), default=2, help="workers for the pipeline item (2)"
    )
    parser.add_argument(
        "--naive-iterations",
        type=whole(1),
        default=2,
        help="LM iterations of the naive formulation to time (2)",
    )
    parser.add_argument(
        "--pipeline-batches", type=whole(1), default=20, help="batches of the pipeline items (20)"
    )
    parser.add_argument(
        "--agreement-segments",
        type=whole(1),
        default=3,
        help="whole segments of the (a)-vs-(b) agreement problem (3)",
    )
    parser.add_argument(
        "--import-hours",
        type=at_least(0.0, "h"),
        default=3.0,
        help="duration of the recording of the import item (h) [h] (3; 0 skips it)",
    )
    parser.add_argument(
        "--only-import",
        action="store_true",
        help="run only the import item (h) (a quick check of the recording import)",
    )
    parser.add_argument("--out", type=Path, default=Path("bench.json"), help="JSON report path")
