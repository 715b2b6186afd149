"""Calibration pipelines: graph solves over segments, validation and the end-to-end run."""
