"""The Unscented Transform (Julier & Uhlmann 1997), with the per-axis skewness of its output.

Sigma points ``X_0 = mu``, ``X_{+-i} = mu +- sqrt((n + kappa) P)_i`` with weights
``W_0 = kappa / (n + kappa)``, ``W_i = 1 / (2 (n + kappa))``: they satisfy the paper 000's
conditions (4) (weights sum to one, the points' mean is ``mu`` and their covariance ``P``).
``kappa >= 0`` keeps every weight non-negative, so the output covariance (5) is PSD.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from workbench.errors import require


def psd_sqrt(cov: np.ndarray) -> np.ndarray:
    """A square root ``S`` with ``S S' = cov`` for a symmetric PSD (possibly singular) matrix.

    Cholesky where it works; else the eigen-decomposition with negative round-off clipped.
    """
    try:
        return np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        return vecs * np.sqrt(np.clip(vals, 0.0, None))


def sigma_points(mean: np.ndarray, cov: np.ndarray, kappa: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The ``2n + 1`` sigma points ``(2n+1, n)`` and their weights ``(2n+1,)``."""
    require(kappa >= 0.0, f"UT kappa must be >= 0 so that every weight is non-negative (got {kappa})")
    n = mean.shape[0]
    root = psd_sqrt((n + kappa) * cov)
    points = np.empty((2 * n + 1, n))
    points[0] = mean
    points[1:n + 1] = mean + root.T
    points[n + 1:] = mean - root.T
    weights = np.full(2 * n + 1, 0.5 / (n + kappa))
    weights[0] = kappa / (n + kappa)
    return points, weights


@dataclass
class Transformed:
    """The UT's output: sigma images ``Y``, mean (5), covariance (5) and per-axis skewness."""

    points: np.ndarray
    weights: np.ndarray
    mean: np.ndarray
    cov: np.ndarray

    def skewness(self, axes: np.ndarray | None = None) -> np.ndarray:
        """Skewness ``gamma_1`` of (5) along the columns of ``axes`` (default: the coordinate axes).

        ``gamma_1 = sum W_i d_i^3 / (sum W_i d_i^2)^(3/2)`` with ``d_i`` the sigma image's
        deviation from the mean projected on the axis.
        """
        dev = self.points - self.mean
        if axes is not None:
            dev = dev @ axes
        var = self.weights @ dev**2
        third = self.weights @ dev**3
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(var > 0, third / np.power(var, 1.5), 0.0)


def transform(fn: Callable[[np.ndarray], np.ndarray], mean: np.ndarray, cov: np.ndarray,
              kappa: float = 1.0) -> Transformed:
    """Push ``N(mean, cov)`` through ``fn`` (which maps ``(P, n) -> (P, m)``, vectorised)."""
    points, weights = sigma_points(mean, cov, kappa)
    return moments(fn(points), weights)


def moments(images: np.ndarray, weights: np.ndarray) -> Transformed:
    """Mean and covariance (5) of sigma images ``(2n+1, m)`` with their weights."""
    mu = weights @ images
    dev = images - mu
    cov_out = (weights[:, None] * dev).T @ dev
    return Transformed(images, weights, mu, 0.5 * (cov_out + cov_out.T))
