"""The settings of a calibration as ``graphcal calibrate`` chooses them: the paper's
defaults, then a TOML settings file, then a vehicle profile, then explicit overrides."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping

from graphcal.errors import GraphcalError
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.configuration.settings_file import (
    load_settings,
    load_vehicle,
    vehicle_settings_in,
)
from graphcal.pipeline.configuration.vehicle_settings import apply_vehicle
from graphcal.pipeline.solvers.joint_settings import without_defect_model


def configure_settings(
    config: str | os.PathLike[str] | None = None,
    vehicle: str | os.PathLike[str] | None = None,
    *,
    segments: Mapping[str, object] | None = None,
    batches: Mapping[str, object] | None = None,
    defect_model: bool = True,
    paper_exact: bool = False,
) -> Settings:
    """Settings: the paper's defaults, then ``config``, then explicit options.

    Args:
        config: a TOML settings file
            (:func:`~graphcal.pipeline.configuration.settings.load_settings`).
        vehicle: a vehicle profile (TOML); it sets what ``config`` does not
            (:func:`~graphcal.pipeline.configuration.settings.apply_vehicle`).
        segments, batches: fields of
            :class:`~graphcal.pipeline.configuration.settings.SegmentSettings` and
            :class:`~graphcal.pipeline.configuration.settings.BatchingSettings` to override (SI; a
            ``None`` value is not given).
        defect_model: False estimates theta alone (no wheel time offset, lever arm, heading
            biases or outlier weights).
        paper_exact: follow the paper literally (eq. 15 heading correction on every sample,
            start poses held in Steps 3 and 5).

    Raises:
        GraphcalError: a file that cannot be read or a value out of range.
    """
    settings = load_settings(config) if config else Settings()
    if vehicle is not None:
        keep = vehicle_settings_in(config) if config else set()
        settings = apply_vehicle(settings, load_vehicle(vehicle), keep=keep)
    segments = _given(segments)
    batches = _given(batches)
    try:
        settings = dataclasses.replace(
            settings,
            segments=dataclasses.replace(settings.segments, **segments),
            batches=dataclasses.replace(settings.batches, **batches),
        )
        if not defect_model:
            settings = dataclasses.replace(settings, joint=without_defect_model(settings.joint))
        if paper_exact:
            staged = dataclasses.replace(
                settings.staged, heading_correction="paper", estimate_start_poses=False
            )
            settings = dataclasses.replace(settings, staged=staged)
    except ValueError as exc:
        raise GraphcalError(str(exc)) from exc
    return settings


def _given(overrides: Mapping[str, object] | None) -> dict[str, object]:
    """The overrides that are given (not ``None``)."""
    return {k: v for k, v in (overrides or {}).items() if v is not None}
