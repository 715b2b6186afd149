"""How the shape of a recording changes graphcal's calibration: its error to the truth
against the σ it reports (the measurement behind issue 25's acceptance), and how it holds
with the length of the drive, its route and the vehicle.

    python scripts/recording_study.py --length-km 12 --seeds 0 1 2 --method whole \\
        --out recording_study.json --markdown recording_study.md

(the command that produced the tables in docs; restrict an axis with ``--rates 10``,
``--heading fused none``, ``--imu yes no``, ``--wheels speeds ticks``), and

    python scripts/recording_study.py --lengths 1 2 6 24 --routes city straight \\
        --vehicles car robot --seeds 0 1 2 --workers 1 --out sweep.json --markdown sweep.md

(the sweep over length, route and vehicle: a cliff such as "exit 0 at 1 km, exit 2 at 2 km"
is one table).

**The car.** A drive is simulated once per seed, length and route (``city``: bends, turns
and roundabouts; ``straight``: a straight road, where t_r and d are not observable) as raw
sensor streams at their own rates (:mod:`graphcal.simulate.streams`): GNSS fixes at 1, 5 or
10 Hz, rear wheels and IMU at 100 Hz. Every combination of

* GNSS rate: 1, 5, 10 Hz;
* heading: ``fused`` (an INS heading with 0.3° noise and its sideslip in ``[gnss]``) or
  ``none`` (the heading and sideslip keys removed from the manifest: the GNSS course is used);
* IMU: ``yes`` or ``no`` (the manifest's ``[imu]`` section removed);
* wheels: ``speeds`` (m/s from the ECU) or ``ticks`` (cumulative counts, 96 per revolution)

is written with :func:`~graphcal.simulate.streams.write_streams` into a temporary directory
(removed at the end unless ``--keep DIR``). When ``--lengths``, ``--routes`` or
``--vehicles`` is given and none of ``--rates``, ``--heading``, ``--imu``, ``--wheels``, the
car's recordings are restricted to :data:`REPRESENTATIVE`: (10 Hz, heading none, IMU no,
speeds), a plain receiver, and (10 Hz, heading fused, IMU yes, speeds), a full INS; a shape
option given restores the cross product of the shape options (the others at their full
defaults). Streams of different rates and wheel kinds come from separate
``simulate_streams`` calls with the same seed; the script checks that they sample the same
noise-free drive and the same ``theta_true``. The heading and IMU variants are edited copies
of one manifest over the same CSV files. As a reference, the 40 Hz drive-log CSV of the same
drive (what ``graphcal simulate --out`` writes: ``simulate_drive`` with the same seed, length
and route, the paper's noise) is calibrated the same way per seed. One 10 Hz recording is

    graphcal simulate --length-km L --seed S --route R --heading-noise-deg 0.3 \\
        [--wheel-kind ticks] --streams DIR

(heading none: the ``heading*`` and ``sideslip*`` lines of ``DIR/manifest.toml`` deleted;
IMU no: its ``[imu]`` section, the last, deleted); each run's ``reproduce`` in the JSON says
it in full.

**The robot** (``--vehicles robot``) is ``--robot-profile`` (default
``data/vehicles/mocap_robot.toml``) simulated by :func:`graphcal.simulate.robot.simulate_robot`
with the profile's noise and encoder resolution (``RobotSettings.from_vehicle``, no
reversing) and ``theta_true_for(profile)``: runs of 5–15 m with spins on the spot and stops,
motion-capture poses at 50 Hz and 2797-tick encoder counts at 100 Hz, no IMU — its own
recording, the one shape of its rows; exactly ``graphcal simulate --vehicle PROFILE --runs N
--seed S --streams DIR``. Its "length" L km is ``N = max(1, round(--runs-per-km × L))``
runs (default 10 per km: 1 km ↔ the CLI's default 10 runs, about 0.1 km driven; the
driven distance is in the table's ``driven`` column). Its route is ``hall`` whatever
``--routes`` says. Its reference is the drive-log CSV of the same simulation at the pose
rate (``graphcal simulate --vehicle PROFILE --runs N --seed S --out drive.csv``). Both are
calibrated with ``--vehicle PROFILE``.

**Calibrating as the CLI does**: ``graphcal calibrate PATH --method METHOD --workers W
[--vehicle PROFILE] --out RESULTS``, step by step as :func:`graphcal.cli.calibrate.run`: the
settings from ``graphcal.cli.options.settings_from_args`` on that command line built by
``graphcal.cli.build_parser`` (so they follow the CLI's defaults), then
:func:`graphcal.calibrate_file` (open the log as :func:`graphcal.open_log` does, calibrate,
the import's warnings in front of the run's), then :func:`graphcal.synthetic_truth`,
:func:`graphcal.evaluate`, :func:`graphcal.write_results` (into a ``results-*`` directory
beside the recording: its ``calibration.json`` is kept with ``--keep``) and
:func:`graphcal.summary_text`. The exit status the CLI would give is recorded: 0, 3 for a
result not trusted, 2 for a :class:`graphcal.GraphcalError` (one line, no result), 1 for any
other exception (a crash). The load is timed apart from the calibration (up to the
"imported"/"loaded" progress line), and the evaluation and writing apart from both.

Per run and parameter (c_e, c_d, t_r, d) the estimate, the reported σ (the square root of
the covariance's diagonal), the error to the truth and error/σ, the verdict, whether the run
is trusted (``run.trust.doubts`` empty: exit 0 rather than 3), the import's warnings, the
wall times, graphcal's progress lines, and the first line of any exception (a failing run
is recorded, it never stops the study; a failed simulation fails the runs it would have
made). Per row (vehicle, length, route and recording shape), over the seeds: trusted runs
n/N, the driven distance, the worst |error/σ| and the mean (error/σ)² per parameter, and the
mean σ per parameter in mm (d in mm·s²/m) with its ratio to the reference CSV's σ of the
same seed. The statistics of error/σ use the parameters whose observability verdict is
``calibrated`` (a run's trust doubts do not remove its parameters from them: an untrusted
run already fails the study's criteria).

Two verdicts close the markdown:

* **Study** (as before, over the streams recordings, references not included): every run
  trusted (a failed run is not), every calibrated parameter within 3σ, the mean (error/σ)²
  over all runs at most 2 per parameter; a parameter calibrated in no run is noted.
* **Acceptance** (the issue's, over every run: recordings and references, every length,
  route and vehicle): no failed run (exit 2, or a crash); every *trusted* run's calibrated
  parameters within 3σ; the mean (error/σ)² over the trusted runs' calibrated parameters at
  most 2 per parameter. An untrusted run (exit 3) is listed but not failed by it.

The rows that break a criterion (a failed or untrusted run, a calibrated parameter beyond
3σ, a row's mean (error/σ)² above 2) are listed under the tables with their runs.

Deterministic given the seeds (except the wall times): the results do not depend on
``--workers``.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal import (
    GraphcalError,
    RobotSettings,
    calibrate_file,
    evaluate,
    load_vehicle,
    simulate_robot,
    summary_text,
    synthetic_truth,
    theta_true_for,
    write_results,
)
from graphcal.cli import build_parser
from graphcal.cli.options import recording_keywords, settings_from_args
from graphcal.errors import first_line
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.solvers.parallel import default_workers
from graphcal.recording.manifest.manifest import load_manifest
from graphcal.simulate.drive import VehicleMotion, simulate_drive, write_synthetic_drive
from graphcal.simulate.streams import StreamSettings, simulate_streams, write_streams
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS

RATES = (1.0, 5.0, 10.0)
HEADINGS = ("fused", "none")
IMUS = ("yes", "no")
WHEELS = ("speeds", "ticks")
ROUTES = ("city", "straight")
VEHICLES = ("car", "robot")
#: The car's recording shapes (rate, heading, IMU, wheels) when the length, route or vehicle
#: axis is swept without a shape option: a plain receiver and a full INS.
REPRESENTATIVE = ((10.0, "none", "no", "speeds"), (10.0, "fused", "yes", "speeds"))
#: Heading noise of the fused (INS) heading [rad].
FUSED_HEADING_NOISE = float(np.deg2rad(0.3))
TICKS_PER_REVOLUTION = 96
#: The route of the study without --routes.
ROUTE = "city"
#: The robot's route (it drives runs in a motion-capture hall, whatever --routes says).
ROBOT_ROUTE = "hall"
ROBOT_PROFILE = Path(__file__).resolve().parents[1] / "data" / "vehicles" / "mocap_robot.toml"
#: Robot runs per km of --lengths: 1 km is the CLI's default 10 runs.
RUNS_PER_KM = 10.0
#: The car's drive-log CSV rate [Hz] (``graphcal simulate``'s --dt 0.025).
CAR_CSV_RATE = 40.0
#: Pass criteria: |error/σ| of every calibrated parameter, mean (error/σ)² per parameter.
MAX_ABS_Z = 3.0
MAX_MEAN_Z2 = 2.0
#: Keys of the manifest's [gnss] section that carry the heading and the sideslip.
HEADING_KEYS = ("heading", "heading_unit", "heading_convention", "sideslip", "sideslip_unit")
#: The CLI's exit statuses.
EXIT_OK, EXIT_CRASH, EXIT_BAD_INPUT, EXIT_UNTRUSTED = 0, 1, 2, 3


@dataclass(frozen=True)
class Drive:
    """What is driven: a vehicle, a length [km] and a route (the robot: ``runs`` runs)."""

    vehicle: str
    length_km: float
    route: str
    runs: int | None = None
    #: [Hz] of its reference drive-log CSV.
    csv_rate: float = 40.0

    def label(self) -> str:
        runs = f" ({self.runs} runs)" if self.runs is not None else ""
        return f"{self.vehicle} {self.length_km:g} km{runs} {self.route}"

    def slug(self) -> str:
        return f"{self.vehicle}-{self.length_km:g}km-{self.route}"

    def key(self) -> dict:
        return {
            "vehicle": self.vehicle,
            "length_km": self.length_km,
            "route": self.route,
            "runs": self.runs,
        }


@dataclass(frozen=True)
class Shape:
    """The shape of a recording: pose rate [Hz], heading, IMU, wheels."""

    rate: float
    heading: str
    imu: str
    wheels: str

    def label(self) -> str:
        return f"{self.rate:g} Hz, heading {self.heading}, IMU {self.imu}, wheels {self.wheels}"

    def key(self) -> dict:
        return {
            "rate_hz": self.rate,
            "heading": self.heading,
            "imu": self.imu,
            "wheels": self.wheels,
        }


@dataclass(frozen=True)
class Case:
    """One row: a drive and a recording shape (``shape`` ``None``: the reference CSV)."""

    drive: Drive
    shape: Shape | None

    def label(self) -> str:
        what = reference_label(self.drive) if self.shape is None else self.shape.label()
        return f"{self.drive.label()}, {what}"

    def key(self) -> dict:
        if self.shape is None:
            shape = {"rate_hz": self.drive.csv_rate, "heading": None, "imu": None, "wheels": None}
        else:
            shape = self.shape.key()
        return {
            **self.drive.key(),
            "recording": "csv" if self.shape is None else "streams",
            **shape,
        }


def robot_shape(profile: Path) -> Shape:
    """The robot's one recording: motion capture at its pose rate, encoder ticks, no IMU."""
    settings = robot_settings(profile)
    return Shape(settings.pose_rate, "mocap", "no", f"ticks ({settings.ticks_per_revolution})")


def robot_settings(profile: Path) -> RobotSettings:
    """As ``graphcal simulate --vehicle PROFILE`` (no --reversing, the profile's noise)."""
    return RobotSettings.from_vehicle(load_vehicle(profile), reversing=False)


def reference_label(drive: Drive) -> str:
    return f"{drive.csv_rate:g} Hz CSV"


# --- Simulation and manifests ----------------------------------------------------------------


def write_recording(
    directory: Path,
    seed: int,
    length_km: float,
    rate: float,
    wheels: str,
    motion: VehicleMotion,
    route: str = ROUTE,
) -> tuple[Path, np.ndarray, np.ndarray]:
    """Simulate the car's streams of one GNSS rate and wheel kind into ``directory``.

    Returns the manifest, ``theta_true`` and the noise-free drive's positions ``(2, N)``
    (to check that every recording of a seed samples the same drive)."""
    settings = StreamSettings(
        gnss_rate=rate,
        heading_noise=FUSED_HEADING_NOISE,
        wheel_kind="ticks" if wheels == "ticks" else "speed",
        ticks_per_revolution=TICKS_PER_REVOLUTION,
    )
    sim = simulate_streams(length_km, seed, settings=settings, motion=motion, route=route)
    write_streams(sim, directory)
    return (
        directory / "manifest.toml",
        truth_of(directory),
        np.vstack([sim.drive.truth.px, sim.drive.truth.py]),
    )


def truth_of(directory: Path) -> np.ndarray:
    """``theta_true`` of the recording in ``directory`` (its ``truth.json``)."""
    truth = json.loads((directory / "truth.json").read_text())["theta_true"]
    return np.array([truth[name] for name in PARAMETER_NAMES])


def edit_manifest(text: str, drop_heading: bool, drop_imu: bool) -> str:
    """The manifest ``text`` without the heading and sideslip keys of ``[gnss]`` and/or
    without the ``[imu]`` section (line by line: the simulated manifest has one key a line)."""
    out, section = [], None
    for line in text.splitlines(keepends=True):
        header = re.match(r"\s*\[([^\]]+)\]", line)
        if header:
            section = header.group(1).strip()
        key = line.split("=", 1)[0].strip() if "=" in line and not header else None
        if drop_imu and section == "imu":
            continue
        if drop_heading and section == "gnss" and key in HEADING_KEYS:
            continue
        out.append(line)
    return "".join(out)


def manifest_variant(manifest: Path, heading: str, imu: str) -> Path:
    """A copy of ``manifest`` (same CSV files) for the heading and IMU of a case, checked."""
    text = edit_manifest(manifest.read_text(), heading == "none", imu == "no")
    path = manifest.with_name(f"manifest-heading-{heading}-imu-{imu}.toml")
    path.write_text(text)
    parsed = load_manifest(path)
    has_heading = any(key in parsed.pose for key in HEADING_KEYS)
    if has_heading != (heading == "fused") or (parsed.imu is not None) != (imu == "yes"):
        raise RuntimeError(
            f"{path}: the edited manifest does not describe heading {heading}, IMU {imu}"
        )
    return path


def simulate_command(case: Case, seed: int, profile: Path, directory: str = "DIR") -> str:
    """The ``graphcal simulate`` command line (and manifest edits) of one case's recording."""
    drive, shape = case.drive, case.shape
    if drive.vehicle == "robot":
        head = f"graphcal simulate --vehicle {profile} --runs {drive.runs} --seed {seed}"
        if shape is None:
            return f"{head} --out {directory}/drive.csv"
        return f"{head} --streams {directory}"
    head = f"graphcal simulate --length-km {drive.length_km:g} --seed {seed} --route {drive.route}"
    if shape is None:
        return f"{head} --out {directory}/drive.csv"
    if shape.rate != 10.0:  # the CLI's streams are 10 Hz; other rates only through this script
        return ""
    wheels = " --wheel-kind ticks" if shape.wheels == "ticks" else ""
    command = f"{head} --heading-noise-deg 0.3{wheels} --streams {directory}"
    if shape.heading == "none":
        command += (
            " && sed -i -E '/^(heading|heading_unit|heading_convention|sideslip|sideslip_unit) ="
            f"/d' {directory}/manifest.toml"
        )
    if shape.imu == "no":
        command += f" && sed -i '/^\\[imu\\]/,$d' {directory}/manifest.toml"
    return command


def reproduce(case: Case, seed: int, method: str, workers: int, profile: Path) -> str:
    """Commands that make and calibrate this one recording outside the study."""
    study = (
        f"python scripts/recording_study.py --seeds {seed} --lengths {case.drive.length_km:g} "
        f"--vehicles {case.drive.vehicle} --method {method} --workers {workers} --keep KEEP"
    )
    if case.drive.vehicle == "car":
        study += f" --routes {case.drive.route}"
        if case.shape is not None:
            s = case.shape
            study += f" --rates {s.rate:g} --heading {s.heading} --imu {s.imu} --wheels {s.wheels}"
    simulate = simulate_command(case, seed, profile)
    vehicle = f" --vehicle {profile}" if case.drive.vehicle == "robot" else ""
    target = "DIR/drive.csv" if case.shape is None else "DIR"
    calibrate = (
        f"graphcal calibrate {target} --method {method} --workers {workers}{vehicle} --out RESULTS"
    )
    cli = f"{simulate} && {calibrate}" if simulate else ""
    return f"{cli}  # or: {study}" if cli else study


# --- Calibration as `graphcal calibrate PATH --method METHOD` ---------------------------------


def calibrate_like_cli(
    path: Path,
    method: str,
    workers: int,
    profile: Path | None,
    out: Path,
    progress: Callable[[str], None],
) -> tuple:
    """``graphcal calibrate PATH --method METHOD --workers W [--vehicle PROFILE] --out OUT``,
    step by step as :func:`graphcal.cli.calibrate.run`.

    Returns the run, the import (``None`` for a CSV) and the wall times [s] of loading,
    calibrating and evaluating with writing the results."""
    argv = [
        "calibrate",
        str(path),
        "--method",
        method,
        "--workers",
        str(workers),
        "--out",
        str(out),
    ]
    if profile is not None:
        argv += ["--vehicle", str(profile)]
    args = build_parser().parse_args(argv)
    settings = settings_from_args(args)
    marks: dict[str, float] = {}

    def say(line: str) -> None:
        if "loaded" not in marks and re.match(r"(imported|loaded) ", line):
            marks["loaded"] = time.perf_counter()
        progress(line)

    started = time.perf_counter()
    run, imported = calibrate_file(
        args.log, settings, method, progress=say, workers=workers, **recording_keywords(args)
    )
    calibrated = time.perf_counter()
    truth = synthetic_truth(run, args.log, imported, say)
    evaluation = None if truth is None else evaluate(run, truth, say, workers)
    write_results(run, args.out, evaluation=evaluation)
    summary_text(run, evaluation)
    loaded = marks.get("loaded", started)
    seconds = {
        "load": loaded - started,
        "calibrate": calibrated - loaded,
        "evaluate_and_write": time.perf_counter() - calibrated,
    }
    return run, imported, seconds


def run_record(
    path: Path,
    theta_true: np.ndarray,
    args: argparse.Namespace,
    profile: Path | None,
    label: str,
) -> dict:
    """One calibration's numbers (SI); ``failed`` holds the exception's first line, if any,
    and ``exit`` the CLI's exit status."""
    record: dict = {"source": str(path), "failed": None, "progress": []}
    started = time.perf_counter()

    def progress(line: str) -> None:
        record["progress"].append(f"[{time.perf_counter() - started:7.1f} s] {line}")
        if args.verbose:
            print(f"    [{label}] {line}", file=sys.stderr, flush=True)

    out = path.parent / f"results-{path.stem}"
    record["results"] = str(out)
    try:
        run, imported, seconds = calibrate_like_cli(
            path, args.method, args.workers, profile, out, progress
        )
        truth = imported.truth if imported is not None else None
        if truth is not None and not np.allclose(truth, theta_true, rtol=0, atol=1e-12):
            raise RuntimeError(f"{path.name}: the manifest's theta_true differs from the drive's")
        sigma = np.sqrt(np.diag(run.covariance))
        error = run.theta - theta_true
        verdicts = run.verdicts()
        observability = run.observability.verdicts()
        record["parameters"] = {
            name: {
                "estimate": float(run.theta[i]),
                "sigma": float(sigma[i]),
                "error": float(error[i]),
                "z": float(error[i] / sigma[i]) if sigma[i] > 0 else None,
                "verdict": verdicts[name],
                "observability": observability[name],
            }
            for i, name in enumerate(PARAMETER_NAMES)
        }
        record.update(
            trusted=bool(run.trust.trusted),
            exit=EXIT_OK if run.trust.trusted else EXIT_UNTRUSTED,
            doubts=list(run.trust.doubts),
            chi2_per_dof=run.trust.chi2_per_dof,
            import_warnings=list(imported.warnings) if imported is not None else [],
            warnings=list(run.warnings),
            seconds=seconds,
            distance_m=float(run.log.travelled_distance(theta_true[0])[-1]),
        )
    except Exception as exc:  # a failing case is a result, not the end of the study
        status = EXIT_BAD_INPUT if isinstance(exc, GraphcalError) else EXIT_CRASH
        record.update(
            trusted=False, exit=status, failed=f"{type(exc).__name__}: {first_line(str(exc))}"
        )
    record["wall_s"] = time.perf_counter() - started
    return record


def failed_record(source: str, exc: BaseException) -> dict:
    """A run that could not be made (its simulation failed)."""
    return {
        "source": source,
        "failed": f"simulation: {type(exc).__name__}: {first_line(str(exc))}",
        "trusted": False,
        "exit": None,
        "progress": [],
        "wall_s": 0.0,
    }


# --- The study --------------------------------------------------------------------------------


def new_axes(args: argparse.Namespace) -> bool:
    """Whether the length, route or vehicle axis is swept."""
    return any(v is not None for v in (args.lengths, args.routes, args.vehicles))


def car_shapes(args: argparse.Namespace) -> list[Shape]:
    """The car's recording shapes: the cross product of the shape options, or
    :data:`REPRESENTATIVE` when a new axis is swept and no shape option is given."""
    given = [args.rates, args.heading, args.imu, args.wheels]
    if new_axes(args) and all(v is None for v in given):
        return [Shape(*shape) for shape in REPRESENTATIVE]
    return [
        Shape(rate, heading, imu, wheels)
        for rate in args.rates or RATES
        for heading in args.heading or HEADINGS
        for imu in args.imu or IMUS
        for wheels in args.wheels or WHEELS
    ]


def robot_runs(length_km: float, runs_per_km: float) -> int:
    return max(1, round(runs_per_km * length_km))


def drives_of(args: argparse.Namespace) -> list[Drive]:
    """Every drive: vehicles × lengths × routes (the robot once per length, in its hall)."""
    lengths = args.lengths or [args.length_km]
    drives = []
    for vehicle in args.vehicles or ["car"]:
        for length in lengths:
            if vehicle == "robot":
                runs = robot_runs(length, args.runs_per_km)
                rate = robot_settings(args.robot_profile).rate
                drives.append(Drive("robot", length, ROBOT_ROUTE, runs, rate))
                continue
            for route in args.routes or [ROUTE]:
                drives.append(Drive("car", length, route, None, CAR_CSV_RATE))
    return drives


def cases_of(args: argparse.Namespace) -> list[Case]:
    """Every streams row (references not included)."""
    cases = []
    for drive in drives_of(args):
        shapes = [robot_shape(args.robot_profile)] if drive.vehicle == "robot" else car_shapes(args)
        cases += [Case(drive, shape) for shape in shapes]
    return cases


def references_of(args: argparse.Namespace) -> list[Case]:
    return [Case(drive, None) for drive in drives_of(args)]


def _mark(record: dict, case: Case, seed: int, args: argparse.Namespace) -> dict:
    record.update(seed=seed, case=case.label(), **case.key())
    record["reproduce"] = reproduce(case, seed, args.method, args.workers, args.robot_profile)
    return record


def run_car(
    drive: Drive, seed: int, directory: Path, args: argparse.Namespace, cases: list[Case]
) -> tuple[dict, list[dict]]:
    """The car's reference CSV and streams recordings of one seed: ``(reference, runs)``."""
    motion = VehicleMotion(rear_cornering_stiffness=args.rear_cornering_stiffness)
    reference = Case(drive, None)
    theta_true = None
    try:
        sim = simulate_drive(drive.length_km, seed, motion=motion, route=drive.route)
        csv_path = directory / "drive.csv"
        csv_path.parent.mkdir(parents=True, exist_ok=True)
        write_synthetic_drive(sim, csv_path)
        theta_true = np.asarray(sim.theta_true, dtype=float)
        csv_record = run_record(
            csv_path, theta_true, args, None, f"{reference.label()}, seed {seed}"
        )
    except Exception as exc:
        csv_record = failed_record(str(directory / "drive.csv"), exc)
    _mark(csv_record, reference, seed, args)
    print(run_line(reference.label(), seed, csv_record), flush=True)

    runs: list[dict] = []
    track = None
    for rate, wheels in dict.fromkeys((c.shape.rate, c.shape.wheels) for c in cases):
        mine = [c for c in cases if (c.shape.rate, c.shape.wheels) == (rate, wheels)]
        sub = directory / f"gnss{rate:g}hz-{wheels}"
        try:
            manifest, truth, this_track = write_recording(
                sub, seed, drive.length_km, rate, wheels, motion, drive.route
            )
            if theta_true is not None and not np.array_equal(truth, theta_true):
                raise RuntimeError(f"seed {seed}: {sub.name} has another theta_true")
            if track is None:
                track = this_track
            elif not np.array_equal(track, this_track):
                raise RuntimeError(f"seed {seed}: {sub.name} samples another drive")
        except Exception as exc:
            for case in mine:
                record = _mark(failed_record(str(sub), exc), case, seed, args)
                runs.append(record)
                print(run_line(case.label(), seed, record), flush=True)
            continue
        for case in mine:
            try:
                path = manifest_variant(manifest, case.shape.heading, case.shape.imu)
            except Exception as exc:
                record = failed_record(str(manifest), exc)
            else:
                record = run_record(path, truth, args, None, f"{case.label()}, seed {seed}")
            runs.append(_mark(record, case, seed, args))
            print(run_line(case.label(), seed, record), flush=True)
    return csv_record, runs


def run_robot(
    drive: Drive, seed: int, directory: Path, args: argparse.Namespace, cases: list[Case]
) -> tuple[dict, list[dict]]:
    """The robot's reference CSV and its recording of one seed: ``(reference, runs)``."""
    profile = args.robot_profile
    reference = Case(drive, None)
    try:
        vehicle = load_vehicle(profile)
        sim = simulate_robot(seed, drive.runs, robot_settings(profile), theta_true_for(vehicle))
        streams = directory / "streams"
        write_streams(sim, streams)
        csv_path = directory / "drive.csv"
        write_synthetic_drive(sim.drive, csv_path)
        theta_true = np.asarray(sim.drive.theta_true, dtype=float)
        if not np.array_equal(truth_of(streams), theta_true):
            raise RuntimeError(f"seed {seed}: the streams' truth.json has another theta_true")
    except Exception as exc:
        csv_record = _mark(failed_record(str(directory), exc), reference, seed, args)
        print(run_line(reference.label(), seed, csv_record), flush=True)
        runs = [_mark(failed_record(str(directory), exc), case, seed, args) for case in cases]
        for case, record in zip(cases, runs, strict=True):
            print(run_line(case.label(), seed, record), flush=True)
        return csv_record, runs
    csv_record = run_record(
        csv_path, theta_true, args, profile, f"{reference.label()}, seed {seed}"
    )
    _mark(csv_record, reference, seed, args)
    print(run_line(reference.label(), seed, csv_record), flush=True)
    runs = []
    for case in cases:  # one shape: the simulator's own recording
        record = run_record(
            streams / "manifest.toml", theta_true, args, profile, f"{case.label()}, seed {seed}"
        )
        runs.append(_mark(record, case, seed, args))
        print(run_line(case.label(), seed, record), flush=True)
    return csv_record, runs


def run_study(args: argparse.Namespace) -> tuple[list[dict], list[dict]]:
    """Every case and reference CSV for every drive and seed: ``(case runs, CSV runs)``."""
    cases = cases_of(args)
    runs: list[dict] = []
    csv_runs: list[dict] = []
    keep = args.keep
    root = Path(keep) if keep is not None else Path(tempfile.mkdtemp(prefix="recording_study-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        for drive in drives_of(args):
            mine = [c for c in cases if c.drive == drive]
            for seed in args.seeds:
                print(f"-- {drive.label()}, seed {seed}", flush=True)
                directory = root / drive.slug() / f"seed{seed}"
                directory.mkdir(parents=True, exist_ok=True)
                go = run_robot if drive.vehicle == "robot" else run_car
                csv_record, these = go(drive, seed, directory, args, mine)
                csv_runs.append(csv_record)
                runs += these
    finally:
        if keep is None:
            shutil.rmtree(root, ignore_errors=True)
    return runs, csv_runs


def run_line(label: str, seed: int, record: dict) -> str:
    """One progress line per run."""
    head = f"{label}, seed {seed}:"
    if record["failed"]:
        status = "" if record.get("exit") is None else f", exit {record['exit']}"
        return f"{head} FAILED ({record['wall_s']:.1f} s{status}): {record['failed']}"
    cells = []
    for i, (name, p) in enumerate(record["parameters"].items()):
        scale, unit = DEVIATION_SCALE[i], DEVIATION_UNITS[i]
        mark = "" if p["observability"] == "calibrated" else f" [{p['observability']}]"
        z = "—" if p["z"] is None else f"{p['z']:+.2f}σ"
        cells.append(f"{name} {z} (σ {p['sigma'] * scale:.3g} {unit}){mark}")
    trust = "trusted" if record["trusted"] else "NOT trusted (exit 3)"
    return f"{head} {'; '.join(cells)}; {trust}; {record['wall_s']:.1f} s"


# --- Summaries --------------------------------------------------------------------------------


def _calibrated(record: dict, name: str) -> bool:
    p = record["parameters"][name]
    return p["observability"] == "calibrated" and p["z"] is not None


def calibrated_z(records: Iterable[dict], name: str, trusted_only: bool = False) -> np.ndarray:
    """error/σ of ``name`` over the successful runs where its verdict is ``calibrated``
    (``trusted_only``: over the trusted ones)."""
    return np.array(
        [
            r["parameters"][name]["z"]
            for r in records
            if not r["failed"] and (r["trusted"] or not trusted_only) and _calibrated(r, name)
        ]
    )


def _is(record: dict, case: Case) -> bool:
    return all(record[k] == v for k, v in case.key().items())


def summarize(
    runs: list[dict], csv_runs: list[dict], cases: list[Case], references: list[Case]
) -> list[dict]:
    """One summary per row over the seeds, each drive's reference first (numbers in SI;
    ``None`` where none)."""
    rows = []
    for reference in references:
        ref_records = [r for r in csv_runs if _is(r, reference)]
        ref_sigma = {
            r["seed"]: np.array([r["parameters"][n]["sigma"] for n in PARAMETER_NAMES])
            for r in ref_records
            if not r["failed"]
        }
        for case in [reference, *[c for c in cases if c.drive == reference.drive]]:
            records = ref_records if case.shape is None else [r for r in runs if _is(r, case)]
            rows.append(_summary(case, records, None if case.shape is None else ref_sigma))
    return rows


def _summary(case: Case, records: list[dict], ref_sigma: dict | None) -> dict:
    summary: dict = {"case": case.key(), "label": case.label()}
    if case.shape is None:
        summary["reference"] = reference_label(case.drive)
    ok = [r for r in records if not r["failed"]]
    summary["runs"] = len(records)
    summary["trusted"] = sum(bool(r["trusted"]) for r in records)
    summary["exits"] = [r.get("exit") for r in records]
    summary["failed"] = [f"seed {r['seed']}: {r['failed']}" for r in records if r["failed"]]
    summary["untrusted"] = [
        f"seed {r['seed']}: " + "; ".join(r["doubts"]) for r in ok if not r["trusted"]
    ]
    distances = [r["distance_m"] for r in ok if "distance_m" in r]
    summary["mean_distance_m"] = float(np.mean(distances)) if distances else None
    for i, name in enumerate(PARAMETER_NAMES):
        z = calibrated_z(records, name)
        sigma = np.array([r["parameters"][name]["sigma"] for r in ok])
        ratios = np.array(
            [
                r["parameters"][name]["sigma"] / ref_sigma[r["seed"]][i]
                for r in ok
                if ref_sigma is not None and r["seed"] in ref_sigma and ref_sigma[r["seed"]][i] > 0
            ]
        )
        summary[name] = {
            "calibrated": len(z),
            "max_abs_z": float(np.max(np.abs(z))) if len(z) else None,
            "mean_z2": float(np.mean(z**2)) if len(z) else None,
            "mean_sigma": float(np.mean(sigma)) if len(sigma) else None,
            "sigma_over_reference": float(np.mean(ratios)) if len(ratios) else None,
        }
    summary["breaks"] = row_breaks(records)
    return summary


def row_breaks(records: list[dict]) -> list[str]:
    """What in one row breaks a criterion: failed or untrusted runs, calibrated parameters
    beyond 3σ, a mean (error/σ)² above 2."""
    breaks = []
    failed = [r for r in records if r["failed"]]
    if failed:
        exits = sorted({str(r.get("exit")) for r in failed})
        breaks.append(f"{len(failed)} failed (exit {'/'.join(exits)})")
    untrusted = [r for r in records if not r["failed"] and not r["trusted"]]
    if untrusted:
        breaks.append(f"{len(untrusted)} not trusted (exit 3)")
    for name in PARAMETER_NAMES:
        z = calibrated_z(records, name)
        outside = [
            f"{r['seed']}"
            for r in records
            if not r["failed"]
            and _calibrated(r, name)
            and abs(r["parameters"][name]["z"]) > MAX_ABS_Z
        ]
        if outside:
            breaks.append(f"{name} beyond {MAX_ABS_Z:g}σ (seed {', '.join(outside)})")
        if len(z) and np.mean(z**2) > MAX_MEAN_Z2:
            breaks.append(f"{name} mean (e/σ)² {np.mean(z**2):.2f}")
    return breaks


def verdict(runs: list[dict]) -> tuple[bool, list[str], list[str]]:
    """The study's pass/fail of the streams runs: ``(passed, why it fails, notes)``: every
    run trusted, every calibrated parameter within 3σ, the mean (error/σ)² over all runs at
    most 2 per parameter. A parameter calibrated in no run is a note, not a failure."""
    reasons, notes = [], []
    if not runs:
        reasons.append("no runs")
    untrusted = [r for r in runs if not r["trusted"]]
    if untrusted:
        failed = sum(bool(r["failed"]) for r in untrusted)
        reasons.append(
            f"{len(untrusted)} of {len(runs)} runs not trusted ({failed} of them failed)"
        )
    for name in PARAMETER_NAMES:
        z = calibrated_z(runs, name)
        if not len(z):
            notes.append(f"{name} calibrated in no run")
            continue
        outside = int((np.abs(z) > MAX_ABS_Z).sum())
        if outside:
            reasons.append(f"{name}: {outside} of {len(z)} calibrated beyond {MAX_ABS_Z:g}σ")
        if np.mean(z**2) > MAX_MEAN_Z2:
            reasons.append(f"{name}: mean (error/σ)² {np.mean(z**2):.2f} > {MAX_MEAN_Z2:g}")
    return not reasons, reasons, notes


def acceptance(records: list[dict]) -> tuple[bool, list[str], list[str]]:
    """The issue's acceptance over every run (recordings and references, every length,
    route and vehicle): no failed run; every trusted run's calibrated parameters within 3σ;
    mean (error/σ)² over the trusted runs at most 2 per parameter. ``(passed, reasons,
    notes)``; untrusted runs are a note."""
    reasons, notes = [], []
    if not records:
        reasons.append("no runs")
    failed = [r for r in records if r["failed"]]
    if failed:
        where = sorted({f"{r['vehicle']} {r['length_km']:g} km {r['route']}" for r in failed})
        reasons.append(f"{len(failed)} of {len(records)} runs failed ({'; '.join(where)})")
    untrusted = [r for r in records if not r["failed"] and not r["trusted"]]
    if untrusted:
        where = sorted({f"{r['vehicle']} {r['length_km']:g} km {r['route']}" for r in untrusted})
        notes.append(f"{len(untrusted)} runs not trusted, exit 3 ({'; '.join(where)})")
    for name in PARAMETER_NAMES:
        z = calibrated_z(records, name, trusted_only=True)
        if not len(z):
            notes.append(f"{name} calibrated in no trusted run")
            continue
        outside = int((np.abs(z) > MAX_ABS_Z).sum())
        if outside:
            reasons.append(f"{name}: {outside} of {len(z)} trusted beyond {MAX_ABS_Z:g}σ")
        if np.mean(z**2) > MAX_MEAN_Z2:
            reasons.append(f"{name}: mean (error/σ)² {np.mean(z**2):.2f} > {MAX_MEAN_Z2:g}")
    return not reasons, reasons, notes


def _number(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def _row_cells(summary: dict) -> list[str]:
    case = summary["case"]
    length = f"{case['length_km']:g} km"
    if case["runs"] is not None:
        length += f" ({case['runs']} runs)"
    head = [case["vehicle"], length, case["route"]]
    if case["recording"] == "csv":
        return [*head, summary["reference"], "", "", ""]
    return [*head, f"{case['rate_hz']:g} Hz", case["heading"], case["imu"], case["wheels"]]


HEAD = ["vehicle", "length", "route", "pose", "heading", "IMU", "wheels"]


def _escape(text: str) -> str:
    return text.replace("|", "\\|")


def markdown(
    summaries: list[dict],
    study: tuple[bool, list[str], list[str]],
    accepted: tuple[bool, list[str], list[str]],
    runs: list[dict],
    command: str,
    wall_s: float,
) -> str:
    """The two tables (accuracy; σ), the rows that break a criterion and the two verdicts."""
    names = PARAMETER_NAMES
    accuracy = [
        "| "
        + " | ".join(
            HEAD
            + ["driven [km]", "trusted", "exits"]
            + [f"max \\|e/σ\\| {n}" for n in names]
            + [f"mean (e/σ)² {n}" for n in names]
            + ["breaks", "failures"]
        )
        + " |",
        "|" + "---|" * (len(HEAD) + 3 + 2 * len(names) + 2),
    ]
    for s in summaries:
        distance = "—" if s["mean_distance_m"] is None else f"{s['mean_distance_m'] / 1000:.2f}"
        exits = ",".join("–" if e is None else str(e) for e in s["exits"])
        cells = [*_row_cells(s), distance, f"{s['trusted']}/{s['runs']}", exits]
        cells += [_number(s[n]["max_abs_z"]) for n in names]
        cells += [_number(s[n]["mean_z2"]) for n in names]
        cells.append("**" + "; ".join(s["breaks"]) + "**" if s["breaks"] else "")
        cells.append(_escape("<br>".join(s["failed"] + s["untrusted"])))
        accuracy.append("| " + " | ".join(cells) + " |")
    sigma = [
        "| "
        + " | ".join(
            HEAD
            + [f"σ {n} [{u}] (× reference)" for n, u in zip(names, DEVIATION_UNITS, strict=True)]
        )
        + " |",
        "|" + "---|" * (len(HEAD) + len(names)),
    ]
    for s in summaries:
        cells = _row_cells(s)
        for i, n in enumerate(names):
            p = s[n]
            if p["mean_sigma"] is None:
                cells.append("—")
                continue
            ratio = (
                ""
                if p["sigma_over_reference"] is None
                else f" ({_number(p['sigma_over_reference'])}×)"
            )
            cells.append(f"{p['mean_sigma'] * DEVIATION_SCALE[i]:.3g}{ratio}")
        sigma.append("| " + " | ".join(cells) + " |")
    broken = _broken_runs(summaries, runs)

    def line(result: tuple[bool, list[str], list[str]]) -> str:
        passed, reasons, notes = result
        text = "**PASS**" if passed else "**FAIL**: " + "; ".join(reasons)
        return text + (" (note: " + "; ".join(notes) + ")" if notes else "")

    study_criteria = (
        f"streams recordings: every run trusted, every calibrated parameter within "
        f"{MAX_ABS_Z:g}σ, mean (e/σ)² ≤ {MAX_MEAN_Z2:g} per parameter over all runs"
    )
    acceptance_criteria = (
        "every run, references included, at every length, route and vehicle: no failed run "
        f"(exit 2 or a crash); every trusted run's calibrated parameters within {MAX_ABS_Z:g}σ; "
        f"mean (e/σ)² over the trusted runs ≤ {MAX_MEAN_Z2:g} per parameter"
    )
    return "\n".join(
        [
            f"`{command}`",
            "",
            f"Total wall time {wall_s / 60:.1f} min.",
            "",
            "Error to the truth over the σ graphcal reports (parameters verdict 'calibrated'); "
            "exits: the CLI's exit status per seed (0 ok, 3 not trusted, 2 error, 1 crash):",
            "",
            *accuracy,
            "",
            "Mean σ over the seeds (ratio: to the reference CSV's σ of the same drive and seed, "
            "averaged):",
            "",
            *sigma,
            "",
            *broken,
            f"Study ({study_criteria}): {line(study)}",
            "",
            f"Acceptance ({acceptance_criteria}): {line(accepted)}",
            "",
        ]
    )


def _broken_runs(summaries: list[dict], runs: list[dict]) -> list[str]:
    """The rows that break a criterion, each with all of its runs: the exit status, the
    trust doubts or the failure, error/σ of the calibrated parameters, and the commands that
    reproduce it."""
    lines = []
    for s in summaries:
        if not s["breaks"]:
            continue
        lines.append(f"- **{s['label']}**: {'; '.join(s['breaks'])}")
        for r in runs:
            if r["case"] != s["label"]:
                continue
            if r["failed"]:
                what = f"exit {r.get('exit')}: {r['failed']}"
            else:
                zs = ", ".join(
                    f"{n} {r['parameters'][n]['z']:+.2f}σ"
                    for n in PARAMETER_NAMES
                    if _calibrated(r, n)
                )
                doubts = "" if r["trusted"] else "; not trusted: " + "; ".join(r["doubts"])
                what = f"exit {r['exit']}: {zs}{doubts}"
            lines.append(f"  - seed {r['seed']}: {_escape(what)}  \n    `{r['reproduce']}`")
    if not lines:
        return []
    return ["Rows that break a criterion (every run of each):", "", *lines, ""]


# --- Command line -----------------------------------------------------------------------------


def build_arguments() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0].replace("\n", " "),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="drive seeds")
    parser.add_argument(
        "--length-km", type=float, default=12.0, help="route length [km] without --lengths"
    )
    parser.add_argument(
        "--lengths",
        type=float,
        nargs="+",
        default=None,
        help="sweep the length [km] (robot: --runs-per-km runs per km); instead of --length-km",
    )
    parser.add_argument(
        "--routes",
        nargs="+",
        choices=ROUTES,
        default=None,
        help=f"sweep the car's route (None: {ROUTE}); the robot drives its hall",
    )
    parser.add_argument(
        "--vehicles",
        nargs="+",
        choices=VEHICLES,
        default=None,
        help="sweep the vehicle (None: car); robot: --robot-profile with simulate_robot",
    )
    parser.add_argument(
        "--robot-profile", type=Path, default=ROBOT_PROFILE, help="the robot's vehicle profile"
    )
    parser.add_argument(
        "--runs-per-km",
        type=float,
        default=RUNS_PER_KM,
        help="robot runs per km of --lengths (10: 1 km is the CLI's default 10 runs)",
    )
    parser.add_argument(
        "--rates",
        type=float,
        nargs="+",
        default=None,
        help=f"GNSS rates [Hz] (None: {' '.join(f'{r:g}' for r in RATES)}, or the "
        "representative shapes when --lengths/--routes/--vehicles is given)",
    )
    parser.add_argument(
        "--heading",
        nargs="+",
        choices=HEADINGS,
        default=None,
        help="fused: an INS heading (0.3° noise) and sideslip; none: the GNSS course "
        "(None: both, or the representative shapes)",
    )
    parser.add_argument(
        "--imu", nargs="+", choices=IMUS, default=None, help="with or without [imu] (None: both)"
    )
    parser.add_argument(
        "--wheels",
        nargs="+",
        choices=WHEELS,
        default=None,
        help=f"speeds [m/s] or ticks ({TICKS_PER_REVOLUTION} per revolution) (None: both)",
    )
    parser.add_argument(
        "--method",
        choices=["whole", "joint"],
        default="whole",
        help="whole: only the whole-log solve, which the table judges; joint adds the batches "
        "(and their spread check to the trust)",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="worker processes (None: one per core)"
    )
    parser.add_argument("--out", type=Path, default=None, help="write every run as JSON here")
    parser.add_argument("--markdown", type=Path, default=None, help="write the tables here")
    parser.add_argument(
        "--keep",
        type=Path,
        default=None,
        help="keep the recordings and each run's results (calibration.json) in this directory "
        "instead of a temporary one",
    )
    parser.add_argument(
        "--rear-cornering-stiffness",
        type=float,
        default=VehicleMotion().rear_cornering_stiffness,
        help="the simulated car's rear-axle cornering stiffness [N/rad] (its tyres' slip angle "
        "is the lateral force over it; inf: a kinematic car whose rear axle never slides; "
        "scripts/rear_axle_slide.py measures the rear axle's sideways motion)",
    )
    parser.add_argument(
        "--verbose", action="store_true", help="print the library's progress lines to stderr"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_arguments().parse_args(argv)
    args.workers = args.workers or default_workers()
    if args.lengths is not None and "--length-km" in (sys.argv[1:] if argv is None else argv):
        raise SystemExit("give --lengths or --length-km, not both")
    lengths = args.lengths or [args.length_km]
    if not all(length > 0 for length in lengths) or any(r <= 0 for r in args.rates or RATES):
        raise SystemExit("lengths and --rates must be positive")
    if not args.runs_per_km > 0:
        raise SystemExit("--runs-per-km must be positive")
    if "robot" in (args.vehicles or []):
        args.robot_profile = args.robot_profile.resolve()
        if not args.robot_profile.is_file():
            raise SystemExit(f"--robot-profile {args.robot_profile}: no such file")
    command = "python scripts/recording_study.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    cases = cases_of(args)
    references = references_of(args)
    print(
        f"{len(cases)} recording(s) and {len(references)} reference(s) × {len(args.seeds)} "
        f"seed(s): {', '.join(d.label() for d in drives_of(args))}; method {args.method}, "
        f"{args.workers} worker(s)",
        flush=True,
    )
    started = time.perf_counter()
    runs, csv_runs = run_study(args)
    wall_s = time.perf_counter() - started
    summaries = summarize(runs, csv_runs, cases, references)
    study = verdict(runs)
    accepted = acceptance(runs + csv_runs)
    table = markdown(summaries, study, accepted, runs + csv_runs, command.strip(), wall_s)
    if args.markdown is not None:
        args.markdown.write_text(table)
    if args.out is not None:
        report = {
            "command": command.strip(),
            "options": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
            "units": "SI (c_e, c_d, t_r [m]; d [s²]); z = error / sigma",
            "criteria": {"max_abs_z": MAX_ABS_Z, "max_mean_z2": MAX_MEAN_Z2},
            "wall_s": wall_s,
            "passed": study[0],
            "reasons": study[1],
            "notes": study[2],
            "acceptance": {"passed": accepted[0], "reasons": accepted[1], "notes": accepted[2]},
            "summaries": summaries,
            "runs": runs,
            "csv_runs": csv_runs,
        }
        args.out.write_text(json.dumps(report, indent=2, ensure_ascii=False) + "\n")
    print()
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
