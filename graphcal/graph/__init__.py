"""The graph layer shared by calibration (``pipeline``) and ``localization``.

Three packages, each importing only those before it (``tests/test_architecture.py``)::

    optimization < construction < solution

* ``optimization``: Levenberg–Marquardt on any GTSAM graph, knowing no key or segment —
  :mod:`~graphcal.graph.optimization.solve_options` (how a solve runs and how it ended),
  :mod:`~graphcal.graph.optimization.levenberg_marquardt` (the damping, step and
  convergence rules), :mod:`~graphcal.graph.optimization.solve` (one whole graph),
  :mod:`~graphcal.graph.optimization.rollout` (chunk-boundary poses rolled out after a
  step), :mod:`~graphcal.graph.optimization.linear_systems`,
  :mod:`~graphcal.graph.optimization.values`, and part by part:
  :mod:`~graphcal.graph.optimization.partition` (the split at the shared keys),
  :mod:`~graphcal.graph.optimization.partitioned` (the graph solved part by part),
  :mod:`~graphcal.graph.optimization.partitioned_lm` (its iterations),
  :mod:`~graphcal.graph.optimization.part_group` (per-part elimination) and
  :mod:`~graphcal.graph.optimization.part_workers` (worker processes).
* ``construction``: what a graph holds and how it is built —
  :mod:`~graphcal.graph.construction.keys` (every key, one encoding),
  :mod:`~graphcal.graph.construction.graph_spec` (a segment graph's shape),
  :mod:`~graphcal.graph.construction.chunking` (chunks of a segment),
  :mod:`~graphcal.graph.construction.builder` (the one builder of chunked segment graphs),
  :mod:`~graphcal.graph.construction.built_graph` (what it built), the Gauss–Markov priors
  of slowly varying quantities (:mod:`~graphcal.graph.construction.gauss_markov`,
  :mod:`~graphcal.graph.construction.slip`,
  :mod:`~graphcal.graph.construction.chunk_processes`) and a localization graph's
  :mod:`~graphcal.graph.construction.keyframes`.
* ``solution``: a segment graph solved and what is read off its solution —
  :mod:`~graphcal.graph.solution.segment_solve` (build, optimize, check theta, covariance),
  :mod:`~graphcal.graph.solution.estimates` (what a solve returns),
  :mod:`~graphcal.graph.solution.covariance` (covariance from information, marginals),
  :mod:`~graphcal.graph.solution.plausibility` (is an estimated theta a plausible vehicle),
  :mod:`~graphcal.graph.solution.observability` (which parameters the data determined) and
  :mod:`~graphcal.graph.solution.reduced_systems` (each segment's system reduced to the
  shared variables, for batches).
"""
