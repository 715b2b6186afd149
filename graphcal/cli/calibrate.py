"""``graphcal calibrate``: theta from a drive log or recording, with results, figures and a
summary; exit status 3 when the results are written but not to be trusted."""

from __future__ import annotations

import argparse
from pathlib import Path

from graphcal import (
    EXIT_UNTRUSTED,
    METHODS,
    GraphcalError,
    calibrate_file,
    check_output_directory,
    default_workers,
    recording_path,
)
from graphcal.cli.arguments import at_least, value_option, whole
from graphcal.cli.options import (
    add_recording_options,
    add_segment_options,
    add_vehicle_option,
    check_recording_options,
    recording_keywords,
    settings_from_args,
    timed_progress,
)

NAME = "calibrate"
HELP = "calibrate theta from a drive log"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The log, ``--out``, the segment options, the method and its batches, the settings
    file, workers, the paper's and the defect model's switches, then the recording and
    vehicle options."""
    p.add_argument(
        "log",
        type=recording_path,
        help="drive-log CSV (t, px, py, psi, n_rl, n_rr, beta, ay), or a streams manifest (or "
        "its directory) or ROS bag (imported in memory)",
    )
    p.add_argument(
        "--out", type=Path, default=Path("results"), help="output directory (default results/)"
    )
    add_segment_options(p)
    value_option(
        p,
        "--validation-length",
        at_least(0.01, "m"),
        "M",
        "validation segment length [m] (default 300; with --vehicle scaled like --segment-length)",
    )
    _add_method_options(p)
    _add_run_options(p)
    add_recording_options(p)
    add_vehicle_option(p)


def _add_method_options(p: argparse.ArgumentParser) -> None:
    """``--method``, ``--batches``, ``--seed``, ``--batch-solve``."""
    p.add_argument(
        "--method",
        choices=list(METHODS),
        default="joint",
        help="joint (default): one graph over all selected segments for start poses, "
        "wheel-rotation corrections and theta together (the recommended theta with its "
        "covariance), then the same per batch; staged: the paper's five steps over batches; "
        "whole: only the solve over all selected segments, quick",
    )
    value_option(
        p,
        "--batches",
        whole(0),
        "N",
        "number of batches for staged and joint (default 100; the paper's study, §5.1, "
        "is 1000); 0 = one joint solve over the whole log (same as --method whole)",
    )
    p.add_argument("--seed", type=whole(0), default=None, help="seed of the batch draw (default 0)")
    p.add_argument(
        "--batch-solve",
        choices=["linearized", "exact"],
        default=None,
        help="how the joint method solves its batches: linearized (default; every segment's "
        "system at the whole-log solution, summed per batch: a few thousandths of σ from "
        "exact on clean drives, up to 0.4σ with modelled slip) or exact (one solve per "
        "batch, 1–2 s each)",
    )


def _add_run_options(p: argparse.ArgumentParser) -> None:
    """``--config``, ``--workers``, ``--paper-exact``, ``--no-defect-model``."""
    value_option(
        p,
        "--config",
        Path,
        "FILE",
        "TOML settings file (see graphcal/pipeline/configuration/settings.py); options override it",
    )
    value_option(
        p,
        "--workers",
        whole(1),
        "N",
        "worker processes (default: one per core); results do not depend on it",
    )
    p.add_argument(
        "--paper-exact",
        action="store_true",
        help="follow the paper literally: eq. 15 heading correction on every sample and start "
        "poses held in Steps 3 and 5 (graphcal's defaults are measured to be more accurate)",
    )
    p.add_argument(
        "--no-defect-model",
        action="store_true",
        help="estimate theta alone: no wheel time offset, antenna lever arm, heading biases "
        "or outlier weights (the joint solve models them by default)",
    )


def run(args: argparse.Namespace) -> int:
    """Calibrate theta from a drive log and write results, figures and a summary."""
    from graphcal import evaluate, summary_text, synthetic_truth, write_results

    check_recording_options(args, args.log)
    method = _method(args)
    settings = settings_from_args(args)
    check_output_directory(args.out)  # before minutes of computation, not after
    workers = args.workers or default_workers()
    say = timed_progress()
    calibration, imported = calibrate_file(
        args.log, settings, method, progress=say, workers=workers, **recording_keywords(args)
    )
    truth = synthetic_truth(calibration, args.log, imported, say)
    evaluation = None if truth is None else evaluate(calibration, truth, say, workers)
    try:
        written = write_results(calibration, args.out, evaluation=evaluation, workers=workers)
    except OSError as exc:
        raise GraphcalError(f"cannot write results to {args.out}: {exc.strerror or exc}") from exc
    say(f"wrote {', '.join(p.name for p in written)} to {Path(args.out)}")
    print(summary_text(calibration, evaluation))
    if calibration.trust is not None and not calibration.trust.trusted:
        return EXIT_UNTRUSTED  # results written, but a check says they are not to be trusted
    return 0


def _method(args: argparse.Namespace) -> str:
    """``--method``, or ``whole`` for ``--batches 0`` (one solve over the whole log)."""
    if args.batches != 0:
        return args.method
    if args.method == "staged":
        raise GraphcalError(
            "--batches 0 (one solve over the whole log) needs --method joint or whole; "
            "the staged method works on batches"
        )
    return "whole"
