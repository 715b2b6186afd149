"""A segment graph solved and what is read off its solution: the solve (build, optimize,
check theta's plausibility, covariance), the estimates it returns, covariance from
information, plausibility, observability and each segment's reduced system for batches. The
top graph package: it may import every other."""
