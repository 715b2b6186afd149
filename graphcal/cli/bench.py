"""``graphcal bench``: time graphcal's solves next to the naive per-step GTSAM formulation.

Its options are shared with ``scripts/bench.py``; their sizes default to a preset of
:mod:`graphcal.bench.options`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from graphcal import GraphcalError
from graphcal.cli.arguments import at_least, whole

NAME = "bench"
HELP = "benchmark against the naive GTSAM formulation"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the benchmark's options to ``parser`` (sizes default to the chosen preset)."""
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a fast check: every item once on an 8 km drive (the sizes of bench.options.QUICK)",
    )
    parser.add_argument(
        "--length-km", type=at_least(1.0, "km"), default=None, help="synthetic drive [km] (24)"
    )
    parser.add_argument(
        "--repeats", type=whole(1), default=None, help="repeats per item (median; 3)"
    )
    parser.add_argument(
        "--workers",
        type=whole(1),
        default=2,
        help="worker processes of the items that use them (2, not one per core as calibrate: "
        "the benchmark's figures are for a fixed count, to compare across machines)",
    )
    parser.add_argument(
        "--naive-iterations",
        type=whole(1),
        default=None,
        help="LM iterations of the naive formulation to time (2)",
    )
    parser.add_argument(
        "--pipeline-batches", type=whole(1), default=None, help="batches of the pipeline items (20)"
    )
    parser.add_argument(
        "--agreement-segments",
        type=whole(1),
        default=None,
        help="whole segments of the (a)-vs-(b) agreement problem (3)",
    )
    parser.add_argument(
        "--import-hours",
        type=at_least(0.0, "h"),
        default=None,
        help="duration of the recording of the import item (h) [h] (3; 0 skips it)",
    )
    parser.add_argument(
        "--scaling-km",
        type=at_least(1.0, "km"),
        nargs="*",
        default=None,
        help="drive lengths [km] of the whole-log scaling item (k) (50 100 200; none skips it)",
    )
    parser.add_argument(
        "--fleet-vehicles",
        type=whole(0),
        default=None,
        help="vehicles (× 2 days of 4 km) of the fleet throughput item (m) (6; 0 skips it)",
    )
    parser.add_argument(
        "--only-import",
        action="store_true",
        help="run only the import item (h) (a quick check of the recording import)",
    )
    parser.add_argument(
        "--only-recordings",
        action="store_true",
        help="run only item (n): calibrate with defaults each recording of the suite and the "
        "simulated shapes of issue 45 (wall time, solves, iterations per solve)",
    )
    parser.add_argument("--out", type=Path, default=Path("bench.json"), help="JSON report path")


def run(args: argparse.Namespace) -> int:
    """Time graphcal's solves next to the naive per-step GTSAM formulation; write JSON."""
    from graphcal import run_bench, write_bench_report

    report = run_bench(args, progress=print)
    if "naive_over_graphcal_per_iteration" in report:
        print(f"(a)/(b) per iteration: {report['naive_over_graphcal_per_iteration']:.0f}x")
    elif "import" in report:
        print(f"(h) import: {report['import']}")
    try:
        write_bench_report(report, args.out)
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    print(f"wrote {args.out}")
    return 0
