"""Angle helpers. Radians inside the code; degrees and arcminutes only at the edges."""

from __future__ import annotations

import numpy as np

ARCMIN = np.pi / (180.0 * 60.0)
"""One arcminute in radians."""


def wrap(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to (-pi, pi]."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def to_arcmin(angle_rad: np.ndarray | float) -> np.ndarray | float:
    """Radians to arcminutes."""
    return np.asarray(angle_rad) / ARCMIN if np.ndim(angle_rad) else float(angle_rad) / ARCMIN


def from_arcmin(angle_arcmin: np.ndarray | float) -> np.ndarray | float:
    """Arcminutes to radians."""
    return np.asarray(angle_arcmin) * ARCMIN if np.ndim(angle_arcmin) else float(angle_arcmin) * ARCMIN
