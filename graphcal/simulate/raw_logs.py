"""A synthetic recording with its sensors' raw logs instead of CSVs: what ``graphcal simulate
--streams DIR --can --nmea`` writes (issue 35).

The samples are the recording's, at its rates; only their encoding differs from the CSVs.
With ``can``, the wheels and the IMU are a car's CAN bus as a candump ``-L`` log
(:data:`CAN_LOG_NAME`) with its DBC (:data:`DBC_NAME`, :data:`graphcal.simulate.can_log.CAR_DBC`):
the rear wheel speeds in km/h, the yaw rate and lateral acceleration in a multiplexed message,
unrelated traffic and a few corrupt frames (:func:`graphcal.simulate.can_bus.can_frames`).
With ``nmea``, the GNSS is a receiver's NMEA 0183 log (:data:`NMEA_NAME`): GGA + RMC per fix,
positions only (:func:`graphcal.simulate.nmea.receiver_fixes`). The other streams are CSVs as
:func:`graphcal.simulate.streams.write_streams` writes them; ``manifest.toml`` reads every file
and ``truth.json`` holds ``theta_true``.
"""

from __future__ import annotations

import os
from pathlib import Path

from graphcal.files import atomic_write_csv, atomic_write_text
from graphcal.simulate.streams import SyntheticRecording, replace_section, write_truth

#: The candump log of the car's bus and its DBC, in the recording's directory.
CAN_LOG_NAME, DBC_NAME = "drive.log", "car.dbc"
#: The receiver's NMEA 0183 log, in the recording's directory.
NMEA_NAME = "receiver.nmea"


def write_raw_logs(
    sim: SyntheticRecording,
    directory: str | os.PathLike[str],
    *,
    can: bool = False,
    nmea: bool = False,
) -> list[Path]:
    """Write the recording into ``directory`` with its wheels and IMU as a CAN log and DBC
    (``can``; the recording must have wheel speeds and an IMU) and its GNSS as an NMEA log
    (``nmea``), the rest as CSVs, with ``manifest.toml`` and ``truth.json`` (module
    docstring); returns the paths written."""
    if can and (sim.settings.wheel_kind != "speed" or sim.imu is None):
        raise ValueError("a CAN log needs a recording with wheel speeds and an IMU")
    if nmea and "lat" not in sim.gnss.columns:
        raise ValueError("an NMEA log needs a recording with GNSS latitude and longitude")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    manifest = sim.manifest()
    written = []
    if nmea:
        from graphcal.simulate.nmea import nmea_section, receiver_fixes, write_nmea

        written.append(write_nmea(receiver_fixes(sim), directory / NMEA_NAME))
        manifest = replace_section(manifest, "gnss", nmea_section(NMEA_NAME))
    else:
        written.append(atomic_write_csv(sim.gnss, directory / "gnss.csv"))
    if can:
        from graphcal.simulate.can_bus import can_frames
        from graphcal.simulate.can_log import CAR_DBC, can_sections, write_candump

        written.append(atomic_write_text(directory / DBC_NAME, CAR_DBC))
        frames, _ = can_frames(sim)
        written.append(write_candump(frames, directory / CAN_LOG_NAME))
        wheels, imu = can_sections(CAN_LOG_NAME, DBC_NAME, float(sim.settings.circumference))
        manifest = replace_section(replace_section(manifest, "wheels", wheels), "imu", imu)
    else:
        written.append(atomic_write_csv(sim.wheels, directory / "wheels.csv"))
        if sim.imu is not None:
            written.append(atomic_write_csv(sim.imu, directory / "imu.csv"))
    written.append(write_truth(sim, directory))
    written.append(atomic_write_text(directory / "manifest.toml", manifest))
    return written
