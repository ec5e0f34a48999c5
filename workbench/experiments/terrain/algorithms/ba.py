"""The baseline: GTSAM bundle adjustment of the pair with navigation priors and the DEM.

Tie points: SIFT on both images (with OpenCV's precise upscaling: without it SIFT reports every
keypoint a quarter pixel right of and below where it is, a bias common to both images that
shifts the whole model), Lowe's ratio test (0.75), RANSAC on the fundamental matrix.

Graph (``spec/terrain.md``): ``Pose3`` for both exposures, ``GenericProjectionFactorCal3_S2``
for every tie point in both images and a height factor per tie point, ``z - h(x, y)`` on the
bilinear DEM (a ``CustomFactor``: built-in factors have no DEM), both Huber. The navigation
system enters as its error model says:

* ``common``: ONE error process, so ONE ``PriorFactorPose3``, on image I (sigma = the maximum
  error / sqrt(3) for uniform errors, / 3 for Gaussian), and the measured relative motion as a
  between: its rotation nearly exact (the attitude errors are common; the sigma is three times
  what common Euler-angle errors leave in the relative rotation at these attitudes, at least
  ``RELATIVE_ROTATION_FLOOR``) and its translation, in
  the WORLD frame, uncertain in X and Y by the velocity errors times the interval and exact in
  H (the error model has no vertical velocity error).
* ``ii-only``: image I's prior is tight (exact), image II's is the navigation prior.

Noise: the sigmas of the two observation groups are estimated from the tie points themselves,
at the poses of the latest solve: the pixel sigma from the reprojection residuals of each tie
point triangulated from its pixels alone (one degree of freedom each), the height sigma from
the scatter of those triangulated heights about the DEM less their stereo part (robust: medians;
never below ``cfg.dem_sigma``, the DEM's stated accuracy: the data can show that features sit
off the modelled surface, not that the DEM is better than stated). Tie points beyond
``OUTLIER`` sigmas are dropped (SIFT matches along the epipolar line survive RANSAC and can
triangulate kilometres off), and the graph is solved again until the sigmas settle (three or
four solves). The solves are graduated: the first holds the DEM loosely (``LOOSE_HEIGHT``) to
get into the basin from a start 100 m off, the second at the DEM's stated accuracy
(``cfg.dem_sigma``), and only then are the sigmas estimated: the scatter of the tie points about
the DEM says how good the DEM is only where the DEM has been used. Estimated straight after the
loose solve, it measured the loose solve's own misplacement: on ngi 0251/0253 (common mode, seed
0, run 2) the loose solve stopped in the flat cost 80 m off in X, the height sigma read there was
17-19 m, and that loose DEM kept the adjustment 76 m off; solved at 5 m first, it reaches 13 m
(10 runs: mean 19.7 -> 13.5 m; 0182/0184 and ii-only unchanged within 0.5 m).
Levenberg-Marquardt from the measured orientation, tie points started on the DEM; marginals give
the refined orientation's covariance.

Why the BA was worse than the search on the real pair (ngi 0182/0184 at 160 x 288, ~23 m
pixels, 100 m / 3 mrad uniform errors, seed 0; image II's mean position error over 20 runs,
common mode; undoing one fix at a time from the final version):

    final 16.7 m | fixed sigmas (1 px, 5 m) 34.9 | SIFT's quarter-pixel bias 25.2 |
    body-frame between 18.7 | prior on both exposures 17.2 | all undone (the old BA) 38.0

(ii-only: final 7.4, old 10.7; synthetic 200 x 200, 8 runs: common 6.7 -> 4.0, ii-only
3.5 -> 1.8.) The causes:

* fixed sigmas of 1 px and 5 m misweighted the data against the priors, so the result shrank
  towards the measured orientation: SIFT's tie points agree to about 0.12 px on both scenes,
  while on the real pair their triangulated heights scatter about the real DEM by 6-8 m beyond
  their stereo noise (the DEM is a 24 m grid over relief with slopes of 0.7 rms);
* OpenCV's SIFT without precise upscaling puts every keypoint a quarter pixel right of and below
  where it is: a bias common to both images, 6 m on the ground at 23 m pixels;
* the common mode held the between's translation in image I's body frame, where the common
  attitude error (3 mrad over the 2.6 km baseline: 8 m) enters the relative motion, and left its
  height free although the error model has no vertical velocity error;
* the common mode put the navigation prior on BOTH exposures: one error counted twice.

What remains is genuine, not a bug. The truth is consistent with the images and the DEM (tie
points reproject under the true orientation to about 0.1 px, and their cloud fits the DEM with a
shift of about 2 m at 640 x 1152). But in the common mode the relative orientation is known, so
all the absolute information is the fit of ONE stereo model to the DEM, and at 160 x 288 the
real frames overlap by only 30 %: about 65 tie points in a 1 x 6.6 km strip. The data alone (no
navigation prior) place image II to (11, 19, 14) m (1 sigma, X, Y, H), and the same tie points
serve every run, so their one noise realisation shows as a common offset of the runs' errors
(about (-8, 2, -9) m) rather than averaging out. Larger frames carry more: over 20 runs the
common mode gives 15.4 m at 320 x 576 and 9.9 m at 640 x 1152 (ii-only 6.0 and 7.1 m), but
there the covariance turns optimistic (ANEES up to 17): a few metres of model error (the true
orientation's own, the DEM's, the camera's) begin to show.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import require
from workbench.experiments.terrain import camera, navigation
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.dem import Dem
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import Scene

PIXEL_SIGMA = 0.3
"""The first solve's sigma of a tie point's pixel coordinates (px); re-estimated after it."""
LOOSE_HEIGHT = 30.0
"""The first solve's height sigma (m; or ``cfg.dem_sigma`` if larger). From a start 100 m off, a
tight DEM makes Levenberg-Marquardt crawl or stop in a local minimum of the relief (at a 0.01 m
DEM sigma the first solve ran out of its 100 iterations far from the truth)."""
RELATIVE_ROTATION_FLOOR = 1e-4
"""common mode: the least sigma of the relative rotation (rad). Common Euler-angle errors leave
about 2e-5 rad in it at the synthetic scene's attitudes; their first-order spread as the sigma
made noise-free adjustments land 5e-5 rad and 9 cm off, 1e-4 rad (0.5 m at 5 km) lets them
reach 2 cm."""
HUBER = 1.345
"""Huber threshold of both observation groups, in sigmas."""
OUTLIER = 5.0
"""Tie points with a pixel or height residual beyond this many sigmas are dropped."""
PASSES = 4
"""At most this many solves with re-estimated sigmas before the final one."""
TOLERANCE = 0.05
"""The sigmas have settled when neither moves by more than this fraction."""
RELATIVE_TOLERANCE = 1e-4
"""Levenberg-Marquardt stops when the error falls by less than this fraction: the bilinear DEM's
gradient jumps at cell edges, so the last digits crawl (0.01 of ~300 per iteration, moving the
poses by centimetres) for dozens of iterations."""
VERTICAL = 0.1
"""common mode: the sigma of the relative motion's height (m); exact in the error model, and
tighter only slows Levenberg-Marquardt."""
PIXEL_FLOOR = 0.01
"""The smallest pixel sigma (px) the estimate may reach."""
MIN_TIE_POINTS = 6
CHI2_1_MEDIAN = 0.45494
"""The median of a chi-square variable with one degree of freedom."""


def _gray8(image: np.ndarray) -> np.ndarray:
    lo, hi = np.percentile(image, [0.5, 99.5])
    return np.clip(255 * (image - lo) / max(hi - lo, 1e-9), 0, 255).astype(np.uint8)


def tie_points(img1: np.ndarray, img2: np.ndarray, features: int) -> tuple[np.ndarray, np.ndarray]:
    """Matched pixels ``(M, 2)`` in both images (pixel centres at integers): SIFT with precise
    upscaling, ratio test, RANSAC fundamental matrix."""
    import cv2

    sift = cv2.SIFT_create(nfeatures=features, enable_precise_upscale=True)
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


def dem_height(dem: Dem, x: float, y: float) -> tuple[float, float, float]:
    """:meth:`Dem.sample` (height, dh/dX, dh/dY; the edge held outside) for one point in plain
    floats: the height factor runs it for every tie point in every iteration, and numpy's
    per-call overhead was most of the adjustment's time."""
    rows, cols = dem.heights.shape
    c = min(max((x - dem.x0) / dem.dx, 0.0), cols - 1.000001) if math.isfinite(x) else 0.0
    r = min(max((y - dem.y0) / dem.dy, 0.0), rows - 1.000001) if math.isfinite(y) else 0.0
    c0, r0 = int(c), int(r)
    fc, fr = c - c0, r - r0
    z = dem.heights
    z00, z01, z10, z11 = float(z[r0, c0]), float(z[r0, c0 + 1]), float(z[r0 + 1, c0]), float(z[r0 + 1, c0 + 1])
    top = z00 + fc * (z01 - z00)
    bot = z10 + fc * (z11 - z10)
    dh_dc = (z01 - z00) + fr * ((z11 - z10) - (z01 - z00))
    return top + fr * (bot - top), dh_dc / dem.dx, (bot - top) / dem.dy


def height_factor(noise, key: int, dem: Dem):
    """``CustomFactor`` on a ``Point3``: ``z - h(x, y)`` (m) on the bilinear DEM, Jacobian
    ``(-dh/dX, -dh/dY, 1)`` (a ``Point3``'s tangent is its world coordinates)."""
    import gtsam

    def error(this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None) -> np.ndarray:
        p = values.atPoint3(this.keys()[0])
        h, hx, hy = dem_height(dem, float(p[0]), float(p[1]))
        if jacobians is not None:
            jacobians[0] = np.array([[-hx, -hy, 1.0]])
        return np.array([p[2] - h])

    return gtsam.CustomFactor(noise, [key], error)


def translation_factor(noise, key0: int, key1: int, delta: np.ndarray):
    """``CustomFactor`` on two ``Pose3``: ``(t1 - t0) - delta`` in the world frame (m). A
    ``Pose3`` retracts its translation as ``t + R v`` (tangent: rotation, then translation in the
    body frame), so the Jacobians are ``[0, -R0]`` and ``[0, R1]``."""
    import gtsam

    delta = np.asarray(delta, float)

    def error(this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None) -> np.ndarray:
        p0, p1 = values.atPose3(this.keys()[0]), values.atPose3(this.keys()[1])
        if jacobians is not None:
            jacobians[0] = np.hstack([np.zeros((3, 3)), -p0.rotation().matrix()])
            jacobians[1] = np.hstack([np.zeros((3, 3)), p1.rotation().matrix()])
        return p1.translation() - p0.translation() - delta

    return gtsam.CustomFactor(noise, [key0, key1], error)


def relative_rotation_sigma(angles: np.ndarray, sigma_angle: float) -> float:
    """What common attitude errors (``sigma_angle`` on each of psi, theta, gamma) leave in the
    relative rotation ``R_I^T R_II`` of exposures at ``angles (2, 3)``: the largest standard
    deviation of its rotation vector to first order (rad, at least 1e-6)."""
    import gtsam

    a = np.asarray(angles, float)
    rel = camera.rotation(a[0]).T @ camera.rotation(a[1])
    eps = 1e-6
    cols = []
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        moved = camera.rotation(a[0] + d).T @ camera.rotation(a[1] + d)
        cols.append(gtsam.Rot3.Logmap(gtsam.Rot3(rel.T @ moved)) / eps)
    jac = np.array(cols).T
    return float(max(sigma_angle * np.sqrt(np.linalg.eigvalsh(jac @ jac.T).max()), 1e-6))


@dataclass
class _Pair:
    """The adjustment's fixed inputs, in a local frame (``origin`` subtracted)."""

    dem: Dem
    k: camera.Intrinsics
    position: np.ndarray      # (2, 3) measured
    rotation: np.ndarray      # (2, 3, 3) measured R_wc
    angles: np.ndarray        # (2, 3) measured
    interval: float           # s between the exposures


def pose_factors(cfg: TerrainConfig, pair: _Pair) -> list:
    """The navigation system's factors for the error mode (see the module docstring)."""
    import gtsam
    from gtsam.symbol_shorthand import X

    poses = [gtsam.Pose3(gtsam.Rot3(pair.rotation[i]), gtsam.Point3(*pair.position[i])) for i in range(2)]
    div = 1.0 / navigation.sigma_fraction(cfg)       # sigma = maximum x the distribution's fraction
    s_lin, s_ang = cfg.max_linear / div, cfg.max_angular / div
    prior = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, s_ang), np.full(3, s_lin)])
    if cfg.mode == "ii-only":
        tight = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, 1e-7), np.full(3, 1e-4)])
        return [gtsam.PriorFactorPose3(X(0), poses[0], tight), gtsam.PriorFactorPose3(X(1), poses[1], prior)]
    s_rel = max(cfg.max_velocity * pair.interval / div, 1e-3)
    s_rot = max(3.0 * relative_rotation_sigma(pair.angles, s_ang), RELATIVE_ROTATION_FLOOR)
    # the rotation of the relative motion only: its translation is free here (1e6 m) and held in
    # the world frame by the translation factor
    rotation_only = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, s_rot), np.full(3, 1e6)])
    shift = gtsam.noiseModel.Diagonal.Sigmas(np.array([s_rel, s_rel, VERTICAL]))
    return [gtsam.PriorFactorPose3(X(0), poses[0], prior),
            gtsam.BetweenFactorPose3(X(0), X(1), poses[0].between(poses[1]), rotation_only),
            translation_factor(shift, X(0), X(1), pair.position[1] - pair.position[0])]


def _graph(cfg: TerrainConfig, pair: _Pair, uv1: np.ndarray, uv2: np.ndarray, keep: np.ndarray,
           sigma_pixel: float, sigma_height: float):
    """The factor graph: the pose factors, then per kept tie point ``j`` its two projections
    onto ``L(j)`` and its height factor."""
    import gtsam
    from gtsam.symbol_shorthand import L, X

    k = pair.k
    cal = gtsam.Cal3_S2(k.fx, k.fy, 0.0, k.cx, k.cy)
    huber = gtsam.noiseModel.mEstimator.Huber.Create(HUBER)
    pix = gtsam.noiseModel.Robust.Create(huber, gtsam.noiseModel.Isotropic.Sigma(2, sigma_pixel))
    height = gtsam.noiseModel.Robust.Create(huber, gtsam.noiseModel.Isotropic.Sigma(1, sigma_height))
    graph = gtsam.NonlinearFactorGraph()
    for f in pose_factors(cfg, pair):
        graph.add(f)
    for j in np.flatnonzero(keep):
        graph.add(gtsam.GenericProjectionFactorCal3_S2(gtsam.Point2(*uv1[j]), pix, X(0), L(j), cal))
        graph.add(gtsam.GenericProjectionFactorCal3_S2(gtsam.Point2(*uv2[j]), pix, X(1), L(j), cal))
        graph.add(height_factor(height, L(j), pair.dem))
    return graph


def triangulate(k: camera.Intrinsics, position: np.ndarray, rotation: np.ndarray, uv1: np.ndarray,
                uv2: np.ndarray, start: np.ndarray, iterations: int = 6
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tie points from their pixels alone at fixed poses (Gauss-Newton from ``start (M, 3)``):
    the points, their squared reprojection residuals summed over the four coordinates (px^2, one
    degree of freedom each) and the normal matrices ``J^T J (M, 3, 3)`` for a unit pixel sigma."""
    g = np.array(start, float)
    obs = np.concatenate([uv1, uv2], axis=1)
    damping = 1e-12 * np.eye(3)
    for it in range(iterations + 1):
        res, jac = [], []
        for i in range(2):
            r = rotation[i]
            q = (g - position[i]) @ r
            z = q[:, 2:3]
            res += [k.cx + k.fx * q[:, 0] / z[:, 0], k.cy + k.fy * q[:, 1] / z[:, 0]]
            jac += [k.fx * (r[:, 0][None] * z - r[:, 2][None] * q[:, 0:1]) / z ** 2,
                    k.fy * (r[:, 1][None] * z - r[:, 2][None] * q[:, 1:2]) / z ** 2]
        e = np.stack(res, axis=1) - obs
        a = np.stack(jac, axis=1)
        normal = np.einsum("mri,mrk->mik", a, a) + damping
        if it == iterations:
            return g, (e ** 2).sum(axis=1), normal
        g = g - np.linalg.solve(normal, np.einsum("mri,mr->mi", a, e)[..., None])[..., 0]
    raise AssertionError("unreachable")


@dataclass
class NoiseEstimate:
    """The two observation groups' sigmas as the tie points show them at given poses, and every
    tie point's normalised squared residuals (pixels; height over the DEM)."""

    pixel: float              # px
    height: float             # m
    pixel_z2: np.ndarray      # (M,)
    height_z2: np.ndarray     # (M,)

    def outliers(self, limit: float) -> np.ndarray:
        """Tie points beyond ``limit`` sigmas in either group (or not finite)."""
        return ~((self.pixel_z2 <= limit ** 2) & (self.height_z2 <= limit ** 2))


def estimate_noise(k: camera.Intrinsics, dem: Dem, position: np.ndarray, rotation: np.ndarray, uv1: np.ndarray,
                   uv2: np.ndarray, start: np.ndarray, height_floor: float) -> NoiseEstimate:
    """Robust moment estimates of the two sigmas at fixed poses. Pixels: a tie point
    triangulated from its pixels alone leaves one degree of freedom of reprojection residual, so
    ``sigma^2 = median(residual^2) / median(chi2_1)``. Heights: the triangulated height minus the
    DEM has the variance ``g^T C g + sigma_h^2`` (``g = (-dh/dX, -dh/dY, 1)``, ``C`` the
    triangulation's covariance at that pixel sigma); ``sigma_h`` (at least ``height_floor``) is
    found by bisection so that the normalised squares have the median of ``chi2_1``."""
    pts, sq, normal = triangulate(k, position, rotation, uv1, uv2, start)
    finite = np.isfinite(sq) & np.isfinite(pts).all(axis=1)
    s_pix = max(float(np.sqrt(np.median(sq[finite]) / CHI2_1_MEDIAN)), PIXEL_FLOOR)
    h, hx, hy = dem.sample(pts[:, 0], pts[:, 1], strict=False)
    g = np.stack([-hx, -hy, np.ones_like(hx)], axis=1)
    stereo = s_pix ** 2 * np.einsum("mi,mi->m", g, np.linalg.solve(normal, g[..., None])[..., 0])
    d2 = (pts[:, 2] - h) ** 2
    lo = height_floor ** 2
    if np.median(d2[finite] / (stereo[finite] + lo)) > CHI2_1_MEDIAN:
        hi = max(float(d2[finite].max()), lo)
        for _ in range(60):
            mid = math.sqrt(lo * hi)
            if np.median(d2[finite] / (stereo[finite] + mid)) > CHI2_1_MEDIAN:
                lo = mid
            else:
                hi = mid
    s_h = math.sqrt(lo)
    return NoiseEstimate(s_pix, s_h, np.where(finite, sq / s_pix ** 2, np.inf),
                         np.where(finite, d2 / (stereo + s_h ** 2), np.inf))


def adjust(cfg: TerrainConfig, scene: Scene, position: np.ndarray, angles: np.ndarray) -> Estimate:
    """Refine both exposures' orientation from the measured one; returns a run ``Estimate``
    whose extras hold the kept tie points and their landmarks, the graph's error before and
    after, the final sigmas, each pass's (pixel sigma, height sigma, tie points, error), the
    outliers dropped, the Levenberg-Marquardt iterations and the marginal covariances."""
    import gtsam
    from gtsam.symbol_shorthand import L, X


    origin = np.array([np.round(position[0, 0]), np.round(position[0, 1]), 0.0])
    dem = Dem(scene.dem.heights, scene.dem.x0 - origin[0], scene.dem.y0 - origin[1], scene.dem.dx, scene.dem.dy)
    pos = np.asarray(position, float) - origin
    rot = camera.rotation(angles)
    pair = _Pair(dem, scene.k, pos, rot, np.asarray(angles, float), scene.interval)
    uv1, uv2 = tie_points(scene.images[0], scene.images[1], cfg.features)
    require(len(uv1) >= MIN_TIE_POINTS,
            f"gtsam-ba: only {len(uv1)} tie points survive matching; the pair is too weak")
    values = gtsam.Values()
    for i in range(2):
        values.insert(X(i), gtsam.Pose3(gtsam.Rot3(rot[i]), gtsam.Point3(*pos[i])))
    start = camera.ground_points(dem, scene.k, pos[0], rot[0], uv1[:, 0], uv1[:, 1], what="the tie points")
    for j in range(len(uv1)):
        values.insert(L(j), gtsam.Point3(*start[j]))
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(100)
    params.setRelativeErrorTol(RELATIVE_TOLERANCE)
    keep = np.ones(len(uv1), bool)
    sigmas = np.array([PIXEL_SIGMA, max(LOOSE_HEIGHT, cfg.dem_sigma)])
    graph = _graph(cfg, pair, uv1, uv2, keep, *sigmas)
    error_before = graph.error(values)
    iterations, history = 0, []
    if sigmas[1] > cfg.dem_sigma:  # graduated: into the basin loosely, then the DEM at its stated accuracy
        opt = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        values = opt.optimize()
        iterations += opt.iterations()
        history.append((float(sigmas[0]), float(sigmas[1]), int(keep.sum()), float(graph.error(values))))
        sigmas = np.array([PIXEL_SIGMA, cfg.dem_sigma])
        graph = _graph(cfg, pair, uv1, uv2, keep, *sigmas)
    for _ in range(PASSES):
        opt = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        values = opt.optimize()
        iterations += opt.iterations()
        history.append((float(sigmas[0]), float(sigmas[1]), int(keep.sum()), float(graph.error(values))))
        idx = np.flatnonzero(keep)
        noise = estimate_noise(scene.k, dem, np.array([values.atPose3(X(i)).translation() for i in range(2)]),
                               np.array([values.atPose3(X(i)).rotation().matrix() for i in range(2)]),
                               uv1[idx], uv2[idx], np.array([values.atPoint3(L(j)) for j in idx]), cfg.dem_sigma)
        drop = idx[noise.outliers(OUTLIER)]
        if len(idx) - len(drop) < MIN_TIE_POINTS:
            drop = drop[:0]
        new = np.array([noise.pixel, noise.height])
        settled = len(drop) == 0 and bool(np.all(np.abs(new / sigmas - 1.0) < TOLERANCE))
        sigmas = new
        for j in drop:
            keep[j] = False
            values.erase(L(j))
        graph = _graph(cfg, pair, uv1, uv2, keep, *sigmas)
        if settled:
            break
    opt = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    result = opt.optimize()
    iterations += opt.iterations()
    out_pos = np.array([result.atPose3(X(i)).translation() for i in range(2)]) + origin
    out_rot = np.array([result.atPose3(X(i)).rotation().matrix() for i in range(2)])
    idx = np.flatnonzero(keep)
    extras: dict = {"tie_points": (uv1[idx], uv2[idx]), "error_before": error_before,
                    "error_after": graph.error(result), "sigmas": (float(sigmas[0]), float(sigmas[1])),
                    "passes": history, "outliers": int((~keep).sum()), "iterations": iterations,
                    "landmarks": np.array([result.atPoint3(L(j)) for j in idx]) + origin}
    position_cov = pose_cov = None
    try:
        marg = gtsam.Marginals(graph, result)
        extras["covariance"] = np.stack([marg.marginalCovariance(X(i)) for i in range(2)])
        pose_cov = tangent_to_pose(out_rot[1]) @ extras["covariance"][1] @ tangent_to_pose(out_rot[1]).T
        position_cov = pose_cov[:3, :3]
    except RuntimeError:
        extras["covariance"] = None
    return Estimate(out_pos, camera.angles_from_rotation(out_rot), 0.0, extras, position_cov, pose_cov)


def tangent_to_pose(r_wc: np.ndarray, step: float = 1e-6) -> np.ndarray:
    """``T (6, 6)``: (position, angles) from Pose3's tangent ``(omega, v)`` at ``R_wc`` to first
    order (GTSAM retracts ``R Exp(omega)``, ``t + R v``): position ``R v``; angles the derivative
    of :func:`camera.angles_from_rotation` along ``R Exp(omega)`` (central differences)."""
    import gtsam

    t = np.zeros((6, 6))
    t[:3, 3:] = r_wc
    rot = gtsam.Rot3(r_wc)
    for i in range(3):
        w = np.zeros(3)
        w[i] = step
        a_plus = camera.angles_from_rotation(rot.compose(gtsam.Rot3.Expmap(w)).matrix())
        a_minus = camera.angles_from_rotation(rot.compose(gtsam.Rot3.Expmap(-w)).matrix())
        t[3:, i] = (a_plus - a_minus) / (2.0 * step)
    return t
