"""The graph layer shared by calibration (``pipeline``) and ``localization``.

* :mod:`~graphcal.graph.keys` — every key, one encoding;
* :mod:`~graphcal.graph.solve` — Levenberg–Marquardt and marginal covariance;
* :mod:`~graphcal.graph.plausibility` — is an estimated theta a plausible vehicle;
* :mod:`~graphcal.graph.observability` — which parameters the data determined;
* :mod:`~graphcal.graph.chunking` — chunks of a segment;
* :mod:`~graphcal.graph.builder` — the one builder of chunked segment graphs.
"""
