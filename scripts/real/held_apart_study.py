"""What graphcal makes of the real recordings in ``data/real/``: each calibrated as a user
would (defaults; ``--vehicle`` for the robot), and validated on data the calibration did not
see — the measurement behind ``docs/real.md``.

    python scripts/real/held_apart_study.py --markdown real.md

* **The car** (comma2k19, one minute of highway): the fused-pose drive log, the raw streams
  (u-blox + CAN wheel speeds, without and with the IMU) and the raw CAN log with its DBC.
  Each is cut into :data:`CAR_FOLDS` equal time windows; each window in turn is held apart
  (masked: no segment spans it), the rest calibrated, and the window validated: its
  validation segments dead-reckoned with the nominal and the calibrated theta
  (:func:`graphcal.pipeline.end_to_end.held_apart.validation_errors`). The error is the mean
  over the windows.
* **The robot** (OptiOdom): calibrated from its free runs, validated on its circular and
  square runs (another day, other paths), each run one validation segment.

Each recording is calibrated as ``graphcal calibrate`` does with its defaults (the joint
method's recommended theta is the whole-log solve's, so ``--method whole`` gives the same
theta, faster), and again with ``--no-defect-model`` for comparison. Also printed: the
verdicts and sensor estimates of the calibration from the whole recording.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from graphcal import open_log
from graphcal.errors import GraphcalError
from graphcal.pipeline.configuration.configure import configure_settings
from graphcal.pipeline.end_to_end.held_apart import (
    holding_apart,
    time_window,
    time_windows,
    validation_errors,
)
from graphcal.pipeline.end_to_end.run import run_calibration

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT / "data" / "real"
ROBOT = ROOT / "data" / "vehicles" / "mocap_robot.toml"
#: Time windows of the car's minute, each held apart once.
CAR_FOLDS = 3
CAR = {
    "car, fused pose (drive-log CSV)": REAL / "comma2k19" / "drive.csv",
    "car, u-blox + CAN wheel speeds": REAL / "comma2k19" / "gnss.toml",
    "car, u-blox + CAN wheel speeds + IMU": REAL / "comma2k19" / "gnss_imu.toml",
    "car, u-blox + raw CAN log + DBC": REAL / "comma2k19" / "can.toml",
}


@dataclass
class Result:
    """One recording with one model: the whole recording's calibration and the validation
    on held-apart data."""

    recording: str
    model: str
    exit: int = 0
    error: str = ""
    theta: list[float] = field(default_factory=list)
    verdicts: dict[str, str] = field(default_factory=dict)
    sensors: dict[str, str] = field(default_factory=dict)
    nominal: float = float("nan")
    calibrated: float = float("nan")
    folds: list[dict] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def improvement(self) -> float:
        return 1.0 - self.calibrated / self.nominal


def settings_for(vehicle: Path | None, defect_model: bool):
    return configure_settings(vehicle=vehicle, defect_model=defect_model)


def calibrate(log, settings):
    """The whole-log calibration (exit status as the CLI's: 3 if not trusted)."""
    run = run_calibration(log, settings, "whole")
    return run, (3 if run.trust is not None and run.trust.doubts else 0)


def describe(result: Result, run) -> None:
    result.theta = [float(x) for x in run.theta]
    result.verdicts = run.verdicts()
    result.sensors = {
        name: f"{e.value:+.4g} ± {e.sigma:.2g} ({e.verdict})" for name, e in run.estimated.items()
    }


def car(label: str, path: Path, defect_model: bool) -> Result:
    result = Result(label, "defaults" if defect_model else "--no-defect-model")
    settings = settings_for(None, defect_model)
    log, _ = open_log(path, settings.vehicle, min_distance=settings.segments.length)
    try:
        run, result.exit = calibrate(log, settings)
        describe(result, run)
    except GraphcalError as exc:
        result.exit, result.error = 2, str(exc)
    nominal, calibrated = [], []
    for start, end in time_windows(log, CAR_FOLDS):
        fold = {"window_s": [float(start - log.t[0]), float(end - log.t[0])]}
        try:
            run, _ = calibrate(holding_apart(log, np.array([[start, end]])), settings)
            errors = validation_errors(time_window(log, start, end), run.theta, settings)
            fold.update(
                theta=[float(x) for x in run.theta],
                nominal=float(np.mean(errors.nominal)),
                calibrated=float(np.mean(errors.calibrated)),
            )
            nominal.append(fold["nominal"])
            calibrated.append(fold["calibrated"])
        except GraphcalError as exc:
            fold["error"] = str(exc)
        result.folds.append(fold)
    if len(calibrated) == CAR_FOLDS:
        result.nominal, result.calibrated = float(np.mean(nominal)), float(np.mean(calibrated))
    return result


def robot(defect_model: bool) -> Result:
    result = Result(
        "robot, free runs -> circle and square runs",
        "defaults" if defect_model else "--no-defect-model",
    )
    settings = settings_for(ROBOT, defect_model)
    free, _ = open_log(REAL / "optiodom" / "free" / "manifest.toml", settings.vehicle)
    kept, _ = open_log(REAL / "optiodom" / "validation" / "manifest.toml", settings.vehicle)
    try:
        run, result.exit = calibrate(free, settings)
        describe(result, run)
        errors = validation_errors(kept, run.theta, settings)
        result.nominal = float(np.mean(errors.nominal))
        result.calibrated = float(np.mean(errors.calibrated))
        result.folds = [
            {"run": i, "nominal": float(n), "calibrated": float(c)}
            for i, (n, c) in enumerate(zip(errors.nominal, errors.calibrated, strict=True))
        ]
    except GraphcalError as exc:
        result.exit, result.error = 2, str(exc)
    return result


def table(results: list[Result]) -> str:
    lines = [
        "| recording | model | exit | c_e [m] | c_d [mm] | t_r [m] | verdicts (c_e, c_d, t_r, d) "
        "| held apart: nominal [m] | calibrated [m] | better |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    short = {
        "calibrated": "cal",
        "not observable": "n/o",
        "fixed at nominal (vehicle profile)": "fixed",
    }
    for r in results:
        verdicts = ", ".join(short.get(v, v) for v in r.verdicts.values()) or r.error[:80]
        theta = r.theta or [float("nan")] * 4
        lines.append(
            f"| {r.recording} | {r.model} | {r.exit} | {theta[0]:.4f} | {theta[1] * 1e3:+.3f} | "
            f"{theta[2]:.4f} | {verdicts} | {r.nominal:.3f} | {r.calibrated:.3f} | "
            f"{r.improvement:.0%} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--markdown", type=Path, help="write the table here too")
    parser.add_argument("--json", type=Path, help="write every result here")
    parser.add_argument("--only", choices=("car", "robot"), help="one vehicle only")
    args = parser.parse_args(argv)
    results = []
    for defect_model in (True, False):
        if args.only != "robot":
            for label, path in CAR.items():
                t0 = time.perf_counter()
                results.append(car(label, path, defect_model))
                results[-1].seconds = time.perf_counter() - t0
                print(table(results[-1:]).splitlines()[-1], flush=True)
        if args.only != "car":
            t0 = time.perf_counter()
            results.append(robot(defect_model))
            results[-1].seconds = time.perf_counter() - t0
            print(table(results[-1:]).splitlines()[-1], flush=True)
    text = table(results)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    if args.json:
        args.json.write_text(json.dumps([r.__dict__ for r in results], indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
