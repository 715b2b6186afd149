"""One factor-graph solve each, configured by its own settings: batch calibration (§4.1),
input estimation (§4.2), the joint graph (warm start, robust fix weights, slip screen,
residual noise), and the worker processes they fan out over. The lowest pipeline package:
it imports no other."""
