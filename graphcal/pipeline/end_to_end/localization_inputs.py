"""What a localization graph takes from an offline calibration: the wheel noise it found
and the log corrected by its sensor estimates (:mod:`graphcal.localization`)."""

from __future__ import annotations

from typing import Any

from graphcal.log.drive_log import DriveLog
from graphcal.pipeline.configuration.settings import Settings
from graphcal.pipeline.end_to_end.calibration_run import CalibrationRun
from graphcal.pipeline.end_to_end.run import run_calibration
from graphcal.pipeline.methods.sensor_estimates import correct_log
from graphcal.progress import muted


def wheel_model(run: CalibrationRun) -> dict[str, float]:
    """The wheel noise a localization graph should carry after this calibration: the tick
    rounding it used (given or detected) and, if it found slow slip, the slip scales' prior.

    The keys are fields of :class:`~graphcal.localization.SmoothingSettings` and
    :class:`~graphcal.localization.OnlineSettings`:
    ``SmoothingSettings(**wheel_model(run))``.
    """
    joint = run.settings.joint
    slip = run.whole is not None and run.whole.slip_modelled
    return {
        "tick_quantization": float(joint.tick_quantization),
        "slip_sigma": float(joint.slip_sigma) if slip else 0.0,
        "slip_time": float(joint.slip_time),
    }


def prepare_localization(
    log: DriveLog, settings: Settings | None = None
) -> tuple[DriveLog, dict[str, Any], str]:
    """What a localization graph takes from an offline calibration of ``log``: the log
    corrected by the estimated time offset and lever arm, the settings that
    :class:`~graphcal.localization.SmoothingSettings` and
    :class:`~graphcal.localization.OnlineSettings` accept (:func:`wheel_model`, and the
    calibrated theta as ``theta_initial``), and a one-line summary of what was found.

    Runs the whole-log calibration (``settings``, default :class:`Settings`).
    """
    with muted():  # a step of the caller's, as before: quiet
        run = run_calibration(log, settings or Settings(), "whole")
    wheels: dict[str, Any] = {**wheel_model(run), "theta_initial": run.theta}
    found = ", ".join(f"{n} {e.value:+.3f} ({e.verdict})" for n, e in run.estimated.items())
    summary = (
        f"calibration: {found}; tick rounding σ {wheels['tick_quantization']:.2e} rev, "
        f"slip σ {wheels['slip_sigma']:g}"
    )
    return correct_log(log, run.estimated), wheels, summary
