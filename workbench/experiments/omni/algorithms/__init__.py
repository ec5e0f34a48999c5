"""The omni experiment's estimators: the EKF-SLAM, the factor graph, the fixed-lag smoother, and
the triangulation and residuals they share."""
