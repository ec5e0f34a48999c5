"""Experiment ``sea``: object position on the sea surface from a monocular camera (seed 002)."""
