"""Estimation maths no single experiment owns: angles, Kalman helpers, diffuse RLS, metrics."""
