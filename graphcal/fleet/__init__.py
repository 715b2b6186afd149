"""Fleet calibration: every vehicle's daily logs calibrated as Dask tasks, and its history.

* :mod:`graphcal.fleet.sources` — which logs: a directory tree ``VEHICLE/DAY.csv`` or a CSV
  manifest ``vehicle, day, path``;
* :mod:`graphcal.fleet.task` — one log's whole-log calibration (the Dask task) and the key
  that makes a run resumable (content hash and settings);
* :mod:`graphcal.fleet.history` — per vehicle: changes of theta between days and the
  combined theta of the days since the last change;
* :mod:`graphcal.fleet.run` — the run on a ``LocalCluster`` or a running scheduler, results
  written as they arrive;
* :mod:`graphcal.fleet.interrupt` — Ctrl-C: one line from graphcal, none from Dask's workers;
* :mod:`graphcal.fleet.report` — ``fleet.csv``, ``vehicles.csv`` and ``fleet.png``.

Dask and tqdm come with the ``fleet`` extra (``pip install -e ".[fleet]"``).
"""
