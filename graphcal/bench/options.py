"""Options of the benchmark, shared by ``graphcal bench`` and ``scripts/bench.py``.

Two presets: the full benchmark (the default, what ``docs/performance.md`` quotes) and
``--quick``, a fast check of every item, each once, on a shorter drive and recording (2.2 min
on the 2-core machine while another job shared it); options given explicitly override
either.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from graphcal.arguments import at_least, whole

#: Each size of the two presets, side by side: ``(full benchmark, --quick)``.
PRESET_SIZES = {
    "length_km": (24.0, 8.0),
    "repeats": (3, 1),
    "naive_iterations": (2, 1),
    "pipeline_batches": (20, 4),
    "agreement_segments": (3, 2),
    "import_hours": (3.0, 0.25),
    "scaling_km": ((50.0, 100.0, 200.0), (4.0, 8.0, 16.0)),
    "fleet_vehicles": (6, 2),
}
#: The full benchmark's sizes.
FULL = {name: full for name, (full, _) in PRESET_SIZES.items()}
#: ``--quick``: every item once, on an 8 km drive, with a short recording.
QUICK = {name: quick for name, (_, quick) in PRESET_SIZES.items()}


def add_bench_arguments(parser: argparse.ArgumentParser) -> None:
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
        "--workers", type=whole(1), default=2, help="workers for the pipeline item (2)"
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
    parser.add_argument("--out", type=Path, default=Path("bench.json"), help="JSON report path")


def resolve_bench_options(args: argparse.Namespace) -> dict[str, Any]:
    """The sizes the benchmark runs with: those given, the rest from the preset
    (:data:`QUICK` with ``--quick``, else :data:`FULL`)."""
    preset = QUICK if getattr(args, "quick", False) else FULL
    given = {name: getattr(args, name, None) for name in preset}
    return {name: preset[name] if value is None else value for name, value in given.items()}
