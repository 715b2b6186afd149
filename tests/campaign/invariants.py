"""The invariants a recording of any shape keeps (issue 43): checks, not numbers. Each
check returns the invariants it found broken, one line each (empty: all kept)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import graphcal
from campaign.recording import THETA_TRUE, twin
from campaign.shape import Shape
from graphcal.log.quantization import ticks_per_revolution
from graphcal.log.segments import Segments, split_segments

NAMES = ("c_e", "c_d", "t_r", "d")
#: Refusals (exit 2) that name a real cause of a recording the campaign draws: too little
#: driving for a segment, no turn to calibrate from, too little acceleration, braking or
#: turning to estimate a mounted IMU's rotation from.
REAL_CAUSES = re.compile(
    r"too short|shorter than|no segment|not enough|no usable|s of acceleration, braking", re.I
)
#: How a parameter that is not calibrated says why.
REASONS = (
    "not calibrated: ",
    "not observable",
    "weakly determined",
    "fixed at nominal",
    "not trusted: ",
)
#: Largest |error / σ| of a calibrated parameter.
MAX_SIGMAS = 3.0


@dataclass
class Opened:
    """A recording opened as ``graphcal check`` and ``calibrate`` open it."""

    log: graphcal.DriveLog | None = None
    settings: object | None = None
    refusal: str | None = None
    broken: list[str] = field(default_factory=list)


def refusal_broken(message: str) -> list[str]:
    """A refusal (exit 2) must be one line naming a real cause."""
    lines = [ln for ln in message.splitlines() if ln.strip()]
    if len(lines) != 1:
        return [f"refusal of {len(lines)} lines: {message[:300]!r}"]
    if not REAL_CAUSES.search(lines[0]):
        return [f"refused: {lines[0][:400]}"]
    return []


def open_recording(manifest: Path) -> Opened:
    """Import the recording at ``manifest`` with its ``vehicle.toml``, and the settings
    ``calibrate`` would use; a refusal that names no real cause, or any other exception (a
    traceback for the user), is broken."""
    profile = manifest.parent / "vehicle.toml"
    out = Opened()
    try:
        vehicle = graphcal.load_vehicle(profile)
        out.settings = graphcal.configure_settings(vehicle=profile)
        out.log, _ = graphcal.open_log(manifest, vehicle)
    except graphcal.GraphcalError as exc:
        out.refusal = str(exc)
        out.broken += refusal_broken(str(exc))
    except Exception as exc:  # a traceback is what the invariant forbids
        last = traceback.format_exception_only(exc)[-1].strip()
        out.broken.append(f"traceback: {last[:400]}")
    return out


def _spanning(log: graphcal.DriveLog, segments: Segments, kind: str) -> list[str]:
    """Segments that contain a masked sample or a run boundary."""
    if len(segments) == 0:
        return []
    masked = np.zeros(len(log), bool) if log.masked is None else np.asarray(log.masked, bool)
    run = np.zeros(len(log)) if log.run is None else np.asarray(log.run)
    masked_before = np.concatenate([[0], np.cumsum(masked)])
    n_masked = masked_before[segments.stop + 1] - masked_before[segments.start]
    changes_before = np.concatenate([[0, 0], np.cumsum(np.diff(run) != 0)])
    n_changes = changes_before[segments.stop + 1] - changes_before[segments.start + 1]
    bad = np.flatnonzero((n_masked > 0) | (n_changes > 0))
    if not len(bad):
        return []
    i = int(bad[0])
    a, b = int(segments.start[i]), int(segments.stop[i])
    return [
        f"{len(bad)} {kind} segment(s) span a gap: first t = {log.t[a]:.1f}–{log.t[b]:.1f} s, "
        f"{int(n_masked[i])} masked sample(s), {int(n_changes[i])} run boundary(ies)"
    ]


def segment_broken(log: graphcal.DriveLog, settings) -> list[str]:
    """No calibration or validation segment contains a masked sample or a run boundary."""
    s = settings.segments
    circumference = float(settings.vehicle.theta_nominal[0])
    calibration = split_segments(log, s.length, s.stride, circumference)
    validation = split_segments(log, s.validation_length, None, circumference)
    return _spanning(log, calibration, "calibration") + _spanning(log, validation, "validation")


def counter_rotations(shape: Shape, rate: float = 40.0) -> np.ndarray:
    """The rotations [rev per interval] a logger writes that reads ``shape``'s counters at
    ``rate`` [Hz] through its first drive: differences of whole counts (at a steady speed,
    the same count for long stretches), the first interval from another epoch."""
    from campaign.recording import motion

    m = motion(shape)
    rng = np.random.default_rng([shape.seed, 44])
    start, end = m.spans[0]
    t = np.arange(start + rng.uniform(0.0, 1.0 / rate), end, 1.0 / rate)
    out = []
    for rev in (m.rev_l, m.rev_r):
        cumulative = np.interp(t, m.t, rev)
        counts = np.floor(cumulative * shape.ticks + rng.uniform())
        n = np.diff(counts) / shape.ticks
        n[0] = cumulative[1] - cumulative[0]  # a log started mid-count: off the grid
        out.append(n)
    return np.column_stack(out)


def tick_broken(shape: Shape, log: graphcal.DriveLog) -> list[str]:
    """The quantization graphcal finds is the one drawn; none on continuous wheel speeds."""
    broken = []
    if shape.wheels == "ticks":
        stated = log.tick_resolution
        if stated is None or round(1.0 / stated) != shape.ticks:
            broken.append(f"tick resolution of the import {stated} (drawn 1/{shape.ticks})")
        found = ticks_per_revolution(counter_rotations(shape))
        if found != shape.ticks:
            broken.append(f"ticks found in a log of counts: {found} (drawn {shape.ticks})")
    else:
        if log.tick_resolution is not None:
            broken.append(f"tick resolution {log.tick_resolution:g} rev on {shape.wheels}")
        found = ticks_per_revolution(np.column_stack([log.n_rl, log.n_rr]))
        if found is not None:
            broken.append(f"{found} ticks per revolution found on continuous {shape.wheels}")
    return broken


def data_path_broken(shape: Shape, manifest: Path) -> list[str]:
    """Every data-path invariant of the recording at ``manifest``: import, segments, ticks."""
    opened = open_recording(manifest)
    if opened.log is None:
        return opened.broken
    return segment_broken(opened.log, opened.settings) + tick_broken(shape, opened.log)


# ------------------------------------------------------------------------------------------
# A full calibration
# ------------------------------------------------------------------------------------------


@dataclass
class Calibrated:
    """What ``graphcal calibrate`` made of a recording: exit status, verdict and error / σ
    per parameter (``ratio``: calibrated ones), the broken invariants."""

    exit_code: int
    verdicts: dict[str, str] = field(default_factory=dict)
    ratio: dict[str, float] = field(default_factory=dict)
    line: str = ""
    broken: list[str] = field(default_factory=list)
    seconds: float = 0.0


def calibrate(
    shape: Shape, manifest: Path, extra: tuple[str, ...] = (), timeout: float | None = None
) -> Calibrated:
    """Run ``graphcal calibrate`` on the recording (with its ``vehicle.toml``, one worker, no
    batch study, ``extra`` options) and check its invariants: exit 0 or a one-line exit 2
    naming a real cause, never a traceback; every calibrated parameter within 3σ of the
    truth; a parameter not calibrated says why. A run longer than ``timeout`` [s] is
    stopped and counted as broken (its progress so far in ``calibrate.log``)."""
    import time

    out_dir = manifest.parent / "result"
    command = [
        sys.executable, "-m", "graphcal.cli", "calibrate", str(manifest),
        "--vehicle", str(manifest.parent / "vehicle.toml"), "--out", str(out_dir),
        "--workers", "1", "--batches", "0", *extra,
    ]  # fmt: skip
    started = time.perf_counter()
    log_path = manifest.parent / "calibrate.log"
    with log_path.open("w") as log:
        log.write(" ".join(command) + "\n")
        log.flush()
        try:
            code = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=log, timeout=timeout)
            code = code.returncode
        except subprocess.TimeoutExpired:
            code = None
    out = Calibrated(-1 if code is None else code, seconds=time.perf_counter() - started)
    stderr = log_path.read_text()
    if code is None:
        out.broken.append(f"no result in {timeout:g} s")
        return out
    if "Traceback" in stderr:
        tail = [ln for ln in stderr.splitlines() if ln.strip()][-1]
        out.broken.append(f"traceback: {tail[:400]}")
        return out
    errors = [ln for ln in stderr.splitlines() if ln.startswith("graphcal: error")]
    out.line = errors[-1] if errors else ""
    if code == 2:
        out.broken += refusal_broken(out.line.removeprefix("graphcal: error: "))
        return out
    if code != 0:
        out.broken.append(f"exit {code}")
    result = out_dir / "calibration.json"
    if not result.is_file():
        out.broken.append("no calibration.json")
        return out
    out.broken += verdict_broken(shape, json.loads(result.read_text()), out)
    return out


def verdict_broken(shape: Shape, doc: dict, out: Calibrated) -> list[str]:
    """Calibrated parameters within :data:`MAX_SIGMAS` σ of the truth; the others say why.
    Fills ``out.verdicts`` and ``out.ratio``."""
    broken = []
    truth = THETA_TRUE[shape.vehicle]
    for i, name in enumerate(NAMES):
        entry = doc["parameters"][name]
        status = str(entry.get("status", ""))
        out.verdicts[name] = status
        if status.startswith("calibrated"):
            sigma = entry.get("sigma")
            if sigma is None or not sigma > 0:
                broken.append(f"{name} calibrated without a σ")
                continue
            ratio = (float(doc["theta"][name]) - truth[i]) / float(sigma)
            out.ratio[name] = ratio
            if abs(ratio) > MAX_SIGMAS:
                broken.append(f"{name} calibrated {ratio:+.1f}σ off")
        elif not status.startswith(REASONS) or status.rstrip().endswith(":"):
            broken.append(f"{name} left out without a reason: {status!r}")
    return broken


__all__ = ["calibrate", "data_path_broken", "open_recording", "twin"]
