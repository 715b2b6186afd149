"""Recordings: sensor streams at their own rates, read from their sources and imported into
a drive log.

* :mod:`.vocabulary` — the units and kinds every source speaks (a leaf);
* :mod:`.streams`, :mod:`.stream_grid`, :mod:`.geodesy`, :mod:`.wheel_scale` — the stream types
  and conversions the sources share;
* one package per source, each importing only those and its own library: :mod:`.manifest`
  (a TOML manifest's CSV files), :mod:`.bag` (ROS bags, MCAP), :mod:`.can` (a raw CAN log and
  its DBC), :mod:`.nmea` (a receiver's NMEA log), :mod:`.imu` (a 3-axis IMU's mounting);
* :mod:`.manifest_recording` — which source reads each section of a manifest;
* the import (:mod:`.importer`, :mod:`.resampling`, :mod:`.import_checks`, ...) — the streams
  onto one grid, checked, as a :class:`~graphcal.log.drive_log.DriveLog`.
"""
