"""The ``graphcal`` command line: thin wrappers around the library.

Bad input prints one line ``graphcal: error: …`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from graphcal import __version__
from graphcal.arguments import at_least as _at_least
from graphcal.arguments import non_negative as _non_negative
from graphcal.arguments import whole as _whole
from graphcal.errors import GraphcalError
from graphcal.pipeline.parallel import default_workers
from graphcal.pipeline.run import METHODS
from graphcal.pipeline.settings import Settings, load_settings
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS

if TYPE_CHECKING:
    from graphcal.evaluation import Evaluation
    from graphcal.pipeline.run import CalibrationRun

EXIT_BAD_INPUT = 2


def _log_line(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _timed_progress() -> Callable[[str], None]:
    start = time.perf_counter()

    def say(message: str) -> None:
        _log_line(f"[{time.perf_counter() - start:6.1f} s] {message}")

    return say


def cmd_simulate(args: argparse.Namespace) -> int:
    """Write a synthetic drive, its noise-free truth and a JSON sidecar."""
    from graphcal.simulate.drive import NoiseLevels, simulate_drive, write_synthetic_drive

    theta_true = np.asarray(args.theta_true, dtype=float) / DISPLAY_SCALE
    if not (np.all(np.isfinite(theta_true)) and theta_true[0] > 0 and theta_true[2] > 0):
        raise GraphcalError(
            f"--theta-true {' '.join(map(str, args.theta_true))}: c_e and t_r must be positive "
            f"and all values finite ({', '.join(DISPLAY_UNITS)})"
        )
    noise = NoiseLevels(
        position=args.position_noise,
        heading=float(np.deg2rad(args.heading_noise_deg)),
        wheel_rotation=args.wheel_noise,
        sideslip=float(np.deg2rad(args.sideslip_noise_deg)),
        lateral_acceleration=args.ay_noise,
    )
    say = _timed_progress()
    drive = simulate_drive(args.length_km, args.seed, theta_true, noise, args.dt, route=args.route)
    say(f"simulated {len(drive.measured)} samples ({drive.measured.t[-1]:.0f} s)")
    try:
        written = write_synthetic_drive(drive, args.out)
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    """Validate a drive log and summarize what calibration would use."""
    from graphcal.data.drive_log import load_drive_log
    from graphcal.data.segments import split_segments, yaw_rate_statistic

    seg = settings_from_args(args).segments
    log = load_drive_log(args.log)
    segments = split_segments(log, seg.length, seg.stride)
    yaw = yaw_rate_statistic(log, segments, seg.yaw_statistic, seg.yaw_window)
    print(f"{args.log}: valid drive log")
    print(f"  samples          {len(log)} at {log.dt * 1e3:.1f} ms ({1 / log.dt:.1f} Hz)")
    print(f"  duration         {log.t[-1] - log.t[0]:.1f} s")
    print(f"  distance         {log.travelled_distance()[-1]:.1f} m (wheels, c_e = 2 m)")
    print(
        f"  segments         {len(segments)} of {seg.length:g} m, "
        f"{int((yaw > seg.min_yaw_rate).sum())} with {seg.yaw_statistic} |yaw rate| > "
        f"{seg.min_yaw_rate:g} rad/s"
    )
    if log.masked is not None:
        print(
            f"  masked           {log.masked.sum() * log.dt:.1f} s where the positions disagree "
            "with the wheels (no segment spans them):"
        )
        for note in log.mask_notes:
            print(f"    {note}")
    return 0


def settings_from_args(args: argparse.Namespace) -> Settings:
    """Settings: the paper's defaults, then ``--config FILE``, then explicit options."""
    settings = load_settings(args.config) if getattr(args, "config", None) else Settings()
    segments = {
        "length": args.segment_length,
        "stride": args.segment_stride,
        "min_yaw_rate": args.min_yaw_rate,
        "yaw_statistic": args.yaw_statistic,
        "validation_length": getattr(args, "validation_length", None),
    }
    segments = {k: v for k, v in segments.items() if v is not None}
    count = getattr(args, "batches", None)
    batches = {"count": count or None, "seed": getattr(args, "seed", None)}
    batches = {k: v for k, v in batches.items() if v is not None}
    try:
        settings = dataclasses.replace(
            settings,
            segments=dataclasses.replace(settings.segments, **segments),
            batches=dataclasses.replace(settings.batches, **batches),
        )
        if getattr(args, "paper_exact", False):
            staged = dataclasses.replace(
                settings.staged, heading_correction="paper", estimate_start_poses=False
            )
            settings = dataclasses.replace(settings, staged=staged)
    except ValueError as exc:
        raise GraphcalError(str(exc)) from exc
    return settings


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrate theta from a drive log and write results, figures and a summary."""
    from graphcal.data.drive_log import load_drive_log
    from graphcal.pipeline.run import run_calibration
    from graphcal.report.result_set import check_output_directory
    from graphcal.report.results import summary_text, write_results

    method = args.method
    if args.batches == 0:
        if method == "staged":
            raise GraphcalError(
                "--batches 0 (one solve over the whole log) needs --method joint or whole; "
                "the staged method works on batches"
            )
        method = "whole"
    settings = settings_from_args(args)
    check_output_directory(args.out)  # before minutes of computation, not after
    workers = args.workers or default_workers()
    say = _timed_progress()
    log = load_drive_log(args.log, min_distance=settings.segments.length)
    say(f"loaded {args.log}: {len(log)} samples, {log.travelled_distance()[-1]:.0f} m")
    run = run_calibration(log, settings, method, progress=say, workers=workers)
    evaluation = _evaluate_synthetic(run, args.log, say, workers)
    try:
        written = write_results(run, args.out, evaluation=evaluation)
    except OSError as exc:
        raise GraphcalError(f"cannot write results to {args.out}: {exc.strerror or exc}") from exc
    say(f"wrote {', '.join(p.name for p in written)} to {Path(args.out)}")
    print(summary_text(run, evaluation))
    return 0


def _evaluate_synthetic(
    run: CalibrationRun, log_path: Path, say: Callable[[str], None], workers: int
) -> Evaluation | None:
    """The run against the truth in a synthetic drive's sidecar, or ``None`` for a real log."""
    from graphcal.data.drive_log import load_drive_log
    from graphcal.evaluation import Truth, evaluate
    from graphcal.simulate.drive import read_sidecar, truth_path

    sidecar = read_sidecar(log_path, len(run.log))
    if sidecar is None:
        return None
    say("synthetic drive: comparing with theta_true from its sidecar")
    path = truth_path(log_path)
    truth_log = None
    try:
        truth_log = load_drive_log(path)
    except GraphcalError as exc:
        say(f"no Cramér–Rao bound: cannot use {path.name}: {exc}")
    if truth_log is not None and len(truth_log) != len(run.log):
        say(
            f"no Cramér–Rao bound: {path.name} has {len(truth_log)} samples, the log {len(run.log)}"
        )
        truth_log = None
    return evaluate(run, Truth(sidecar["theta_true"], truth_log), say, workers)


def cmd_bench(args: argparse.Namespace) -> int:
    """Time graphcal's solves next to the naive per-step GTSAM formulation; write JSON."""
    from graphcal.bench.run import run_from_options, write_report

    report = run_from_options(args, progress=print)
    print(f"(a)/(b) per iteration: {report['naive_over_graphcal_per_iteration']:.0f}x")
    try:
        write_report(report, args.out)
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    print(f"wrote {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``graphcal`` command."""
    parser = argparse.ArgumentParser(
        prog="graphcal",
        description="Wheel-odometry calibration with noise compensation, as GTSAM factor graphs.",
    )
    parser.add_argument("--version", action="version", version=f"graphcal {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def segment_options(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--segment-length",
            type=_at_least(10.0, "m"),
            default=None,
            metavar="M",
            help="calibration segment length [m] (default 150, paper §5.1)",
        )
        p.add_argument(
            "--segment-stride",
            type=_at_least(1.0, "m"),
            default=None,
            metavar="M",
            help="distance between segment starts [m]; shorter than the length gives "
            "overlapping segments (default: disjoint)",
        )
        p.add_argument(
            "--min-yaw-rate",
            type=_non_negative,
            default=None,
            metavar="RAD_S",
            help="select segments whose |yaw rate| statistic exceeds this (default 0.15 rad/s)",
        )
        p.add_argument(
            "--yaw-statistic",
            choices=["mean", "median", "rms"],
            default=None,
            help="statistic of |yaw rate| used for selection (default mean)",
        )

    p = sub.add_parser(
        "simulate",
        help="write a synthetic drive with known theta",
        description=cmd_simulate.__doc__,
    )
    p.add_argument(
        "--length-km", type=_at_least(0.1, "km"), default=24.0, help="route length [km] (24)"
    )
    p.add_argument("--seed", type=_whole(0), default=0, help="seed of every random choice (0)")
    p.add_argument(
        "--route",
        choices=["city", "straight"],
        default="city",
        help="city: bends, turns and roundabouts (default); straight: a straight road, where "
        "t_r and d are not observable",
    )
    p.add_argument("--out", required=True, type=Path, help="output CSV path")
    p.add_argument(
        "--dt", type=_at_least(1e-3, "s"), default=0.025, help="sampling interval [s] (0.025)"
    )
    p.add_argument(
        "--theta-true",
        type=float,
        nargs=4,
        metavar=("C_E", "C_D", "T_R", "D"),
        default=[1.985, 1.2, 1.585, 1.5],
        help=f"true theta in {', '.join(DISPLAY_UNITS)} (1.985 1.2 1.585 1.5)",
    )
    p.add_argument(
        "--position-noise",
        type=_non_negative,
        default=0.2,
        metavar="M",
        help="position noise sigma [m] (0.2)",
    )
    p.add_argument(
        "--heading-noise-deg",
        type=_non_negative,
        default=1.5,
        metavar="DEG",
        help="heading noise sigma [deg] (1.5)",
    )
    p.add_argument(
        "--wheel-noise",
        type=_non_negative,
        default=0.0005,
        metavar="REV",
        help="wheel rotation noise sigma [rev] (0.0005)",
    )
    p.add_argument(
        "--sideslip-noise-deg",
        type=_non_negative,
        default=0.0,
        metavar="DEG",
        help="sideslip noise sigma [deg] (0)",
    )
    p.add_argument(
        "--ay-noise",
        type=_non_negative,
        default=0.0,
        metavar="M_S2",
        help="lateral acceleration noise sigma [m/s²] (0)",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "bench", help="benchmark against the naive GTSAM formulation", description=cmd_bench.__doc__
    )
    from graphcal.bench.options import add_bench_arguments

    add_bench_arguments(p)
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser(
        "check", help="validate a drive log and summarize it", description=cmd_check.__doc__
    )
    p.add_argument("log", type=Path, help="drive-log CSV")
    segment_options(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser(
        "calibrate", help="calibrate theta from a drive log", description=cmd_calibrate.__doc__
    )
    p.add_argument("log", type=Path, help="drive-log CSV (t, px, py, psi, n_rl, n_rr, beta, ay)")
    p.add_argument(
        "--out", type=Path, default=Path("results"), help="output directory (default results/)"
    )
    segment_options(p)
    p.add_argument(
        "--validation-length",
        type=_at_least(10.0, "m"),
        default=None,
        metavar="M",
        help="validation segment length [m] (default 300)",
    )
    p.add_argument(
        "--method",
        choices=list(METHODS),
        default="joint",
        help="joint (default): one graph per batch for start poses, wheel-rotation "
        "corrections and theta together, then one over all selected segments for the "
        "recommended theta with its covariance; staged: the paper's five steps over batches; "
        "whole: only the solve over all selected segments, quick",
    )
    p.add_argument(
        "--batches",
        type=_whole(0),
        default=None,
        metavar="N",
        help="number of batches for staged and joint (default 1000, paper §5.1); 0 = one "
        "joint solve over the whole log (same as --method whole)",
    )
    p.add_argument(
        "--seed", type=_whole(0), default=None, help="seed of the batch draw (default 0)"
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="TOML settings file (see graphcal/pipeline/settings.py); options override it",
    )
    p.add_argument(
        "--workers",
        type=_whole(1),
        default=None,
        metavar="N",
        help="worker processes (default: one per core); results do not depend on it",
    )
    p.add_argument(
        "--paper-exact",
        action="store_true",
        help="follow the paper literally: eq. 15 heading correction on every sample and start "
        "poses held in Steps 3 and 5 (graphcal's defaults are measured to be more accurate)",
    )
    p.set_defaults(func=cmd_calibrate)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``graphcal`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except GraphcalError as exc:
        print(f"graphcal: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("graphcal: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `graphcal check LOG | head`: the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
