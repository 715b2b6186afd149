"""A 3-axis IMU in its own frame: the mounting convention, a given or estimated mounting, and
its signals rotated into the vehicle frame."""
