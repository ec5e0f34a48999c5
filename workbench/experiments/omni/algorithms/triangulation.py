"""Landmark initialisation (1)-(5): triangulation of two bearings, pushed through the UT,
accepted only when the landmark's distribution is close to Gaussian.

Reading taken (``spec/omni.md``): equation (1) as printed has its indices swapped; the
correct form, derived from the two rays ``p_i + s_i d_i`` and ``p_j + s_j d_j`` with
``d = (cos(phi + theta), sin(phi + theta))``, is

    x_L = (x_i s_i c_j - x_j s_j c_i + (y_j - y_i) c_i c_j) / (s_i c_j - s_j c_i)
    y_L = (y_j s_i c_j - y_i s_j c_i + (x_i - x_j) s_i s_j) / (s_i c_j - s_j c_i)

(:func:`triangulate_printed` keeps the printed one, for the test that shows it wrong). The
gate: every sigma point's rays meet in front of both views, the rays' parallax is at least
``min_parallax``, and the skewness ``gamma_1`` of (5) is below ``skew_gate`` on both axes of
the current vehicle frame (in world axes the pose's own uncertainty dilutes it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.estimation import unscented
from workbench.estimation.angles import wrap


def rays(mu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For rows ``[x_i, y_i, phi_i, x_j, y_j, phi_j, theta_i, theta_j]``: the landmark, and the
    distances ``s_i``, ``s_j`` along each ray (negative: behind that view)."""
    mu = np.atleast_2d(mu)
    ai = mu[:, 2] + mu[:, 6]
    aj = mu[:, 5] + mu[:, 7]
    ci, si, cj, sj = np.cos(ai), np.sin(ai), np.cos(aj), np.sin(aj)
    denom = ci * sj - si * cj
    dx, dy = mu[:, 3] - mu[:, 0], mu[:, 4] - mu[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        s_i = (dx * sj - dy * cj) / denom
        s_j = (dx * si - dy * ci) / denom
    point = np.stack([mu[:, 0] + s_i * ci, mu[:, 1] + s_i * si], axis=1)
    return point, s_i, s_j


def triangulate(mu: np.ndarray) -> np.ndarray:
    """Equation (1), corrected: the landmark ``(P, 2)`` for rows of ``mu (P, 8)``."""
    return _equation_1(mu, printed=False)


def triangulate_printed(mu: np.ndarray) -> np.ndarray:
    """Equation (1) exactly as printed (indices swapped): wrong, kept for the test."""
    return _equation_1(mu, printed=True)


def _equation_1(mu: np.ndarray, printed: bool) -> np.ndarray:
    mu = np.atleast_2d(mu)
    ai = mu[:, 2] + mu[:, 6]
    aj = mu[:, 5] + mu[:, 7]
    ci, si, cj, sj = np.cos(ai), np.sin(ai), np.cos(aj), np.sin(aj)
    xi, yi, xj, yj = mu[:, 0], mu[:, 1], mu[:, 3], mu[:, 4]
    # the printed numerators pair s_i with c_i and s_j with c_j; the rays need s_i c_j, s_j c_i
    a, b = (si * ci, sj * cj) if printed else (si * cj, sj * ci)
    den = si * cj - sj * ci
    with np.errstate(divide="ignore", invalid="ignore"):
        x = (xi * a - xj * b + (yj - yi) * ci * cj) / den
        y = (yj * a - yi * b + (xi - xj) * si * sj) / den
    return np.stack([x, y], axis=1)


def jacobian(mu: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``dg/dmu`` ``(2, 8)`` by central differences (one vectorised call of (1))."""
    pts = np.repeat(mu[None, :], 16, axis=0)
    idx = np.arange(8)
    pts[idx, idx] += step
    pts[idx + 8, idx] -= step
    g = triangulate(pts)
    with np.errstate(invalid="ignore"):  # parallel rays: inf - inf, reported as NaN
        return ((g[:8] - g[8:]) / (2 * step)).T


@dataclass
class Attempt:
    """One try at initialising a landmark from two sightings."""

    accepted: bool
    reason: str
    mean: np.ndarray
    cov: np.ndarray
    skewness: np.ndarray
    parallax: float
    points: np.ndarray


def parallax(mu: np.ndarray) -> float:
    """The angle between the two rays of ``mu`` (8-dim, as :func:`rays`' rows), radians."""
    return float(abs(wrap((mu[5] + mu[7]) - (mu[2] + mu[6]))))


def attempt(mu: np.ndarray, cov: np.ndarray, skew_gate: float, min_parallax: float,
            kappa: float = 1.0) -> Attempt:
    """Triangulate ``N(mu, cov)`` (8-dim, (2)-(3)) through the UT (4)-(5) and apply the gate."""
    angle = parallax(mu)
    points, weights = unscented.sigma_points(mu, cov, kappa)
    images, s_i, s_j = rays(points)
    with np.errstate(invalid="ignore"):  # a sigma point on parallel rays is inf: rejected below
        ut = unscented.moments(images, weights)
        c, s = np.cos(mu[5]), np.sin(mu[5])
        skew = ut.skewness(np.array([[c, -s], [s, c]]))
    if not (np.all(s_i > 0) and np.all(s_j > 0) and np.isfinite(ut.points).all()):
        return Attempt(False, "behind", ut.mean, ut.cov, skew, angle, ut.points)
    if angle < min_parallax:
        return Attempt(False, "parallax", ut.mean, ut.cov, skew, angle, ut.points)
    if np.max(np.abs(skew)) >= skew_gate:
        return Attempt(False, "skewness", ut.mean, ut.cov, skew, angle, ut.points)
    return Attempt(True, "ok", ut.mean, ut.cov, skew, angle, ut.points)
