"""Benchmark graphcal's solves next to the naive GTSAM formulation (as ``graphcal bench``).

    python scripts/bench.py [--length-km 24] [--repeats 3] [--workers 2] [--out bench.json]
    python scripts/bench.py --quick      # every item once on an 8 km drive: a fast check

See :mod:`graphcal.bench.run` for the items. Prints a table and writes ``bench.json``.
"""

from __future__ import annotations

import argparse
import sys

from graphcal.bench.run import run_bench, write_bench_report
from graphcal.cli.bench import add_arguments


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    write_bench_report(run_bench(args, progress=print), args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
