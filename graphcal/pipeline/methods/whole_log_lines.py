"""The progress lines of what the whole-log solve
(:mod:`graphcal.pipeline.methods.whole_log`) found: its sensor estimates, the fixes it
down-weighted and its slow wheel slip verdict."""

from __future__ import annotations

from graphcal.log.drive_log import DriveLog
from graphcal.pipeline.methods.sensor_estimates import DownWeightedFixes, SensorEstimate, run_of
from graphcal.pipeline.solvers.joint import JointCalibration
from graphcal.pipeline.solvers.joint_settings import JointSettings
from graphcal.progress import say
from graphcal.units import LengthUnit


def report_whole_log(
    whole: JointCalibration,
    estimate_lines: list[str],
    down_weighted: DownWeightedFixes,
    settings: JointSettings,
) -> None:
    """The progress lines of what the whole-log solve found: the sensor estimates (their
    lines: :func:`estimate_lines`), the fixes it down-weighted and slow wheel slip."""
    for line in estimate_lines:
        say(line)
    if whole.fix_weights is not None:
        say(down_weighted.summary())
    if whole.slip_test is not None:
        say(slip_line(whole, settings))


def slip_line(whole: JointCalibration, settings: JointSettings) -> str:
    """One line: whether the whole-log solve found slow wheel slip and modelled it."""
    test = whole.slip_test.describe()
    if whole.slip_modelled:
        return f"slow wheel slip found ({test}): modelled; σ includes it"
    line = f"no slow wheel slip ({test}; limit at a false-alarm rate of {settings.slip_alpha:g})"
    scale = whole.slip_test.unseen_slip_scale()
    if scale is None:
        return line
    return (
        f"{line}; c_e's σ ×{scale[0]:.2f} for slow slip of {100 * settings.unseen_slip_sigma:g} % "
        f"over {settings.unseen_slip_time:g} s that no test can show ([joint] unseen_slip_sigma)"
    )


def estimate_lines(
    estimated: dict[str, SensorEstimate], log: DriveLog, unit: LengthUnit
) -> list[str]:
    """One progress line per sensor estimate: the time offset in ms, the lever arm of the
    log's position sensor (:meth:`~graphcal.log.drive_log.DriveLog.position_sensor`) from
    its reference point (:meth:`~graphcal.log.drive_log.DriveLog.position_reference`) in the
    vehicle's length ``unit``."""
    sensor, point = log.position_sensor(), log.position_reference()
    labels = {
        "time_offset": "time offset: wheels late against the pose",
        "lever_arm_longitudinal": f"{sensor} ahead of the {point}",
        "lever_arm_lateral": f"{sensor} left of the {point}",
        "rear_slip_gain": f"{point}'s slip angle per lateral acceleration",
    }
    lines = []
    for name, e in estimated.items():
        base, run = run_of(name)
        label = labels[base]
        if run is not None:
            label = f"{label} (run {run})"
        if not e.observable:
            lines.append(f"{label}: not observable from this drive")
        elif base == "time_offset":
            lines.append(f"{label}: {e.value * 1e3:+.1f} ± {e.sigma * 1e3:.1f} ms; {e.verdict}")
        elif base == "rear_slip_gain":
            lines.append(
                f"{label}: {e.value * 1e3:+.2f} ± {e.sigma * 1e3:.2f} mrad per m/s²; {e.verdict}"
            )
        else:
            lines.append(
                f"{label}: {unit.format(e.value, sign=True)} ± {unit.spread(e.sigma)} "
                f"{unit.name}; {e.verdict}"
            )
    return lines
