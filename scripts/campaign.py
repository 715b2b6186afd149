"""The randomized campaign over recording shapes (issue 43): N shapes drawn by hypothesis,
each recorded by the independent twin and calibrated with ``graphcal calibrate``.

    python scripts/campaign.py --n 30 --seed 0 --jobs 1 --car-km 1 3
    python scripts/campaign.py --n 200 --seed 43 --only 194 --recording-seeds 16

Per shape: the exit status, each parameter's verdict and error / σ against the truth, and
the invariants it broke (``tests/campaign/invariants.py``: exit 0 or one line naming a real
cause, never a traceback; no segment across a gap or a run boundary; the tick resolution the
one drawn, none on continuous signals; calibrated parameters within 3σ; a parameter left
out says why). At the end: the shapes that broke one, and the mean (e/σ)² per parameter
over the runs that calibrated it (1 when the σ are honest).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import shutil
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from campaign.invariants import MAX_SIGMAS, NAMES, Calibrated, calibrate, data_path_broken
from campaign.recording import write_recording
from campaign.shape import Shape, drawn_from_the_seed_alone, shapes


def draw_shapes(
    n: int, seed: int, car_km: tuple[float, float], robot_m: tuple[float, float]
) -> list[Shape]:
    """``n`` shapes of distinct recording seeds drawn by hypothesis from ``seed`` (the same
    list for a seed, whatever the code around it or how this file was started)."""
    from hypothesis import HealthCheck, Phase, given, settings
    from hypothesis import seed as hypothesis_seed

    drawn: list[Shape] = []
    seeds: set[int] = set()
    seen: set[Shape] = set()
    strategy = shapes(car_length_m=(car_km[0] * 1e3, car_km[1] * 1e3), robot_length_m=robot_m)

    @hypothesis_seed(seed)
    @settings(
        max_examples=20 * n, phases=[Phase.generate], database=None, deadline=None,
        suppress_health_check=list(HealthCheck),
    )  # fmt: skip
    @given(strategy)
    def collect(shape: Shape) -> None:
        # hypothesis mutates what it drew (one axis moved): keep one per seed and per axes
        axes = dataclasses.replace(shape, seed=0)
        if len(drawn) < n and shape.seed not in seeds and axes not in seen:
            drawn.append(shape)
            seeds.add(shape.seed)
            seen.add(axes)

    with drawn_from_the_seed_alone():
        collect()
    return drawn


def _verdict(status: str) -> str:
    """A verdict, short: "" calibrated, "given X", "n/o" (not observable), "weak" (weakly
    determined), "fixed", "NT" (not trusted)."""
    status = status.removeprefix("not calibrated: ")
    if status.startswith("calibrated given"):
        return "given " + status.split("given", 1)[1].split("=")[0].strip()
    for prefix, short in (("calibrated", ""), ("not observable", "n/o"), ("weakly", "weak"),
                          ("fixed", "fixed"), ("not trusted", "NT")):  # fmt: skip
        if status.startswith(prefix):
            return short
    return status[:20]


def _cell(result: Calibrated, name: str) -> str:
    if name not in result.verdicts:
        return "—"
    short = _verdict(result.verdicts[name])
    if name in result.ratio:
        value = f"{result.ratio[name]:+.1f}"
        return f"{value} ({short})" if short else value
    return short


def table(rows: list[tuple[Shape, Calibrated, list[str]]], numbers: list[int] | None = None) -> str:
    """The campaign's table and summary (markdown); ``numbers``: each row's index in the
    draw (default: 0, 1, …)."""
    numbers = list(range(len(rows))) if numbers is None else numbers
    lines = [
        "| # | shape | exit | " + " | ".join(f"{n} e/σ" for n in NAMES) + " | broken | s |",
        "|---|---|---|" + "---|" * len(NAMES) + "---|---|",
    ]
    for i, (shape, result, broken) in zip(numbers, rows, strict=True):
        cells = " | ".join(_cell(result, n) for n in NAMES)
        lines.append(
            f"| {i} | {shape.label()} | {result.exit_code} | {cells} | "
            f"{'; '.join(broken) or '—'} | {result.seconds:.0f} |"
        )
    failing = sum(bool(b) for _, _, b in rows)
    lines += ["", f"shapes breaking an invariant: {failing}/{len(rows)}"]
    for name in NAMES:
        r = np.array([res.ratio[name] for _, res, _ in rows if name in res.ratio])
        if len(r):
            lines.append(
                f"- {name}: mean (e/σ)² {np.mean(r**2):.2f} over {len(r)} calibrated runs, "
                f"worst |e/σ| {np.max(np.abs(r)):.1f}"
            )
        else:
            lines.append(f"- {name}: calibrated in no run")
    ratios = [r for _, res, _ in rows for r in res.ratio.values()]
    lines.append(beyond_line(ratios))
    return "\n".join(lines)


def beyond_line(ratios: list[float]) -> str:
    """How many calibrated values lie beyond :data:`MAX_SIGMAS` σ of the truth, beside what
    honest normal errors give: each with chance ``p = P(|z| > MAX_SIGMAS)``, so ``M p`` of M
    expected, and the binomial chance of at least as many."""
    count = len(ratios)
    beyond = sum(abs(r) > MAX_SIGMAS for r in ratios)
    p = math.erfc(MAX_SIGMAS / math.sqrt(2.0))
    tail = 1.0 - sum(math.comb(count, k) * p**k * (1 - p) ** (count - k) for k in range(beyond))
    return (
        f"- beyond {MAX_SIGMAS:g}σ: {beyond} of {count} calibrated values; normal errors with "
        f"the σ reported put {count * p:.1f} there, and {beyond} or more with chance "
        f"{max(tail, 0.0):.2g}"
    )


def run_shape(shape: Shape, directory: Path, timeout: float) -> tuple[Shape, Calibrated, list[str]]:
    """Record, check the data path, calibrate: the shape, its calibration, what it broke."""
    manifest = write_recording(shape, directory)
    (directory / "shape.txt").write_text(f"{shape!r}\n")  # to keep it as an example test
    data_path = data_path_broken(shape, manifest)
    result = calibrate(shape, manifest, timeout=timeout)
    broken = list(dict.fromkeys([*data_path, *result.broken]))
    print(
        f"{shape.label()}: exit {result.exit_code} ({result.seconds:.0f} s)"
        + (f"; BROKEN: {'; '.join(broken)}" if broken else ""),
        file=sys.stderr,
        flush=True,
    )
    return shape, result, broken


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--n", type=int, default=20, help="shapes to draw (20)")
    parser.add_argument("--seed", type=int, default=0, help="hypothesis seed (0)")
    parser.add_argument("--jobs", type=int, default=1, help="calibrations at once (1)")
    parser.add_argument(
        "--car-km", type=float, nargs=2, default=(1.0, 3.0), help="car drive lengths [km]"
    )
    parser.add_argument(
        "--robot-m", type=float, nargs=2, default=(100.0, 250.0), help="robot drives [m]"
    )
    parser.add_argument(
        "--timeout", type=float, default=300.0, help="longest calibration [s] (300; broken after)"
    )
    parser.add_argument("--keep", type=Path, help="write the recordings and results here")
    parser.add_argument(
        "--only",
        type=int,
        nargs="+",
        metavar="INDEX",
        help="run only these shapes of the draw (0-based, as the table numbers them)",
    )
    parser.add_argument(
        "--recording-seeds",
        type=int,
        metavar="N",
        help="record each shape N times, with recording seeds 0 … N−1 (its noise drawn anew; "
        "with --only: whether one shape's σ are honest, from the mean (e/σ)² over N)",
    )
    args = parser.parse_args(argv)
    if args.n < 1 or args.jobs < 1 or (args.recording_seeds or 1) < 1:
        parser.error("--n, --jobs and --recording-seeds must be at least 1")
    drawn = list(enumerate(draw_shapes(args.n, args.seed, tuple(args.car_km), tuple(args.robot_m))))
    if args.only:
        if not all(0 <= i < args.n for i in args.only):
            parser.error(f"--only: each index must be in 0 … {args.n - 1}")
        drawn = [drawn[i] for i in args.only]
    names = [f"shape{i:03d}" for i, _ in drawn]
    if args.recording_seeds:
        drawn = [
            (i, dataclasses.replace(shape, seed=k))
            for i, shape in drawn
            for k in range(args.recording_seeds)
        ]
        names = [f"shape{i:03d}_seed{shape.seed}" for i, shape in drawn]
    base = args.keep or Path(tempfile.mkdtemp(prefix="campaign_"))
    try:
        with ThreadPoolExecutor(max_workers=args.jobs) as pool:
            rows = list(
                pool.map(
                    lambda shape, name: run_shape(shape, base / name, args.timeout),
                    [shape for _, shape in drawn],
                    names,
                )
            )
    finally:
        if args.keep is None:
            shutil.rmtree(base, ignore_errors=True)
    print(f"`python scripts/campaign.py {' '.join(argv if argv is not None else sys.argv[1:])}`\n")
    print(table(rows, [i for i, _ in drawn]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
