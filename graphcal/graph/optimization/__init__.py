"""Levenberg–Marquardt on any GTSAM graph, whole or part by part: how a solve runs and
ended, the one damping, step and convergence rule, the rollout of chunk-boundary poses, the
split at the shared keys and the worker processes the parts are shared out among. The lowest
graph package: it imports no other, and knows no key or segment."""
