"""What every terrain estimator returns: both exposures' exterior orientation.

A researcher's estimator ``my_orient(data: TerrainData, cfg: TerrainConfig) -> Estimate``
returns ``position (2, 3)`` (projection centres, metres, in the scene's world frame: x east,
y north, z up) and ``angles (2, 3)`` (psi, theta, gamma in radians, the convention of
:func:`~workbench.experiments.terrain.camera.rotation`), row 0 for image I and row 1 for image
II (the one scored). ``position_cov (3, 3)``: image II's position covariance (m^2, symmetric
positive semi-definite), where the estimator has one (it gives the NEES). ``pose_cov (6, 6)``:
image II's whole orientation covariance, position then angles in the order of ``position`` and
``angles`` (m, rad), where the estimator has one: the halftone model's measurements
(:mod:`.measure`) propagate it to their standard deviations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Estimate:
    """Both exposures' orientation as an estimator gives it."""

    position: np.ndarray | None = None      # (2, 3) m
    angles: np.ndarray | None = None        # (2, 3) rad
    seconds: float = 0.0                    # set by the workbench
    extras: dict = field(default_factory=dict)
    position_cov: np.ndarray | None = None  # (3, 3) image II's position covariance, m^2
    pose_cov: np.ndarray | None = None      # (6, 6) image II's position and angles covariance


def check(est: Estimate, data, cfg, estimator) -> Estimate:
    """An estimator's answer against this type's contract: finite ``(2, 3)`` orientations, a
    PSD covariance. Raises :class:`~workbench.core.estimator.EstimateError`."""
    from workbench.core.estimator import EstimateError, as_array, psd

    if not isinstance(est, Estimate):
        raise EstimateError(f"returned {type(est).__name__}, not a terrain Estimate")
    if est.position is None or est.angles is None:
        raise EstimateError("the estimate needs position and angles")
    for what in ("position", "angles"):
        a = as_array(getattr(est, what), what, (2, 3))
        if not np.isfinite(a).all():
            raise EstimateError(f"{what} has NaN values")
        setattr(est, what, a)
    if est.position_cov is not None:
        cov = as_array(est.position_cov, "position_cov", (3, 3))
        if np.isfinite(cov).all():
            psd(cov, "position_cov", None, estimator)
        est.position_cov = cov
    if est.pose_cov is not None:
        cov = as_array(est.pose_cov, "pose_cov", (6, 6))
        if np.isfinite(cov).all():
            psd(cov, "pose_cov", None, estimator)
        est.pose_cov = cov
    return est
