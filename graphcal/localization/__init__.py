"""graphcal inside a GTSAM localization: factors, value conversions, smoothing, online
recalibration and dead reckoning through GNSS outages.

* :mod:`~graphcal.localization.keyframe_odometry` — wheel odometry between Pose2 keyframes
  of your graph, with theta as a variable (or fixed) and the wheel noise propagated;
* :mod:`~graphcal.localization.values` — theta and states to and from ``gtsam.Values``;
* :mod:`~graphcal.localization.smoothing` — a GNSS + wheel-odometry smoothing graph that
  calibrates theta in the same solve;
* :mod:`~graphcal.localization.online` — theta as a random walk in a fixed-lag smoother;
* :mod:`~graphcal.localization.dead_reckoning` — position errors through GNSS outages.
"""
