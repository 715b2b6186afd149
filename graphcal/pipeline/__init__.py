"""Calibration pipelines: graph solves over segments, validation and the end-to-end run.

Four packages, each importing only those before it (``tests/test_architecture.py``)::

    solvers < configuration < methods < end_to_end

* ``solvers``: one factor-graph solve each, configured by its own settings — batch
  calibration (§4.1), input estimation (§4.2), the joint graph with its warm start, robust
  fix weights, slip screen and residual noise — and the worker processes they fan out over.
* ``configuration``: a run's :class:`Settings` (composing the solvers' settings), its TOML
  and vehicle files, and ``configure_settings``.
* ``methods``: what a run does with one log under those settings — segment selection and
  preparation, the paper's staged method, the whole-log joint procedure (noise levels,
  parameters held at their prior, sensor estimates, the segments' agreement, the batch
  study, the model check) and validation (eq. 16).
* ``end_to_end``: a log calibrated end to end — ``run_calibration``, its
  ``CalibrationRun``, the trust checks, validation on data held apart, ``calibrate_file``
  and what localization takes from a calibration.
"""
