"""graphcal: wheel-odometry calibration with noise compensation, as GTSAM factor graphs."""

__version__ = "0.1.0"
