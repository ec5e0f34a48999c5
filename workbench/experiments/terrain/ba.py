"""The baseline: GTSAM bundle adjustment of the pair with navigation priors and the DEM.

Tie points: SIFT on both images, Lowe's ratio test (0.75), RANSAC on the fundamental matrix.
Graph (``spec/terrain.md``): ``Pose3`` for both exposures with ``PriorFactorPose3`` from the
navigation system (sigma = the maximum error / sqrt(3) for uniform errors, / 3 for Gaussian);
in the common-error mode a ``BetweenFactorPose3`` with the measured relative motion (its
translation uncertain by the velocity error times the interval, its rotation nearly exact, as
the attitude errors are common); in the ii-only mode image I's prior is tight (exact);
``GenericProjectionFactorCal3_S2`` for every tie point in both images (1 px, Huber); and a
height factor per tie point, ``z - h(x, y)`` on the DEM (``dem_sigma``), the one
``CustomFactor`` (built-in factors have no DEM). Levenberg-Marquardt from the measured
orientation, tie points started on the DEM; marginals give the refined orientation's covariance.
"""

from __future__ import annotations

import numpy as np

from workbench.errors import require
from workbench.experiments.terrain import camera
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.dem import Dem


def _gray8(image: np.ndarray) -> np.ndarray:
    lo, hi = np.percentile(image, [0.5, 99.5])
    return np.clip(255 * (image - lo) / max(hi - lo, 1e-9), 0, 255).astype(np.uint8)


def tie_points(img1: np.ndarray, img2: np.ndarray, features: int) -> tuple[np.ndarray, np.ndarray]:
    """Matched pixels ``(M, 2)`` in both images: SIFT, ratio test, RANSAC fundamental matrix."""
    import cv2

    sift = cv2.SIFT_create(nfeatures=features)
    a, b = _gray8(img1), _gray8(img2)
    k1, d1 = sift.detectAndCompute(a, None)
    k2, d2 = sift.detectAndCompute(b, None)
    if d1 is None or d2 is None or len(k1) < 8 or len(k2) < 8:
        return np.zeros((0, 2)), np.zeros((0, 2))
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(d1, d2, k=2)
    good = [m for m, n in (p for p in pairs if len(p) == 2) if m.distance < 0.75 * n.distance]
    if len(good) < 8:
        return np.zeros((0, 2)), np.zeros((0, 2))
    p1 = np.array([k1[m.queryIdx].pt for m in good])
    p2 = np.array([k2[m.trainIdx].pt for m in good])
    _, mask = cv2.findFundamentalMat(p1, p2, cv2.FM_RANSAC, 1.5, 0.999)
    if mask is None:
        return np.zeros((0, 2)), np.zeros((0, 2))
    keep = mask.ravel().astype(bool)
    return p1[keep], p2[keep]


def _height_factor(noise, key: int, dem: Dem):
    import gtsam

    def error(this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None) -> np.ndarray:
        p = values.atPoint3(this.keys()[0])
        h, hx, hy = dem.sample(np.array([p[0]]), np.array([p[1]]), strict=False)
        if jacobians is not None:
            jacobians[0] = np.array([[-hx[0], -hy[0], 1.0]])
        return np.array([p[2] - h[0]])

    return gtsam.CustomFactor(noise, [key], error)


def adjust(cfg: TerrainConfig, scene, position: np.ndarray, angles: np.ndarray):
    """Refine both exposures' orientation from the measured one; returns a run ``Estimate``."""
    import gtsam
    from gtsam.symbol_shorthand import L, X

    from workbench.experiments.terrain.run import Estimate

    origin = np.array([np.round(position[0, 0]), np.round(position[0, 1]), 0.0])
    dem = Dem(scene.dem.heights, scene.dem.x0 - origin[0], scene.dem.y0 - origin[1], scene.dem.dx, scene.dem.dy)
    pos = np.asarray(position, float) - origin
    rot = camera.rotation(angles)
    k = scene.k
    uv1, uv2 = tie_points(scene.images[0], scene.images[1], cfg.features)
    require(len(uv1) >= 6, f"gtsam-ba: only {len(uv1)} tie points survive matching; the pair is too weak")
    cal = gtsam.Cal3_S2(k.fx, k.fy, 0.0, k.cx, k.cy)
    poses = [gtsam.Pose3(gtsam.Rot3(rot[i]), gtsam.Point3(*pos[i])) for i in range(2)]
    div = np.sqrt(3.0) if cfg.distribution == "uniform" else 3.0
    s_lin, s_ang = cfg.max_linear / div, cfg.max_angular / div
    prior = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, s_ang), np.full(3, s_lin)])
    tight = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, 1e-7), np.full(3, 1e-4)])
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    for i in range(2):
        values.insert(X(i), poses[i])
    if cfg.mode == "ii-only":
        graph.add(gtsam.PriorFactorPose3(X(0), poses[0], tight))
        graph.add(gtsam.PriorFactorPose3(X(1), poses[1], prior))
    else:
        graph.add(gtsam.PriorFactorPose3(X(0), poses[0], prior))
        graph.add(gtsam.PriorFactorPose3(X(1), poses[1], prior))
        s_rel = max(cfg.max_velocity * scene.interval / div, 1e-3)
        between = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, 1e-5), np.full(3, s_rel)])
        graph.add(gtsam.BetweenFactorPose3(X(0), X(1), poses[0].between(poses[1]), between))
    pix = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(1.345),
                                         gtsam.noiseModel.Isotropic.Sigma(2, 1.0))
    height = gtsam.noiseModel.Isotropic.Sigma(1, cfg.dem_sigma)
    start = camera.ground_points(dem, k, pos[0], rot[0], uv1[:, 0], uv1[:, 1], what="the tie points")
    for j in range(len(uv1)):
        graph.add(gtsam.GenericProjectionFactorCal3_S2(gtsam.Point2(*uv1[j]), pix, X(0), L(j), cal))
        graph.add(gtsam.GenericProjectionFactorCal3_S2(gtsam.Point2(*uv2[j]), pix, X(1), L(j), cal))
        graph.add(_height_factor(height, L(j), dem))
        values.insert(L(j), gtsam.Point3(*start[j]))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(50)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    out_pos = np.array([result.atPose3(X(i)).translation() for i in range(2)]) + origin
    out_rot = np.array([result.atPose3(X(i)).rotation().matrix() for i in range(2)])
    extras: dict = {"tie_points": (uv1, uv2), "error_before": graph.error(values), "error_after": graph.error(result),
                    "landmarks": np.array([result.atPoint3(L(j)) for j in range(len(uv1))]) + origin}
    try:
        marg = gtsam.Marginals(graph, result)
        extras["covariance"] = np.stack([marg.marginalCovariance(X(i)) for i in range(2)])
        r2 = out_rot[1]  # Pose3's tangent is (rotation, translation) in the body frame: to world
        extras["position_cov"] = r2 @ extras["covariance"][1][3:, 3:] @ r2.T
    except RuntimeError:
        extras["covariance"] = None
    return Estimate(out_pos, camera.angles_from_rotation(out_rot), 0.0, extras)
