"""Benchmark graphcal against the naive GTSAM formulation (same as ``graphcal bench``).

    python scripts/bench.py [--length-km 24] [--repeats 3] [--workers 2] [--out bench.json]

See :mod:`graphcal.bench.run` for the items. Prints a table and writes ``bench.json``.
"""

from __future__ import annotations

import sys

from graphcal.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
