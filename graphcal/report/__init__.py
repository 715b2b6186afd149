"""Reports of a calibration run: tables in display units, figures, result files."""
