"""How the shape of a recording changes graphcal's calibration: its error to the truth
against the σ it reports (the measurement behind issue 25's acceptance).

    python scripts/recording_study.py --length-km 12 --seeds 0 1 2 --method whole \\
        --out recording_study.json --markdown recording_study.md

(the command that produced the tables in docs; restrict an axis with ``--rates 10``,
``--heading fused none``, ``--imu yes no``, ``--wheels speeds ticks``).

A city drive is simulated once per seed as raw sensor streams at their own rates
(:mod:`graphcal.simulate.streams`): GNSS fixes at 1, 5 or 10 Hz, rear wheels and IMU at
100 Hz. Every combination of

* GNSS rate: 1, 5, 10 Hz;
* heading: ``fused`` (an INS heading with 0.3° noise and its sideslip in ``[gnss]``) or
  ``none`` (the heading and sideslip keys removed from the manifest: the GNSS course is used);
* IMU: ``yes`` or ``no`` (the manifest's ``[imu]`` section removed);
* wheels: ``speeds`` (m/s from the ECU) or ``ticks`` (cumulative counts, 96 per revolution)

is written with :func:`~graphcal.simulate.streams.write_streams` into a temporary directory
(removed at the end), imported and calibrated with graphcal's defaults, exactly as

    graphcal calibrate DIR/manifest.toml --method whole

does. Streams of different rates and wheel kinds come from separate ``simulate_streams``
calls with the same seed; the script checks that they sample the same noise-free drive and
the same ``theta_true``. The heading and IMU variants are edited copies of one manifest over
the same CSV files. As a reference, the 40 Hz drive-log CSV of the same drive (what
``graphcal simulate --out`` writes: ``simulate_drive`` with the same seed and length, the
paper's noise) is calibrated the same way per seed.

Per run and parameter (c_e, c_d, t_r, d) the estimate, the reported σ (the square root of
the covariance's diagonal), the error to the truth and error/σ, the verdict, whether the run
is trusted (``run.trust.doubts`` empty: the CLI's exit status 0 rather than 3), the import's
warnings, the wall time, and the first line of any exception (a failing case is recorded, it
does not stop the study). Per case (rate, heading, IMU, wheels), over the seeds: trusted runs
n/N, the worst |error/σ| and the mean (error/σ)² per parameter, and the mean σ per parameter
in mm (d in mm·s²/m) with its ratio to the 40 Hz CSV's σ of the same seed. The statistics
of error/σ use the parameters whose observability verdict is ``calibrated`` (a run's trust
doubts do not remove its parameters from them: an untrusted run already fails the
criteria). The final line is pass/fail against: every run trusted (a failed run is not),
every calibrated parameter within 3σ, and the mean (error/σ)² over all runs at most 2 per
parameter; a parameter calibrated in no run is noted, not failed.

Calibrating as the CLI does: the settings come from ``graphcal.cli.options.settings_from_args`` on
the ``graphcal calibrate`` command line built by ``graphcal.cli.build_parser`` (so they
follow the CLI's defaults); the log is loaded as :func:`graphcal.open_log` does
(``import_recording`` for a manifest, ``load_drive_log`` for the CSV, with the vehicle's
nominal theta and the segment length as the minimum distance), timed apart from the
calibration. One step of :func:`graphcal.calibrate_file` is repeated here: the import's
warnings are put in front of the run's warnings (they do not change ``run.trust``). The
CLI's evaluation against the truth (:func:`graphcal.evaluation.evaluate`) does not change
the estimate and is not run.

Deterministic given the seeds (except the wall times): the results do not depend on
``--workers``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import sys
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from graphcal.cli import build_parser
from graphcal.cli.options import settings_from_args
from graphcal.data.drive_log import load_drive_log
from graphcal.data.importer import import_recording, is_recording
from graphcal.data.manifest import load_manifest
from graphcal.errors import first_line
from graphcal.model import PARAMETER_NAMES
from graphcal.pipeline.calibration_run import CalibrationRun
from graphcal.pipeline.parallel import default_workers
from graphcal.pipeline.run import run_calibration
from graphcal.progress import Progress
from graphcal.simulate.drive import VehicleMotion, simulate_drive, write_synthetic_drive
from graphcal.simulate.streams import StreamSettings, simulate_streams, write_streams
from graphcal.units import DEVIATION_SCALE, DEVIATION_UNITS

RATES = (1.0, 5.0, 10.0)
HEADINGS = ("fused", "none")
IMUS = ("yes", "no")
WHEELS = ("speeds", "ticks")
#: Heading noise of the fused (INS) heading [rad].
FUSED_HEADING_NOISE = float(np.deg2rad(0.3))
TICKS_PER_REVOLUTION = 96
ROUTE = "city"
#: Pass criteria: |error/σ| of every calibrated parameter, mean (error/σ)² per parameter.
MAX_ABS_Z = 3.0
MAX_MEAN_Z2 = 2.0
#: Keys of the manifest's [gnss] section that carry the heading and the sideslip.
HEADING_KEYS = ("heading", "heading_unit", "heading_convention", "sideslip", "sideslip_unit")


@dataclass(frozen=True)
class Case:
    """One shape of the recording."""

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


# --- Simulation and manifests ----------------------------------------------------------------


def write_recording(
    directory: Path, seed: int, length_km: float, rate: float, wheels: str, motion: VehicleMotion
) -> tuple[Path, np.ndarray, np.ndarray]:
    """Simulate the streams of one GNSS rate and wheel kind into ``directory``.

    Returns the manifest, ``theta_true`` and the noise-free drive's positions ``(2, N)``
    (to check that every recording of a seed samples the same drive)."""
    settings = StreamSettings(
        gnss_rate=rate,
        heading_noise=FUSED_HEADING_NOISE,
        wheel_kind="ticks" if wheels == "ticks" else "speed",
        ticks_per_revolution=TICKS_PER_REVOLUTION,
    )
    sim = simulate_streams(length_km, seed, settings=settings, motion=motion, route=ROUTE)
    write_streams(sim, directory)
    truth = json.loads((directory / "truth.json").read_text())["theta_true"]
    theta_true = np.array([truth[name] for name in PARAMETER_NAMES])
    track = np.vstack([sim.drive.truth.px, sim.drive.truth.py])
    return directory / "manifest.toml", theta_true, track


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


# --- Calibration as `graphcal calibrate PATH --method METHOD` ---------------------------------


def calibrate_like_cli(
    path: Path, method: str, workers: int, progress: Progress | None
) -> tuple[CalibrationRun, tuple[str, ...], np.ndarray | None, dict[str, float]]:
    """Load and calibrate ``path`` as ``graphcal calibrate PATH --method METHOD`` does.

    Returns the run, the import's warnings, the manifest's ``theta_true`` (``None`` for a
    CSV) and the wall times [s] of loading and calibrating."""
    args = build_parser().parse_args(
        ["calibrate", str(path), "--method", method, "--workers", str(workers)]
    )
    settings = settings_from_args(args)
    nominal = settings.vehicle.theta_nominal
    min_distance = settings.segments.length
    started = time.perf_counter()
    imported = None
    if is_recording(path):
        imported = import_recording(path, nominal=nominal, min_distance=min_distance)
        log = imported.log
    else:
        log = load_drive_log(path, min_distance=min_distance, nominal=nominal)
    loaded = time.perf_counter()
    run = run_calibration(log, settings, method, progress=progress, workers=workers)
    import_warnings = imported.warnings if imported is not None else ()
    if import_warnings:  # as calibrate_file: the import's doubts go with the result
        run = dataclasses.replace(run, warnings=(*import_warnings, *run.warnings))
    seconds = {"load": loaded - started, "calibrate": time.perf_counter() - loaded}
    truth = imported.truth if imported is not None else None
    return run, tuple(import_warnings), truth, seconds


def run_record(
    path: Path,
    theta_true: np.ndarray,
    method: str,
    workers: int,
    progress: Progress | None,
) -> dict:
    """One calibration's numbers (SI); ``failed`` holds the exception's first line, if any."""
    record: dict = {"source": path.name, "failed": None}
    started = time.perf_counter()
    try:
        run, import_warnings, truth, seconds = calibrate_like_cli(path, method, workers, progress)
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
                "z": float(error[i] / sigma[i]),
                "verdict": verdicts[name],
                "observability": observability[name],
            }
            for i, name in enumerate(PARAMETER_NAMES)
        }
        record.update(
            trusted=bool(run.trust.trusted),
            doubts=list(run.trust.doubts),
            chi2_per_dof=run.trust.chi2_per_dof,
            import_warnings=list(import_warnings),
            warnings=list(run.warnings),
            seconds=seconds,
        )
    except Exception as exc:  # a failing case is a result, not the end of the study
        record.update(trusted=False, failed=f"{type(exc).__name__}: {first_line(str(exc))}")
    record["wall_s"] = time.perf_counter() - started
    return record


# --- The study --------------------------------------------------------------------------------


def cases_of(args: argparse.Namespace) -> list[Case]:
    return [
        Case(rate, heading, imu, wheels)
        for rate in args.rates
        for heading in args.heading
        for imu in args.imu
        for wheels in args.wheels
    ]


def run_study(args: argparse.Namespace) -> tuple[list[dict], list[dict]]:
    """Every case and the 40 Hz CSV for every seed: ``(case runs, CSV runs)``."""
    cases = cases_of(args)
    runs: list[dict] = []
    csv_runs: list[dict] = []
    motion = VehicleMotion(sideslip_speed_gain=args.sideslip_gain)

    def progress_for(label: str) -> Progress | None:
        if not args.verbose:
            return None
        return lambda line: print(f"    [{label}] {line}", file=sys.stderr, flush=True)

    with tempfile.TemporaryDirectory(prefix="recording_study-") as tmp:
        root = Path(tmp)
        for seed in args.seeds:
            drive = simulate_drive(args.length_km, seed, motion=motion, route=ROUTE)
            csv_path = root / f"seed{seed}" / "drive.csv"
            csv_path.parent.mkdir(parents=True)
            write_synthetic_drive(drive, csv_path)
            theta_true = np.asarray(drive.theta_true, dtype=float)
            record = run_record(
                csv_path, theta_true, args.method, args.workers, progress_for("40 Hz CSV")
            )
            record.update(seed=seed, case="40 Hz CSV")
            csv_runs.append(record)
            print(run_line("40 Hz CSV", seed, record), flush=True)

            track = None
            for rate in args.rates:
                for wheels in args.wheels:
                    directory = root / f"seed{seed}" / f"gnss{rate:g}hz-{wheels}"
                    manifest, truth, this_track = write_recording(
                        directory, seed, args.length_km, rate, wheels, motion
                    )
                    if not np.array_equal(truth, theta_true):
                        raise RuntimeError(f"seed {seed}: {directory.name} has another theta_true")
                    if track is None:
                        track = this_track
                    elif not np.array_equal(track, this_track):
                        raise RuntimeError(f"seed {seed}: {directory.name} samples another drive")
                    for case in cases:
                        if case.rate != rate or case.wheels != wheels:
                            continue
                        path = manifest_variant(manifest, case.heading, case.imu)
                        record = run_record(
                            path, theta_true, args.method, args.workers, progress_for(case.label())
                        )
                        record.update(seed=seed, **case.key())
                        runs.append(record)
                        print(run_line(case.label(), seed, record), flush=True)
    return runs, csv_runs


def run_line(label: str, seed: int, record: dict) -> str:
    """One progress line per run."""
    head = f"{label}, seed {seed}:"
    if record["failed"]:
        return f"{head} FAILED ({record['wall_s']:.1f} s): {record['failed']}"
    cells = []
    for i, (name, p) in enumerate(record["parameters"].items()):
        scale, unit = DEVIATION_SCALE[i], DEVIATION_UNITS[i]
        mark = "" if p["observability"] == "calibrated" else f" [{p['observability']}]"
        cells.append(f"{name} {p['z']:+.2f}σ (σ {p['sigma'] * scale:.3g} {unit}){mark}")
    trust = "trusted" if record["trusted"] else "NOT trusted"
    return f"{head} {'; '.join(cells)}; {trust}; {record['wall_s']:.1f} s"


# --- Summaries --------------------------------------------------------------------------------


def calibrated_z(records: Iterable[dict], name: str) -> np.ndarray:
    """error/σ of ``name`` over the successful runs where its verdict is ``calibrated``."""
    return np.array(
        [
            r["parameters"][name]["z"]
            for r in records
            if not r["failed"] and r["parameters"][name]["observability"] == "calibrated"
        ]
    )


def summarize(runs: list[dict], csv_runs: list[dict], cases: list[Case]) -> list[dict]:
    """One summary per case over the seeds (numbers in SI; ``None`` where none)."""
    csv_sigma = {
        r["seed"]: np.array([r["parameters"][n]["sigma"] for n in PARAMETER_NAMES])
        for r in csv_runs
        if not r["failed"]
    }
    rows = []
    for case in [None, *cases]:  # None: the 40 Hz CSV itself
        records = csv_runs if case is None else [r for r in runs if _is(r, case)]
        summary: dict = {"case": "40 Hz CSV" if case is None else case.key()}
        summary["runs"] = len(records)
        summary["trusted"] = sum(bool(r["trusted"]) for r in records)
        summary["failed"] = [f"seed {r['seed']}: {r['failed']}" for r in records if r["failed"]]
        for name in PARAMETER_NAMES:
            z = calibrated_z(records, name)
            ok = [r for r in records if not r["failed"]]
            sigma = np.array([r["parameters"][name]["sigma"] for r in ok])
            i = PARAMETER_NAMES.index(name)
            ratios = np.array(
                [
                    r["parameters"][name]["sigma"] / csv_sigma[r["seed"]][i]
                    for r in ok
                    if r["seed"] in csv_sigma
                ]
            )
            summary[name] = {
                "calibrated": len(z),
                "max_abs_z": float(np.max(np.abs(z))) if len(z) else None,
                "mean_z2": float(np.mean(z**2)) if len(z) else None,
                "mean_sigma": float(np.mean(sigma)) if len(sigma) else None,
                "sigma_over_csv": float(np.mean(ratios)) if len(ratios) else None,
            }
        rows.append(summary)
    return rows


def _is(record: dict, case: Case) -> bool:
    return all(record[k] == v for k, v in case.key().items())


def verdict(runs: list[dict]) -> tuple[bool, list[str], list[str]]:
    """Pass/fail of all case runs against the criteria: ``(passed, why it fails, notes)``.
    A parameter calibrated in no run is a note, not a failure (the criteria are silent)."""
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


def _number(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def _case_cells(summary: dict) -> list[str]:
    case = summary["case"]
    if isinstance(case, str):
        return [case, "", "", ""]
    return [f"{case['rate_hz']:g} Hz", case["heading"], case["imu"], case["wheels"]]


def markdown(
    summaries: list[dict], passed: bool, reasons: list[str], notes: list[str], command: str
) -> str:
    """The two tables (accuracy; σ) and the pass/fail line."""
    names = PARAMETER_NAMES
    head = ["GNSS", "heading", "IMU", "wheels", "trusted"]
    accuracy = [
        "| "
        + " | ".join(
            head
            + [f"max \\|e/σ\\| {n}" for n in names]
            + [f"mean (e/σ)² {n}" for n in names]
            + ["failures"]
        )
        + " |",
        "|" + "---|" * (len(head) + 2 * len(names) + 1),
    ]
    for s in summaries:
        cells = [*_case_cells(s), f"{s['trusted']}/{s['runs']}"]
        cells += [_number(s[n]["max_abs_z"]) for n in names]
        cells += [_number(s[n]["mean_z2"]) for n in names]
        cells.append("<br>".join(s["failed"]).replace("|", "\\|") or "")
        accuracy.append("| " + " | ".join(cells) + " |")
    sigma = [
        "| "
        + " | ".join(
            head[:4]
            + [f"σ {n} [{u}] (× 40 Hz CSV)" for n, u in zip(names, DEVIATION_UNITS, strict=True)]
        )
        + " |",
        "|" + "---|" * (4 + len(names)),
    ]
    for s in summaries:
        cells = _case_cells(s)
        for i, n in enumerate(names):
            p = s[n]
            if p["mean_sigma"] is None:
                cells.append("—")
                continue
            ratio = "" if isinstance(s["case"], str) else f" ({_number(p['sigma_over_csv'])}×)"
            cells.append(f"{p['mean_sigma'] * DEVIATION_SCALE[i]:.3g}{ratio}")
        sigma.append("| " + " | ".join(cells) + " |")
    result = "**PASS**" if passed else "**FAIL**: " + "; ".join(reasons)
    if notes:
        result += " (note: " + "; ".join(notes) + ")"
    criteria = (
        f"every run trusted, every calibrated parameter within {MAX_ABS_Z:g}σ, mean (e/σ)² ≤ "
        f"{MAX_MEAN_Z2:g} per parameter over all runs"
    )
    return "\n".join(
        [
            f"`{command}`",
            "",
            "Error to the truth over the σ graphcal reports (parameters verdict 'calibrated'):",
            "",
            *accuracy,
            "",
            "Mean σ over the seeds (ratio: to the 40 Hz CSV's σ of the same seed, averaged):",
            "",
            *sigma,
            "",
            f"Overall ({criteria}): {result}",
            "",
        ]
    )


# --- Command line -----------------------------------------------------------------------------


def build_arguments() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0].replace("\n", " "),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="drive seeds")
    parser.add_argument("--length-km", type=float, default=12.0, help="route length [km]")
    parser.add_argument(
        "--rates", type=float, nargs="+", default=list(RATES), help="GNSS rates [Hz]"
    )
    parser.add_argument(
        "--heading",
        nargs="+",
        choices=HEADINGS,
        default=list(HEADINGS),
        help="fused: an INS heading (0.3° noise) and sideslip; none: the GNSS course",
    )
    parser.add_argument(
        "--imu", nargs="+", choices=IMUS, default=list(IMUS), help="with or without [imu]"
    )
    parser.add_argument(
        "--wheels",
        nargs="+",
        choices=WHEELS,
        default=list(WHEELS),
        help=f"speeds [m/s] or ticks ({TICKS_PER_REVOLUTION} per revolution)",
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
        "--sideslip-gain",
        type=float,
        default=VehicleMotion().sideslip_speed_gain,
        help="the simulated car's sideslip speed gain k [s²/m] (beta = kappa (l_r - k v²); "
        "scripts/rear_axle_slide.py shows what it does to the rear axle)",
    )
    parser.add_argument(
        "--verbose", action="store_true", help="print the library's progress lines to stderr"
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_arguments().parse_args(argv)
    args.workers = args.workers or default_workers()
    if not args.length_km > 0 or any(r <= 0 for r in args.rates):
        raise SystemExit("--length-km and --rates must be positive")
    command = "python scripts/recording_study.py " + " ".join(
        sys.argv[1:] if argv is None else argv
    )
    cases = cases_of(args)
    print(
        f"{len(cases)} case(s) × {len(args.seeds)} seed(s), {args.length_km:g} km {ROUTE} route, "
        f"method {args.method}, {args.workers} worker(s)",
        flush=True,
    )
    runs, csv_runs = run_study(args)
    summaries = summarize(runs, csv_runs, cases)
    passed, reasons, notes = verdict(runs)
    table = markdown(summaries, passed, reasons, notes, command.strip())
    if args.markdown is not None:
        args.markdown.write_text(table)
    if args.out is not None:
        report = {
            "command": command.strip(),
            "options": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
            "units": "SI (c_e, c_d, t_r [m]; d [s²]); z = error / sigma",
            "criteria": {"max_abs_z": MAX_ABS_Z, "max_mean_z2": MAX_MEAN_Z2},
            "passed": passed,
            "reasons": reasons,
            "notes": notes,
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
