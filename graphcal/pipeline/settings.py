"""All settings of a calibration run, with the paper's values as defaults (§4.4, §5.1).

One schema: TOML sections and keys are the dataclass field names, recursively. Load a file
with :func:`load_settings`; :func:`settings_to_dict` (or :meth:`Settings.to_dict`) gives the
plain-data view written into ``calibration.json``. A file may set any subset; a missing key
keeps the default of the enclosing setting. Every section and key, with the defaults::

    [segments]
    length = 150.0              # m
    # stride = 50.0             # m; omit for disjoint segments
    min_yaw_rate = 0.15         # rad/s
    yaw_statistic = "mean"      # mean | median | rms
    yaw_window = 1.0            # s, window of the yaw-rate difference
    validation_length = 300.0   # m

    [batches]
    size = 9                    # segments per batch
    count = 1000
    seed = 0

    [calibration]               # batch solves of Steps 1, 3 and 5
    theta_initial = [2.0, 0.0, 1.55, 0.0]           # c_e m, c_d m, t_r m, d s²
    theta_prior_sigmas = [0.1, 0.01, 0.2, 0.01]     # same units
    pose_weights = [1.0, 1.0, 50.0]                 # the paper's W on x, y, heading
    position_sigma = 0.2        # m
    estimate_start_poses = false  # Step 1 holds the start; [staged] frees it in Steps 3, 5
    max_iterations = 5

    [staged]                    # --method staged: Steps 2 and 4
    heading_correction_step = 10  # k of eq. (15)
    heading_correction = "start"  # start | paper (eq. 15 verbatim)
    estimations = 12            # input estimations per segment in Step 4
    trim_fraction = 0.1         # dropped at each end before averaging
    estimate_start_poses = true # in Steps 3 and 5; false = the paper's held start

    [staged.step2]              # input estimation of Step 2
    tracking_weights = [1.0, 1.0, 1.0]              # Q on x, y, heading
    smoothness_weight = 1000.0  # R on the change of the corrected rotations
    input_bound = 0.05          # relative bound on the corrections
    chunk_steps = 50
    continuity_sigmas = [0.01, 0.01, 0.001]         # m, m, rad
    max_iterations = 10

    [staged.step4]              # input estimation of Step 4
    tracking_weights = [1.0, 1.0, 10.0]
    smoothness_weight = 1000.0
    input_bound = 0.05
    chunk_steps = 50
    continuity_sigmas = [0.01, 0.01, 0.001]         # m, m, rad
    max_iterations = 10

    [joint]                     # --method joint and whole
    theta_initial = [2.0, 0.0, 1.55, 0.0]           # c_e m, c_d m, t_r m, d s²
    theta_prior_sigmas = [0.1, 0.01, 0.2, 0.01]     # what "not observable" leaves
    pose_weights = [1.0, 1.0, 50.0]
    position_sigma = 0.2        # m
    wheel_noise = 0.0005        # rev, sigma of the corrections' prior
    smoothness_weight = 0.0     # R on the change of the corrections; 0 = off
    chunk_steps = 50
    continuity_sigmas = [0.001, 0.001, 0.0001]      # m, m, rad
    max_iterations = 30
    max_sigma_ratio = 0.1       # calibrated = data shrink the prior sigma to at most this
"""

from __future__ import annotations

import dataclasses
import os
import re
import tomllib
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from graphcal.data.segments import YawRateStatistic
from graphcal.errors import GraphcalError
from graphcal.pipeline.batch_calibration import BatchSettings
from graphcal.pipeline.input_estimation import InputEstimationSettings
from graphcal.pipeline.joint import JointSettings

#: Upper limit [rad/s] of the yaw-rate selection threshold: no road vehicle keeps a mean yaw
#: rate near it over a calibration segment, so a larger value is a unit or typing mistake.
MAX_MIN_YAW_RATE = 1.0


@dataclass(frozen=True)
class SegmentSettings:
    """How the log is cut and which segments calibrate (§5.1); lengths in m, rates in rad/s."""

    length: float = 150.0
    stride: float | None = None
    min_yaw_rate: float = 0.15
    yaw_statistic: YawRateStatistic = "mean"
    yaw_window: float = 1.0
    validation_length: float = 300.0

    def __post_init__(self) -> None:
        for name in ("length", "validation_length"):
            if not getattr(self, name) >= 10.0:
                raise ValueError(f"segments.{name} must be at least 10 m")
        if not self.yaw_window > 0:
            raise ValueError("segments.yaw_window must be positive")
        if self.stride is not None and not self.stride >= 1.0:
            raise ValueError("segments.stride must be at least 1 m")
        if not 0 <= self.min_yaw_rate < MAX_MIN_YAW_RATE:
            raise ValueError(
                f"segments.min_yaw_rate must be >= 0 and below {MAX_MIN_YAW_RATE:g} rad/s "
                f"({np.degrees(MAX_MIN_YAW_RATE):.0f}°/s; a car's mean yaw rate over a segment "
                f"stays far below it), got {self.min_yaw_rate:g}"
            )
        if self.yaw_statistic not in ("mean", "median", "rms"):
            raise ValueError("segments.yaw_statistic must be mean, median or rms")


@dataclass(frozen=True)
class BatchingSettings:
    """Batches of distinct segments (§4.3: N = 9; §5.1: 1000 batches)."""

    size: int = 9
    count: int = 1000
    seed: int = 0

    def __post_init__(self) -> None:
        if self.size < 1 or self.count < 1:
            raise ValueError("batches.size and batches.count must be at least 1")
        if self.seed < 0:
            raise ValueError("batches.seed must be >= 0")


@dataclass(frozen=True)
class StagedSettings:
    """Steps 2 and 4 of the paper (§4.3, §4.4).

    Attributes:
        step2, step4: input-estimation settings; they differ in the heading weight q_psi.
        heading_correction_step: k of eq. (15) (paper: 10).
        heading_correction: how Step 2 corrects the heading.
            ``"paper"`` is eq. (15) verbatim: Δψ = ψ̂_k − ψ̃_k added to every measured heading
            of the segment; right when the heading error is a slowly varying bias (a
            Kalman-filtered heading, as on the paper's vehicle).
            ``"start"`` (default) corrects only the held initial heading, by the yaw the
            estimated inputs add over the first k steps: Δψ = ψ̂_k − ψ_k(measured inputs).
            With white heading noise (the paper's simulation model) eq. (15) swaps the start's
            noise for the noise at sample k: measured on 30 synthetic segments at 1.5°
            noise, the start heading error was 1.38° uncorrected, 2.36° after eq. (15) and
            0.95° after ``"start"``.
        estimations: input estimations per segment in Step 4 (paper: 12).
        trim_fraction: fraction dropped at each end before averaging the estimations
            (paper: mean of the middle 80 %, i.e. 0.1).
        estimate_start_poses: in Steps 3 and 5, estimate each segment's start pose under its
            (heading-corrected) measurement prior instead of holding it. The paper holds it;
            with noisy wheel rotations a held start biases d and t_r even when the start
            heading is exact (measured with the true start heading on 40 batches of a 24 km
            synthetic drive: d +0.08 mm·s²/m, t_r −7.6 mm), and d dominates the validation
            error. Estimating it brought the median validation error of Step 5 from 0.27 m to
            0.07 m above the reachable limit. ``False`` reproduces the paper.
    """

    step2: InputEstimationSettings = field(default_factory=InputEstimationSettings)
    step4: InputEstimationSettings = field(
        default_factory=lambda: InputEstimationSettings(tracking_weights=(1.0, 1.0, 10.0))
    )
    heading_correction_step: int = 10
    heading_correction: str = "start"
    estimations: int = 12
    trim_fraction: float = 0.1
    estimate_start_poses: bool = True

    def __post_init__(self) -> None:
        if self.heading_correction_step < 1 or self.estimations < 1:
            raise ValueError("heading_correction_step and estimations must be at least 1")
        if not 0 <= self.trim_fraction < 0.5:
            raise ValueError("trim_fraction must be in [0, 0.5)")
        if self.heading_correction not in ("start", "paper"):
            raise ValueError("heading_correction must be 'start' or 'paper'")


@dataclass(frozen=True)
class Settings:
    """Everything that shapes a calibration run. Defaults are the paper's."""

    segments: SegmentSettings = field(default_factory=SegmentSettings)
    batches: BatchingSettings = field(default_factory=BatchingSettings)
    calibration: BatchSettings = field(
        default_factory=lambda: BatchSettings(estimate_start_poses=False, max_iterations=5)
    )
    staged: StagedSettings = field(default_factory=StagedSettings)
    joint: JointSettings = field(default_factory=JointSettings)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view (lists instead of arrays), as written into ``calibration.json``."""
        return settings_to_dict(self)


#: Keys of older settings files, with where they went; loading one is a one-line error.
_MOVED = {
    "input_estimation": (
        "[input_estimation] is now [staged] with sub-tables [staged.step2] and [staged.step4]: "
        "step2_tracking_weights -> staged.step2.tracking_weights, step4_tracking_weights -> "
        "staged.step4.tracking_weights, smoothness_weight, input_bound, chunk_steps, "
        "continuity_sigmas and max_iterations -> both staged.step2.<key> and "
        "staged.step4.<key>, heading_correction_step, heading_correction, estimations, "
        "trim_fraction and estimate_start_poses -> staged.<key>"
    ),
    "calibration.theta_nominal": "[calibration] theta_nominal is now theta_initial",
    "joint.theta_nominal": "[joint] theta_nominal is now theta_initial",
}


def settings_to_dict(settings: Any) -> dict[str, Any]:
    """Plain data of a settings dataclass: sub-tables for dataclasses, lists for vectors.

    An unset optional value stays ``None`` (JSON ``null``); a TOML writer leaves it out.
    """
    return {f.name: _plain(getattr(settings, f.name)) for f in dataclasses.fields(settings)}


def settings_from_dict(data: dict[str, Any], source: str = "<settings>") -> Settings:
    """Build :class:`Settings` from a nested dict like a TOML file's (unknown keys rejected)."""
    return _load(Settings(), data, "", source)


def load_settings(path: str | os.PathLike[str]) -> Settings:
    """Read :class:`Settings` from a TOML file (missing keys keep the paper's defaults)."""
    source = str(path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise GraphcalError(f"{source}: no such settings file; check the path") from None
    except tomllib.TOMLDecodeError as exc:
        raise GraphcalError(f"{source}: not valid TOML ({exc})") from exc
    return settings_from_dict(data, source)


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return settings_to_dict(value)
    if isinstance(value, np.ndarray | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _load(default: Any, data: Any, section: str, source: str) -> Any:
    """``default`` with the values of ``data`` (table ``section``) replaced, checked by type."""
    where = f"[{section}]" if section else "the file"
    if not isinstance(data, dict):
        raise GraphcalError(f"{source}: {where} must be a table, got {data!r}")
    names = [f.name for f in dataclasses.fields(default)]
    unknown = [key for key in data if key not in names]
    for key in unknown:
        moved = _MOVED.get(f"{section}.{key}" if section else key)
        if moved:
            raise GraphcalError(f"{source}: {moved}")
    if unknown:
        what = f"key(s) {sorted(unknown)} in [{section}]" if section else f"section(s) {unknown}"
        raise GraphcalError(f"{source}: unknown {what}; known: {names}")
    hints = typing.get_type_hints(type(default))
    changes = {}
    for key, value in data.items():
        current = getattr(default, key)
        if dataclasses.is_dataclass(current):
            path = f"{section}.{key}" if section else key
            changes[key] = _load(current, value, path, source)
        else:
            changes[key] = _convert(value, hints[key], current, f"[{section}] {key}", source)
    try:
        return dataclasses.replace(default, **changes)
    except (TypeError, ValueError) as exc:
        message = str(exc)
        if section and not message.startswith(f"{section}."):
            # A dataclass names its own section ("input_estimation.") or none at all.
            named = re.match(r"\w+\.(?=\w)", message)
            message = f"{section}.{message[named.end() :]}" if named else f"[{section}] {message}"
        raise GraphcalError(f"{source}: {message}") from exc


def _convert(value: Any, hint: Any, current: Any, name: str, source: str) -> Any:
    """``value`` as the type ``hint`` of a field whose default is ``current``."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType) and type(None) in args:
        if value is None:
            return None
        (hint,) = [a for a in args if a is not type(None)]
        origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is np.ndarray or origin is tuple:
        n = len(current)
        ok = (
            isinstance(value, list | tuple)
            and len(value) == n
            and all(_is_number(v) and np.isfinite(v) for v in value)
        )
        if not ok:
            raise GraphcalError(
                f"{source}: {name} must be a list of {n} finite numbers, got {value!r}"
            )
        return (
            np.array(value, dtype=float) if hint is np.ndarray else tuple(float(v) for v in value)
        )
    if origin is Literal:
        ok, kind = value in args, "one of " + ", ".join(repr(a) for a in args)
    elif hint is bool:
        ok, kind = isinstance(value, bool), "true or false"
    elif hint is int:
        ok, kind = isinstance(value, int) and not isinstance(value, bool), "a whole number"
    elif hint is float:
        ok, kind = _is_number(value), "a number"
        value = float(value) if ok else value
    elif hint is str:
        ok, kind = isinstance(value, str), "text"
    else:
        raise TypeError(f"settings field {name} has a type the loader does not know: {hint}")
    if not ok:
        raise GraphcalError(f"{source}: {name} must be {kind}, got {value!r}")
    return value


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)
