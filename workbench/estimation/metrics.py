"""Error metrics: bias, RMSE, maximum, NEES/NIS and their chi-square bounds.

Conventions: an error is ``truth - estimate`` (the sea paper's ``e = x - x_hat``). Steps where
an estimator has no estimate are NaN and are left out of its time averages.
"""

from __future__ import annotations

import numpy as np
from scipy import special


def bias(err: np.ndarray, axis: int = -1) -> np.ndarray:
    """Time-averaged error, NaNs ignored."""
    return np.nanmean(err, axis=axis)


def rmse(err: np.ndarray, axis: int = -1) -> np.ndarray:
    """Root mean square error, NaNs ignored."""
    return np.sqrt(np.nanmean(np.square(err), axis=axis))


def max_abs(err: np.ndarray, axis: int = -1) -> np.ndarray:
    """Largest absolute error, NaNs ignored."""
    return np.nanmax(np.abs(err), axis=axis)


def nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ``e' P^-1 e`` for stacked ``err (..., n)``, ``cov (..., n, n)``."""
    sol = np.linalg.solve(cov, err[..., None])[..., 0]
    return np.einsum("...i,...i->...", err, sol)


def chi2_band(dof: int, runs: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided band for an average of ``runs`` NEES (or NIS) values of ``dof`` dimensions.

    ``runs * mean`` is chi-square with ``runs * dof`` degrees of freedom (Bar-Shalom 5.4.2).
    """
    alpha = 1.0 - confidence
    total = dof * runs
    lo = chi2_quantile(alpha / 2.0, total) / runs
    hi = chi2_quantile(1.0 - alpha / 2.0, total) / runs
    return float(lo), float(hi)


def chi2_quantile(q: float, dof: float) -> float:
    """The chi-square quantile (``scipy.stats.chi2.ppf``) via the inverse incomplete gamma
    function, which spares the start-up cost of importing ``scipy.stats``."""
    return float(2.0 * special.gammaincinv(dof / 2.0, q))
