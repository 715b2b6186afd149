"""Benchmarks: graphcal's solves measured side by side with the naive GTSAM formulation."""
