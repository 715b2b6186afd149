"""A drive log described in lines, as ``graphcal check`` and ``graphcal import`` print it
under the log's name: its size, distance, segments, excitation and what is masked."""

from __future__ import annotations

from graphcal.log.consistency import runs
from graphcal.log.drive_log import DriveLog, measurement_line
from graphcal.log.excitation import drive_excitation
from graphcal.log.segments import split_segments, yaw_rate_statistic
from graphcal.pipeline.configuration.settings import Settings
from graphcal.vehicle import VehicleProfile


def log_distance_line(log: DriveLog, vehicle: VehicleProfile) -> str:
    """The distance the wheels travel [m] with the vehicle's nominal circumference."""
    c_e = float(vehicle.theta_nominal[0])
    return f"{log.travelled_distance(c_e)[-1]:.1f} m (wheels, nominal c_e = {c_e:g} m)"


def log_check_lines(log: DriveLog, settings: Settings) -> list[str]:
    """Samples, duration, measurements (of a sparse log), distance and the segments of
    ``settings.segments`` with how many turn enough to be selected."""
    seg = settings.segments
    segments = split_segments(log, seg.length, seg.stride, settings.vehicle.theta_nominal[0])
    nominal = settings.vehicle.theta_nominal
    yaw = yaw_rate_statistic(log, segments, seg.yaw_statistic, seg.yaw_window, nominal)
    lines = [
        f"  samples          {len(log)} at {log.dt * 1e3:.1f} ms ({1 / log.dt:.1f} Hz)",
        f"  duration         {log.t[-1] - log.t[0]:.1f} s",
    ]
    if log.sparse:
        lines.append(f"  measurements     {measurement_line(log)}")
    lines.append(f"  distance         {log_distance_line(log, settings.vehicle)}")
    lines.append(
        f"  segments         {len(segments)} of {seg.length:g} m, "
        f"{int((yaw > seg.min_yaw_rate).sum())} with {seg.yaw_statistic} |yaw rate| > "
        f"{seg.min_yaw_rate:g} rad/s"
    )
    return lines


def log_excitation_lines(log: DriveLog, settings: Settings) -> list[str]:
    """How much the drive turns and varies its speed, for the observability of theta."""
    seg = settings.segments
    excitation = drive_excitation(
        log,
        seg.length,
        seg.min_yaw_rate,
        seg.yaw_statistic,
        seg.yaw_window,
        wheel_circumference=float(settings.vehicle.theta_nominal[0]),
        theta=settings.vehicle.theta_nominal,
    )
    return [f"  {line}" for line in excitation.lines()]


def log_masked_lines(log: DriveLog) -> list[str]:
    """The isolated position spikes given no weight and the time no segment spans."""
    lines = []
    if log.outlying is not None:
        runs_ = runs(log.outlying)
        first = ", ".join(f"{log.t[a]:.1f} s" for a, _ in runs_[:3])
        lines.append(
            f"  outlying fixes   {len(runs_)} isolated position spike(s), {log.outlying.sum()} "
            f"sample(s), given no weight (first at {first})"
        )
    if log.masked is not None:
        lines.append(
            f"  masked           {log.masked.sum() * log.dt:.1f} s that no segment spans "
            "(gaps, reversing, positions that disagree with the wheels):"
        )
        lines += [f"    {note}" for note in log.mask_notes]
    return lines
