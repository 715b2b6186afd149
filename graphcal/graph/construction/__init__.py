"""What a graph holds and how it is built: the keys, a segment graph's shape
(:class:`~graphcal.graph.construction.graph_spec.SegmentGraphSpec`), chunks, the one builder
and what it built, the Gauss–Markov priors of slip and the fixes' shared error, and a
localization graph's keyframes. Imports only ``graph.optimization``."""
