"""The graph layer shared by calibration (``pipeline``) and ``localization``.

* :mod:`~graphcal.graph.keys` — every key, one encoding;
* :mod:`~graphcal.graph.levenberg_marquardt` — the damping, step and convergence rules;
* :mod:`~graphcal.graph.solve` — Levenberg–Marquardt on one whole graph;
* :mod:`~graphcal.graph.covariance` — covariance from information, marginals;
* :mod:`~graphcal.graph.plausibility` — is an estimated theta a plausible vehicle;
* :mod:`~graphcal.graph.observability` — which parameters the data determined;
* :mod:`~graphcal.graph.chunking` — chunks of a segment;
* segment graphs: :mod:`~graphcal.graph.graph_spec` (their shape),
  :mod:`~graphcal.graph.builder` (the one builder of chunked segment graphs),
  :mod:`~graphcal.graph.built_graph`, :mod:`~graphcal.graph.segment_solve` (build, solve,
  check theta) and :mod:`~graphcal.graph.estimates` (what a solve returns);
* part by part: :mod:`~graphcal.graph.partition` (the split at the shared keys),
  :mod:`~graphcal.graph.partitioned` (the graph solved part by part),
  :mod:`~graphcal.graph.partitioned_lm` (its iterations), :mod:`~graphcal.graph.part_group`
  (per-part elimination), :mod:`~graphcal.graph.part_workers` (worker processes),
  :mod:`~graphcal.graph.linear_systems`, :mod:`~graphcal.graph.values` and
  :mod:`~graphcal.graph.reduced_systems` (each segment's system reduced to the shared
  variables, for batches).
"""
