"""The best rigid alignment of an estimated trajectory to the truth: Umeyama's least-squares
rotation and translation (S. Umeyama, "Least-squares estimation of transformation parameters
between two point patterns", IEEE TPAMI 13(4), 1991), without scale, as evo's ``evo_ape -a``
computes it. SLAM papers and tools report the error both raw and after this alignment: a
trajectory right in shape but rotated as a whole (an unobservable gauge, or a bad start) scores
badly raw and well aligned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.estimation.angles import wrap


@dataclass(frozen=True)
class Alignment:
    """``truth ~ R(rotation) estimate + translation`` in the plane."""

    rotation: float            # rad
    translation: np.ndarray    # (2,) m

    def apply(self, pose: np.ndarray) -> np.ndarray:
        """Poses ``(N, 3)`` (x, y, phi) moved by the alignment."""
        c, s = np.cos(self.rotation), np.sin(self.rotation)
        xy = pose[:, :2] @ np.array([[c, s], [-s, c]]) + self.translation
        return np.column_stack([xy, wrap(pose[:, 2] + self.rotation)])


def umeyama(estimate: np.ndarray, truth: np.ndarray) -> Alignment:
    """The rotation and translation that best map the points ``estimate (N, 2)`` onto ``truth
    (N, 2)`` (rows that are not finite in either are left out): the SVD of the cross-covariance,
    with the reflection removed."""
    ok = np.isfinite(estimate).all(axis=1) & np.isfinite(truth).all(axis=1)
    a, b = np.asarray(estimate, float)[ok], np.asarray(truth, float)[ok]
    if len(a) < 2:
        return Alignment(0.0, np.zeros(2))
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    cov = (b - mb).T @ (a - ma) / len(a)
    u, _, vt = np.linalg.svd(cov)
    d = np.diag([1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
    R = u @ d @ vt
    return Alignment(float(np.arctan2(R[1, 0], R[0, 0])), mb - R @ ma)


def interpolate_pose(times: np.ndarray, poses: np.ndarray, t: np.ndarray | float,
                     max_gap: float = 0.5) -> np.ndarray:
    """Poses ``(x, y, heading)`` sampled at strictly increasing ``times``, interpolated at ``t``.

    The heading along the shorter arc, wrapped; NaN rows outside the span and inside gaps over ``max_gap``.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    out = np.full((t.size, 3), np.nan)
    n = times.size
    if n == 0:
        return out
    if n == 1:
        out[t == times[0]] = poses[0]
        return out
    inside = (t >= times[0]) & (t <= times[-1])
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, n - 2)
    span = times[i + 1] - times[i]
    frac = (t - times[i]) / span
    ok = inside & ((span <= max_gap) | (frac <= 0.0) | (frac >= 1.0))
    i, frac = i[ok], frac[ok]
    p0, p1 = poses[i], poses[i + 1]
    out[ok, :2] = p0[:, :2] + frac[:, None] * (p1[:, :2] - p0[:, :2])
    out[ok, 2] = wrap(p0[:, 2] + frac * wrap(p1[:, 2] - p0[:, 2]))
    return out
