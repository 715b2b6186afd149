"""Sizes of the benchmark, from the options of ``graphcal bench`` and ``scripts/bench.py``
(:func:`graphcal.cli.bench.add_arguments`).

Two presets: the full benchmark (the default, what ``docs/performance.md`` quotes) and
``--quick``, a fast check of every item, each once, on a shorter drive and recording (2.2 min
on the 2-core machine while another job shared it); options given explicitly override
either.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
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


@dataclass(frozen=True)
class BenchSizes:
    """The sizes of a benchmark run (defaults: the full benchmark's, :data:`FULL`, without
    its scaling and fleet items, which take long).

    Attributes:
        length_km: the synthetic drive the solves run on [km].
        repeats: timings per item (the fastest counts).
        naive_iterations: iterations of the naive one-factor-per-step graph.
        pipeline_batches: batches of the batch method's run.
        agreement_segments: segments on which the factors' answers are compared.
        import_hours: the recording the import items read [h].
        scaling_km: drive lengths of the whole-log scaling item [km] (empty: none).
        fleet_vehicles: vehicles of the fleet item (0: none).
    """

    length_km: float = FULL["length_km"]
    repeats: int = FULL["repeats"]
    naive_iterations: int = FULL["naive_iterations"]
    pipeline_batches: int = FULL["pipeline_batches"]
    agreement_segments: int = FULL["agreement_segments"]
    import_hours: float = FULL["import_hours"]
    scaling_km: tuple[float, ...] = ()
    fleet_vehicles: int = 0


def resolve_bench_options(args: argparse.Namespace) -> dict[str, Any]:
    """The sizes the benchmark runs with: those given, the rest from the preset
    (:data:`QUICK` with ``--quick``, else :data:`FULL`)."""
    preset = QUICK if getattr(args, "quick", False) else FULL
    given = {name: getattr(args, name, None) for name in preset}
    return {name: preset[name] if value is None else value for name, value in given.items()}
