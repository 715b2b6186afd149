"""A log calibrated end to end: ``run_calibration`` and its ``CalibrationRun``, the trust
checks, validation on data held apart, ``calibrate_file``, and what localization takes from
a calibration. The top pipeline package: it may import every other."""
