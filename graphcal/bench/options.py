"""Sizes of the benchmark, from the options of ``graphcal bench`` and ``scripts/bench.py``
(:func:`graphcal.cli.bench.add_arguments`).

Two presets: the full benchmark (the default, what ``docs/performance.md`` quotes) and
``--quick``, a fast check of every item, each once, on a shorter drive and recording (2.2 min
on the 2-core machine while another job shared it); options given explicitly override
either.
"""

from __future__ import annotations

import argparse
from typing import Any

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


def resolve_bench_options(args: argparse.Namespace) -> dict[str, Any]:
    """The sizes the benchmark runs with: those given, the rest from the preset
    (:data:`QUICK` with ``--quick``, else :data:`FULL`)."""
    preset = QUICK if getattr(args, "quick", False) else FULL
    given = {name: getattr(args, name, None) for name in preset}
    return {name: preset[name] if value is None else value for name, value in given.items()}
