"""The ``graphcal`` command line: thin wrappers around the library.

Bad input prints one line ``graphcal: error: …`` and exits with status 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from graphcal import __version__
from graphcal.arguments import at_least as _at_least
from graphcal.arguments import in_range as _in_range
from graphcal.arguments import non_negative as _non_negative
from graphcal.arguments import whole as _whole
from graphcal.data.consistency import runs
from graphcal.errors import GraphcalError, first_line
from graphcal.pipeline.joint import without_defect_model
from graphcal.pipeline.parallel import default_workers
from graphcal.pipeline.run import METHODS
from graphcal.pipeline.settings import Settings
from graphcal.pipeline.settings_file import load_settings, load_vehicle, vehicle_settings_in
from graphcal.pipeline.vehicle_settings import apply_vehicle
from graphcal.units import DISPLAY_SCALE, DISPLAY_UNITS

if TYPE_CHECKING:
    from graphcal.evaluation import Evaluation
    from graphcal.pipeline.calibration_run import CalibrationRun

EXIT_BAD_INPUT = 2
EXIT_UNTRUSTED = 3  # graphcal.pipeline.trust: written, but not to be trusted


def _log_line(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def _timed_progress() -> Callable[[str], None]:
    start = time.perf_counter()

    def say(message: str) -> None:
        _log_line(f"[{time.perf_counter() - start:6.1f} s] {message}")

    return say


def cmd_simulate(args: argparse.Namespace) -> int:
    """Write a synthetic drive, its noise-free truth and a JSON sidecar."""
    from graphcal.simulate.drive import (
        THETA_TRUE_DEFAULT,
        NoiseLevels,
        simulate_drive,
        write_synthetic_drive,
    )

    theta_true = None
    if args.theta_true is not None:
        theta_true = np.asarray(args.theta_true, dtype=float) / DISPLAY_SCALE
        if not (np.all(np.isfinite(theta_true)) and theta_true[0] > 0 and theta_true[2] > 0):
            raise GraphcalError(
                f"--theta-true {' '.join(map(str, args.theta_true))}: c_e and t_r must be "
                f"positive and all values finite ({', '.join(DISPLAY_UNITS)})"
            )
    if args.vehicle is not None:
        return _simulate_robot(args, theta_true)
    if args.reversing:
        raise GraphcalError("--reversing drives a robot: give its profile with --vehicle")
    if theta_true is None:
        theta_true = THETA_TRUE_DEFAULT
    if args.position_noise is None:
        args.position_noise = NoiseLevels.position
    if args.heading_noise_deg is None:
        args.heading_noise_deg = CAR_HEADING_NOISE_DEG
    noise = NoiseLevels(
        position=args.position_noise,
        heading=float(np.deg2rad(args.heading_noise_deg)),
        wheel_rotation=args.wheel_noise,
        sideslip=float(np.deg2rad(args.sideslip_noise_deg)),
        lateral_acceleration=args.ay_noise,
    )
    say = _timed_progress()
    defects = None
    if args.defects is not None:
        if args.streams is not None:
            raise GraphcalError(
                "--defects applies to the drive-log output (--out) for now, not to --streams"
            )
        from graphcal.simulate.defects import parse_defects

        try:
            defects = parse_defects(args.defects)
        except ValueError as exc:
            raise GraphcalError(f"--defects {args.defects}: {exc}") from None
    if args.fleet is not None:
        return _simulate_fleet(args, say)
    length_km = 24.0 if args.length_km is None else args.length_km
    if args.streams is not None:
        return _simulate_streams(args, theta_true, say)
    if args.out is None:
        raise GraphcalError("simulate needs --out FILE.csv (or --streams DIR)")
    drive = simulate_drive(length_km, args.seed, theta_true, noise, args.dt, route=args.route)
    say(f"simulated {len(drive.measured)} samples ({drive.measured.t[-1]:.0f} s)")
    if defects is not None and defects.names:
        from graphcal.simulate.defects import degrade

        try:
            drive = degrade(drive, defects, args.seed)
        except ValueError as exc:
            raise GraphcalError(f"--defects {args.defects}: {exc}") from None
        say(f"added defects: {', '.join(defects.names)}")
    try:
        written = write_synthetic_drive(drive, args.out)
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


#: The car simulation's heading noise [deg] unless --heading-noise-deg gives one.
CAR_HEADING_NOISE_DEG = 1.5


def _simulate_robot(args: argparse.Namespace, theta_true: np.ndarray | None) -> int:
    """``simulate --vehicle ROBOT``: a robot's runs and spins as motion-capture poses and
    encoder counts (``--streams DIR``, optionally ``--bag``) or a drive-log CSV (``--out``)."""
    from graphcal.pipeline.settings_file import load_vehicle
    from graphcal.simulate.robot import RobotSettings, simulate_robot, theta_true_for

    vehicle = load_vehicle(args.vehicle)
    if not vehicle.reverses:
        raise GraphcalError(
            f"--vehicle {args.vehicle}: simulate drives robots that turn on the spot; this "
            "profile does not (reverses = false): leave --vehicle out to simulate the car"
        )
    unused = [
        f"--{name.replace('_', '-')}"
        for name in ("fleet", "defects", "length_km")
        if getattr(args, name) is not None
    ]
    if unused or args.route != "city":
        raise GraphcalError(
            f"--vehicle simulates a robot's runs; {', '.join(unused) or '--route'} "
            "applies to the car (use --runs)"
        )
    if (args.out is None) == (args.streams is None):
        raise GraphcalError("simulate --vehicle needs one of --out FILE.csv or --streams DIR")
    overrides: dict[str, object] = {"reversing": args.reversing}
    if args.position_noise is not None:
        overrides["position_noise"] = args.position_noise
    if args.heading_noise_deg is not None:
        overrides["heading_noise"] = float(np.deg2rad(args.heading_noise_deg))
    try:
        robot = RobotSettings.from_vehicle(vehicle, **overrides)
    except ValueError as exc:
        raise GraphcalError(f"--vehicle {args.vehicle}: {exc}") from None
    theta = theta_true_for(vehicle) if theta_true is None else theta_true
    say = _timed_progress()
    sim = simulate_robot(args.seed, args.runs, robot, theta)
    say(
        f"simulated {vehicle.name}: {args.runs} runs, {sim.total_distance:.1f} m, "
        f"{sim.drive.measured.t[-1]:.0f} s"
    )
    try:
        if args.out is not None:
            from graphcal.simulate.drive import write_synthetic_drive

            written = write_synthetic_drive(sim.drive, args.out)
        else:
            written = _write_streams(sim, Path(args.streams), args.bag, mocap=True)
    except OSError as exc:
        raise GraphcalError(f"cannot write {exc.filename or args.out}: {exc.strerror}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def _simulate_fleet(args: argparse.Namespace, say: Callable[[str], None]) -> int:
    """``simulate --fleet DIR``: a synthetic fleet with per-vehicle truths and one change."""
    from graphcal.simulate.fleet import FleetChange, simulate_fleet

    others = [name for name in ("out", "streams", "defects") if getattr(args, name) is not None]
    if others:
        raise GraphcalError(
            f"--fleet writes a fleet of clean drives at the paper's noise; it does not take "
            f"{', '.join('--' + n for n in others)}"
        )
    change = None
    if args.change.lower() != "none":
        try:
            vehicle, day, millimetres = args.change.split(":")
            change = FleetChange(
                int(vehicle.lstrip("v")),
                int(day.removeprefix("day")),
                np.array([float(millimetres) * 1e-3, 0.0, 0.0, 0.0]),
            )
        except ValueError:
            raise GraphcalError(
                f"--change {args.change}: expected VEHICLE:DAY:C_E_MM (e.g. 3:3:-3 or "
                "v3:day3:-3) or none"
            ) from None
    length_km = 4.0 if args.length_km is None else args.length_km
    try:
        truth = simulate_fleet(args.fleet, args.vehicles, args.days, length_km, args.seed, change)
    except ValueError as exc:
        raise GraphcalError(f"--fleet: {exc}") from None
    except OSError as exc:
        raise GraphcalError(f"cannot write {args.fleet}: {exc.strerror or exc}") from exc
    what = (
        "no change"
        if change is None
        else f"c_e {args.change.split(':')[2]} mm on v{change.vehicle} from day{change.day}"
    )
    say(
        f"wrote a fleet of {args.vehicles} vehicles × {args.days} days of {length_km:g} km "
        f"({what}) to {args.fleet}; truths in {truth.name}"
    )
    return 0


def cmd_fleet(args: argparse.Namespace) -> int:
    """Calibrate every log of a fleet on Dask; per vehicle, changes of theta over days."""
    from graphcal.fleet.run import run_fleet
    from graphcal.pipeline.settings_file import vehicle_settings_in

    settings = settings_from_args(args)
    keep = vehicle_settings_in(args.config) if args.config else set()
    say = _timed_progress()
    run = run_fleet(
        args.source,
        args.out,
        settings,
        workers=args.workers or default_workers(),
        scheduler=args.scheduler,
        alpha=args.alpha,
        keep=keep,
        progress=say,
        bar=not args.no_progress_bar,
    )
    say(f"wrote {', '.join(p.name for p in run.written)} to {Path(args.out)}")
    for line in run.summary():
        print(line)
    return 0


class _PrintManifestKeys(argparse.Action):
    """``graphcal import --help-manifest``: print every manifest key with its default."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from graphcal.data import manifest

        print(inspect.cleandoc(manifest.__doc__ or ""))
        parser.exit()


def recording_path(text: str) -> Path:
    """A log or recording argument as a path: a directory holding ``manifest.toml`` (as
    ``graphcal simulate --streams DIR`` writes) is that recording, unless it is a ROS 2 bag."""
    path = Path(text)
    manifest = path / "manifest.toml"
    if path.is_dir() and manifest.is_file() and not (path / "metadata.yaml").exists():
        return manifest
    return path


def _bag_options(args: argparse.Namespace):
    """The bag flags (``--pose-topic`` ...) as :class:`~graphcal.data.importer.BagOptions`."""
    from graphcal.data.importer import BagOptions

    return BagOptions(**{f.name: getattr(args, f.name) for f in dataclasses.fields(BagOptions)})


def _load(args: argparse.Namespace, settings: Settings, min_distance: float = 0.0):
    """The drive log of ``args.log`` — a drive-log CSV, or a manifest or bag imported in
    memory — and the :class:`~graphcal.data.importer.ImportedLog` of an import (else None).
    Checked against the vehicle's nominal theta."""
    from graphcal.data.drive_log import load_drive_log
    from graphcal.data.importer import import_recording, is_recording

    nominal = settings.vehicle.theta_nominal
    if is_recording(args.log):
        imported = import_recording(
            args.log,
            rate=args.rate,
            max_gap=args.max_gap,
            bag=_bag_options(args),
            nominal=nominal,
            min_distance=min_distance,
            reverses=settings.vehicle.reverses,
        )
        return imported.log, imported
    log = load_drive_log(
        args.log, min_distance=min_distance, nominal=nominal, reverses=settings.vehicle.reverses
    )
    return log, None


def _distance_line(log, settings: Settings) -> str:
    c_e = float(settings.vehicle.theta_nominal[0])
    return f"{log.travelled_distance(c_e)[-1]:.1f} m (wheels, nominal c_e = {c_e:g} m)"


def _print_masked(log) -> None:
    if log.outlying is not None:
        runs_ = runs(log.outlying)
        first = ", ".join(f"{log.t[a]:.1f} s" for a, _ in runs_[:3])
        print(
            f"  outlying fixes   {len(runs_)} isolated position spike(s), {log.outlying.sum()} "
            f"sample(s), given no weight (first at {first})"
        )
    if log.masked is not None:
        print(
            f"  masked           {log.masked.sum() * log.dt:.1f} s that no segment spans "
            "(gaps, reversing, positions that disagree with the wheels):"
        )
        for note in log.mask_notes:
            print(f"    {note}")


def _print_excitation(log, settings: Settings) -> None:
    from graphcal.data.excitation import drive_excitation

    seg = settings.segments
    excitation = drive_excitation(
        log,
        seg.length,
        seg.min_yaw_rate,
        seg.yaw_statistic,
        seg.yaw_window,
        wheel_circumference=float(settings.vehicle.theta_nominal[0]),
    )
    for line in excitation.lines():
        print(f"  {line}")


def cmd_import(args: argparse.Namespace) -> int:
    """Import a streams manifest (TOML) or a ROS 1/2 bag or MCAP file into a drive-log CSV."""
    from graphcal.data.importer import check_import_output, import_recording, write_import

    settings = settings_from_args(args)
    check_import_output(args.source, args.out)
    out = Path(args.out)
    say = _timed_progress()
    imported = import_recording(
        args.source,
        rate=args.rate,
        max_gap=args.max_gap,
        bag=_bag_options(args),
        nominal=settings.vehicle.theta_nominal,
        reverses=settings.vehicle.reverses,
    )
    say(f"imported {args.source}")
    log = imported.log
    print(f"{args.source}: recording")
    for line in imported.lines():
        print(f"  {line}")
    print(f"  distance         {_distance_line(log, settings)}, {log.t[-1] - log.t[0]:.1f} s")
    _print_excitation(log, settings)
    _print_masked(log)
    for warning in imported.warnings:
        print(f"warning: {warning}")
    try:
        written = write_import(imported, out)
    except OSError as exc:
        raise GraphcalError(
            f"cannot write {exc.filename or out}: {exc.strerror or exc}; nothing was written"
        ) from exc
    say(f"wrote {', '.join(str(p) for p in written)}")
    return 0


def _simulate_streams(
    args: argparse.Namespace, theta_true: np.ndarray, say: Callable[[str], None]
) -> int:
    """``simulate --streams DIR``: raw GNSS, wheel and IMU streams with a manifest."""
    from graphcal.simulate.streams import StreamSettings, simulate_streams

    directory = Path(args.streams)
    stream_settings = StreamSettings(
        position_noise=args.position_noise,
        heading_noise=float(np.deg2rad(args.heading_noise_deg)),
        lateral_acceleration_noise=args.ay_noise,
        sideslip_noise=float(np.deg2rad(args.sideslip_noise_deg)),
        wheel_kind=args.wheel_kind_sim,
    )
    length_km = 24.0 if args.length_km is None else args.length_km
    sim = simulate_streams(length_km, args.seed, theta_true, stream_settings, route=args.route)
    say(f"simulated {length_km:g} km as GNSS, wheel and IMU streams")
    try:
        written = _write_streams(sim, directory, args.bag)
    except OSError as exc:
        raise GraphcalError(f"cannot write {directory}: {exc.strerror or exc}") from exc
    for path in written:
        say(f"wrote {path}")
    return 0


def _write_streams(sim, directory: Path, bag: str | None, mocap: bool = False):
    """Write ``sim``'s streams and manifest into ``directory`` and, with ``bag``, a bag (the
    pose as a motion-capture ``PoseStamped`` on ``/mocap/pose`` when ``mocap``)."""
    from graphcal.simulate.streams import write_streams

    if bag is not None:
        import importlib.util

        if importlib.util.find_spec("rosbags") is None:
            raise GraphcalError(f'--bag {bag} needs the rosbags package: pip install -e ".[ros]"')
    if directory.exists() and not directory.is_dir():
        raise GraphcalError(f"--streams {directory}: exists and is not a directory")
    written = write_streams(sim, directory)
    if bag is not None:
        from graphcal.simulate.bags import write_bag

        suffix = {"ros1": "drive.bag", "ros2": "drive_ros2", "mcap": "drive_mcap"}[bag]
        pose = {"pose_topic": "/mocap/pose", "pose_message": "posestamped"} if mocap else {}
        written.append(write_bag(sim.recording, directory / suffix, bag, **pose))
    return written


def cmd_check(args: argparse.Namespace) -> int:
    """Validate a drive log (or a manifest or bag, imported in memory) and summarize it."""
    from graphcal.data.drive_log import measurement_line
    from graphcal.data.segments import split_segments, yaw_rate_statistic

    settings = settings_from_args(args)
    seg = settings.segments
    log, imported = _load(args, settings)
    segments = split_segments(log, seg.length, seg.stride, settings.vehicle.theta_nominal[0])
    yaw = yaw_rate_statistic(log, segments, seg.yaw_statistic, seg.yaw_window)
    print(f"{args.log}: valid {'recording' if imported else 'drive log'}")
    if imported is not None:
        for line in imported.lines():
            print(f"  {line}")
    print(f"  samples          {len(log)} at {log.dt * 1e3:.1f} ms ({1 / log.dt:.1f} Hz)")
    print(f"  duration         {log.t[-1] - log.t[0]:.1f} s")
    if log.sparse:
        print(f"  measurements     {measurement_line(log)}")
    print(f"  distance         {_distance_line(log, settings)}")
    print(
        f"  segments         {len(segments)} of {seg.length:g} m, "
        f"{int((yaw > seg.min_yaw_rate).sum())} with {seg.yaw_statistic} |yaw rate| > "
        f"{seg.min_yaw_rate:g} rad/s"
    )
    _print_excitation(log, settings)
    _print_masked(log)
    for warning in imported.warnings if imported is not None else ():
        print(f"warning: {warning}")
    return 0


def settings_from_args(args: argparse.Namespace) -> Settings:
    """Settings: the paper's defaults, then ``--config FILE``, then explicit options."""
    settings = load_settings(args.config) if getattr(args, "config", None) else Settings()
    if getattr(args, "vehicle", None) is not None:
        keep = vehicle_settings_in(args.config) if getattr(args, "config", None) else set()
        settings = apply_vehicle(settings, load_vehicle(args.vehicle), keep=keep)
    segments = {
        "length": args.segment_length,
        "stride": args.segment_stride,
        "min_yaw_rate": args.min_yaw_rate,
        "yaw_statistic": args.yaw_statistic,
        "validation_length": getattr(args, "validation_length", None),
    }
    segments = {k: v for k, v in segments.items() if v is not None}
    count = getattr(args, "batches", None)
    batches = {
        "count": count or None,
        "seed": getattr(args, "seed", None),
        "joint_solve": getattr(args, "batch_solve", None),
    }
    batches = {k: v for k, v in batches.items() if v is not None}
    try:
        settings = dataclasses.replace(
            settings,
            segments=dataclasses.replace(settings.segments, **segments),
            batches=dataclasses.replace(settings.batches, **batches),
        )
        if getattr(args, "no_defect_model", False):
            settings = dataclasses.replace(settings, joint=without_defect_model(settings.joint))
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
    log, imported = _load(args, settings, min_distance=settings.segments.length)
    what = "imported" if imported else "loaded"
    distance = log.travelled_distance(settings.vehicle.theta_nominal[0])[-1]
    say(f"{what} {args.log}: {len(log)} samples, {distance:.0f} m")
    if imported is not None:
        for line in imported.lines():
            say(line)
    run = run_calibration(log, settings, method, progress=say, workers=workers)
    if imported is not None and imported.warnings:  # the import's doubts go with the result
        run = dataclasses.replace(run, warnings=(*imported.warnings, *run.warnings))
    if imported is not None:
        evaluation = None
        if imported.truth is not None:
            from graphcal.evaluation import Truth, evaluate

            say("synthetic recording: comparing with theta_true from its manifest")
            evaluation = evaluate(run, Truth(imported.truth), say, workers)
    else:
        evaluation = _evaluate_synthetic(run, args.log, say, workers)
    try:
        written = write_results(run, args.out, evaluation=evaluation)
    except OSError as exc:
        raise GraphcalError(f"cannot write results to {args.out}: {exc.strerror or exc}") from exc
    say(f"wrote {', '.join(p.name for p in written)} to {Path(args.out)}")
    print(summary_text(run, evaluation))
    if run.trust is not None and not run.trust.trusted:
        return EXIT_UNTRUSTED  # results written, but a check says they are not to be trusted
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
    if not path.exists():
        # An imported recording's sidecar carries theta_true but no noise-free drive; only
        # `graphcal simulate` writes one, and only then is its absence worth a word.
        if str(sidecar.get("generator", "")).endswith("simulate"):
            say(f"no Cramér–Rao bound: the noise-free drive {path} is missing")
    else:
        try:
            truth_log = load_drive_log(path, reverses=run.settings.vehicle.reverses)
        except GraphcalError as exc:
            say(f"no Cramér–Rao bound: cannot use {path}: {exc}")
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
    if "naive_over_graphcal_per_iteration" in report:
        print(f"(a)/(b) per iteration: {report['naive_over_graphcal_per_iteration']:.0f}x")
    else:
        print(f"(h) import: {report['import']}")
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
            type=_at_least(0.01, "m"),
            default=None,
            metavar="M",
            help="calibration segment length [m] (default 150, paper §5.1; with --vehicle "
            "scaled by its track over the car's 1.55 m; at least 5 tracks)",
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
        "--length-km",
        type=_at_least(0.1, "km"),
        default=None,
        help="route length [km] (24; with --fleet, 4 per day)",
    )
    p.add_argument("--seed", type=_whole(0), default=0, help="seed of every random choice (0)")
    p.add_argument(
        "--route",
        choices=["city", "straight"],
        default="city",
        help="city: bends, turns and roundabouts (default); straight: a straight road, where "
        "t_r and d are not observable",
    )
    p.add_argument("--out", type=Path, default=None, help="output CSV path")
    p.add_argument(
        "--vehicle",
        type=Path,
        default=None,
        metavar="FILE",
        help="a robot's profile (reverses = true, e.g. data/vehicles/mocap_robot.toml): drive "
        "a robot instead of the car — runs of 5–15 m, spins on the spot, stops, "
        "motion-capture poses and encoder counts with the profile's noise and resolution",
    )
    p.add_argument(
        "--runs", type=_whole(1), default=10, help="with a robot --vehicle: runs to drive (10)"
    )
    p.add_argument(
        "--reversing",
        action="store_true",
        help="with a robot --vehicle: reverse straight back a few metres after every second run",
    )
    p.add_argument(
        "--streams",
        type=Path,
        default=None,
        metavar="DIR",
        help="instead of a drive-log CSV, write raw streams into DIR: GNSS at 10 Hz "
        "(latitude/longitude), rear wheels and IMU at 100 Hz on their own clocks, with "
        "manifest.toml for `graphcal import`",
    )
    p.add_argument(
        "--wheel-kind",
        dest="wheel_kind_sim",
        choices=["speed", "ticks"],
        default="speed",
        help="with --streams: wheel speeds in m/s (the ECU's circumference 2.0 m; default) or "
        "cumulative ticks (96 per revolution)",
    )
    p.add_argument(
        "--bag",
        choices=["ros1", "ros2", "mcap"],
        default=None,
        help="with --streams: also write the streams as a ROS 1 bag, a ROS 2 bag or an MCAP file",
    )
    p.add_argument(
        "--dt", type=_at_least(1e-3, "s"), default=0.025, help="sampling interval [s] (0.025)"
    )
    p.add_argument(
        "--theta-true",
        type=float,
        nargs=4,
        metavar=("C_E", "C_D", "T_R", "D"),
        default=None,
        help=f"true theta in {', '.join(DISPLAY_UNITS)} (1.985 1.2 1.585 1.5; with a robot "
        "--vehicle near its nominal: 0.2639 0.1 0.205 0 for data/vehicles/mocap_robot.toml)",
    )
    p.add_argument(
        "--position-noise",
        type=_non_negative,
        default=None,
        metavar="M",
        help="position noise sigma [m] (0.2; with --vehicle the profile's)",
    )
    p.add_argument(
        "--heading-noise-deg",
        type=_non_negative,
        default=None,
        metavar="DEG",
        help="heading noise sigma [deg] (1.5; with --vehicle the profile's)",
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
    from graphcal.simulate.defects import ALL_NAMES, DEFECT_NAMES

    p.add_argument(
        "--defects",
        default=None,
        metavar="LIST",
        help="add defects of real logs to the drive-log output, comma-separated: "
        f"{', '.join(DEFECT_NAMES)}, or all (= {', '.join(ALL_NAMES)}); a name alone takes "
        "its realistic default, name=VALUE sets its size in SI units (gnss10hz/hold: Hz; "
        "outliers: share; outages/dropouts: count; heading_bias: rad/√s; latency: s; "
        "lever_arm: LONG[:LAT] m; ticks: per revolution; slip: relative σ), e.g. "
        "all,latency=0.1 or outliers=0.01,lever_arm=1.5:0.2 (docs/results.md)",
    )
    p.add_argument(
        "--fleet",
        type=Path,
        default=None,
        metavar="DIR",
        help="instead of one drive, a synthetic fleet in DIR (VEHICLE/DAY.csv, each with its "
        "truth, and fleet_truth.csv) for `graphcal fleet`",
    )
    p.add_argument("--vehicles", type=_whole(1), default=6, help="with --fleet: vehicles (6)")
    p.add_argument("--days", type=_whole(1), default=3, help="with --fleet: days (3)")
    p.add_argument(
        "--change",
        default="3:3:-3",
        metavar="V:DAY:MM",
        help="with --fleet: vehicle V's c_e changes by MM mm from day DAY on (3:3:-3), or none",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "bench", help="benchmark against the naive GTSAM formulation", description=cmd_bench.__doc__
    )
    from graphcal.bench.options import add_bench_arguments

    add_bench_arguments(p)
    p.set_defaults(func=cmd_bench)

    def vehicle_option(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--vehicle",
            type=Path,
            default=None,
            metavar="FILE",
            help="vehicle profile (TOML: nominal theta, sensor noise, ticks per revolution; "
            "data/vehicles/*.toml); default the paper's car",
        )

    def recording_options(p: argparse.ArgumentParser) -> None:
        g = p.add_argument_group(
            "recordings (a streams manifest or a ROS bag instead of a drive-log CSV)"
        )
        g.add_argument(
            "--rate",
            type=_in_range(1.0, 1000.0, "Hz"),
            default=None,
            metavar="HZ",
            help="rate of the drive log [Hz] (default: the manifest's rate, else 40)",
        )
        g.add_argument(
            "--max-gap",
            type=_at_least(0.01, "s"),
            default=None,
            metavar="S",
            help="a longer gap in any stream is masked [s] (default: the manifest's, else 0.5)",
        )
        g.add_argument("--pose-topic", default=None, help="bag: NavSatFix/Odometry/Pose topic")
        g.add_argument(
            "--wheel-topic",
            default=None,
            help="bag: JointState, Dataspeed WheelSpeedReport or PACMod WheelSpeedRpt topic (the "
            "last two are found by type), or the topic of --rear-left/--rear-right FIELDs",
        )
        g.add_argument("--imu-topic", default=None, help="bag: Imu topic (optional)")
        field = "TOPIC:FIELD, the field dotted into nested fields and indices: /car/wheels:w[2].v"
        g.add_argument(
            "--rear-left", default=None, metavar="JOINT|TOPIC:FIELD", help=f"bag: joint, or {field}"
        )
        g.add_argument(
            "--rear-right",
            default=None,
            metavar="JOINT|TOPIC:FIELD",
            help="bag: joint, or field (of --rear-left's topic when no TOPIC: is given)",
        )
        g.add_argument(
            "--wheel-kind",
            choices=["speed", "angular_speed", "rpm", "ticks", "angle"],
            default=None,
            help="bag: joints: positions (angle) [rad] or velocities (angular_speed) [rad/s] "
            "(default: positions if logged); fields: any, as [wheels] kind (a vendor message: "
            "angular_speed)",
        )
        g.add_argument(
            "--speed-unit",
            choices=["m/s", "km/h", "mph"],
            default=None,
            help="bag fields, --wheel-kind speed: their unit (default m/s)",
        )
        g.add_argument(
            "--circumference",
            type=_at_least(0.01, "m"),
            default=None,
            metavar="M",
            help="bag fields, --wheel-kind speed: the ECU's wheel circumference [m]",
        )
        g.add_argument(
            "--ticks-per-revolution",
            type=_at_least(1.0, "ticks"),
            default=None,
            metavar="N",
            help="bag fields, --wheel-kind ticks: counts per wheel revolution",
        )
        g.add_argument(
            "--heading",
            default=None,
            metavar="TOPIC:FIELD",
            help="bag: the heading from a field, at the pose's times (default unit rad, "
            "convention enu: REP 103)",
        )
        g.add_argument(
            "--heading-unit", choices=["rad", "deg"], default=None, help="bag: of --heading"
        )
        g.add_argument(
            "--heading-convention",
            choices=["enu", "compass"],
            default=None,
            help="bag: of --heading (enu: 0 = east, counter-clockwise; compass: 0 = north, "
            "clockwise)",
        )
        g.add_argument(
            "--yaw-rate",
            default=None,
            metavar="TOPIC:FIELD",
            help="bag: the yaw rate from a field instead of an Imu topic (default unit rad/s)",
        )
        g.add_argument(
            "--yaw-rate-unit", choices=["rad/s", "deg/s"], default=None, help="bag: of --yaw-rate"
        )
        g.add_argument(
            "--lateral-acceleration",
            default=None,
            metavar="TOPIC:FIELD",
            help="bag: the lateral acceleration [m/s², positive left] from a field",
        )

    p = sub.add_parser(
        "import",
        help="import a streams manifest or a ROS bag into a drive-log CSV",
        description=cmd_import.__doc__
        + " The manifest's keys are documented in graphcal/data/manifest.py and the README.",
    )
    p.add_argument(
        "source",
        type=recording_path,
        help="streams manifest (.toml, or the directory holding manifest.toml), ROS 1 bag, "
        "ROS 2 bag, MCAP",
    )
    p.add_argument("--out", type=Path, required=True, help="drive-log CSV to write (+ .json)")
    p.add_argument(
        "--help-manifest",
        action=_PrintManifestKeys,
        help="print every key of a streams manifest, with its default, and exit",
    )
    recording_options(p)
    segment_options(p)
    vehicle_option(p)
    p.set_defaults(func=cmd_import)

    p = sub.add_parser(
        "check", help="validate a drive log and summarize it", description=cmd_check.__doc__
    )
    p.add_argument("log", type=recording_path, help="drive-log CSV, streams manifest or ROS bag")
    segment_options(p)
    recording_options(p)
    vehicle_option(p)
    p.set_defaults(func=cmd_check)

    p = sub.add_parser(
        "calibrate", help="calibrate theta from a drive log", description=cmd_calibrate.__doc__
    )
    p.add_argument(
        "log",
        type=recording_path,
        help="drive-log CSV (t, px, py, psi, n_rl, n_rr, beta, ay), or a streams manifest (or "
        "its directory) or ROS bag (imported in memory)",
    )
    p.add_argument(
        "--out", type=Path, default=Path("results"), help="output directory (default results/)"
    )
    segment_options(p)
    p.add_argument(
        "--validation-length",
        type=_at_least(0.01, "m"),
        default=None,
        metavar="M",
        help="validation segment length [m] (default 300; with --vehicle scaled like "
        "--segment-length)",
    )
    p.add_argument(
        "--method",
        choices=list(METHODS),
        default="joint",
        help="joint (default): one graph over all selected segments for start poses, "
        "wheel-rotation corrections and theta together (the recommended theta with its "
        "covariance), then the same per batch; staged: the paper's five steps over batches; "
        "whole: only the solve over all selected segments, quick",
    )
    p.add_argument(
        "--batches",
        type=_whole(0),
        default=None,
        metavar="N",
        help="number of batches for staged and joint (default 100; the paper's study, §5.1, "
        "is 1000); 0 = one joint solve over the whole log (same as --method whole)",
    )
    p.add_argument(
        "--seed", type=_whole(0), default=None, help="seed of the batch draw (default 0)"
    )
    p.add_argument(
        "--batch-solve",
        choices=["linearized", "exact"],
        default=None,
        help="how the joint method solves its batches: linearized (default; every segment's "
        "system at the whole-log solution, summed per batch: a few thousandths of σ from "
        "exact on clean drives, up to 0.4σ with modelled slip) or exact (one solve per "
        "batch, 1–2 s each)",
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
    p.add_argument(
        "--no-defect-model",
        action="store_true",
        help="estimate theta alone: no wheel time offset, antenna lever arm, heading biases "
        "or outlier weights (the joint solve models them by default)",
    )
    recording_options(p)
    vehicle_option(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser(
        "fleet",
        help="calibrate a fleet's logs on Dask and find changes of theta",
        description=cmd_fleet.__doc__,
    )
    p.add_argument(
        "source",
        type=Path,
        help="a directory VEHICLE/DAY.csv (VEHICLE/vehicle.toml: that vehicle's profile) or a "
        "CSV manifest with columns vehicle, day, path (and optionally profile)",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="result directory (kept between runs: resumable)"
    )
    p.add_argument(
        "--workers",
        type=_whole(1),
        default=None,
        metavar="N",
        help="worker processes of the local Dask cluster (default: one per core)",
    )
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="a running Dask scheduler (tcp://HOST:8786) instead of a local cluster",
    )
    p.add_argument(
        "--alpha",
        type=_in_range(1e-12, 0.5, "probability"),
        default=1e-3,
        help="false-alarm probability of each day's test for a change of theta (0.001)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE",
        help="TOML settings file for every log (see graphcal/pipeline/settings.py)",
    )
    p.add_argument("--no-progress-bar", action="store_true", help="progress lines instead of a bar")
    segment_options(p)
    vehicle_option(p)
    p.set_defaults(func=cmd_fleet)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``graphcal`` console script; returns the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except GraphcalError as exc:
        print(f"graphcal: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt as exc:  # a note, if any, says what was kept and how to go on
        note = first_line(str(exc))
        print(f"graphcal: interrupted{f'; {note}' if note else ''}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `graphcal check LOG | head`: the reader left, not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
