"""The terrain experiment's Cramér-Rao bound: how well any estimator could know image II's
exterior orientation from the image pair and the navigation prior
(:mod:`workbench.estimation.bounds`).

The images' Fisher information is that of the search's own measurement model (:mod:`.search`:
image II's irradiance at the nodes of image I, through the DEM), at the true navigation errors:
``sum_nodes H H' / R`` with ``H = grad f_II . d(u, v)/dX`` (``search.sums`` at the true state).
``R`` is the residual variance the data have there (image II against image I at the true
orientation, over the nodes), not the filter's tuning. The prior is the navigation errors' own
spread (``sigma_fraction`` of each maximum), as a Gaussian. The state is the error mode's
(``common``: both exposures' errors; ``ii-only``: image II's six). The bound is one run's; the
variances are averaged over the runs like the squared errors.

The bundle adjustment reads other data from the same images (SIFT tie points) and is held to
its own graph's bound (:func:`bundle_adjustment`): the tie points' projections and DEM heights
with the sigmas it estimated, the navigation factors of the mode, at the true orientation.

Readings taken: the information is the residuals' own slopes' (central differences of the
measurement model, the bilinear image's slopes: :func:`residual_slopes`), not the model's ``H``
that the filters use (image II's gradient by central differences, interpolated), which gives
1.9-3 times less on a synthetic 100 x 100 pair: the search's posterior reads the actual slopes
(its sandwich's bread) and was below a bound taken from ``H`` (efficiency 0.58 +- 0.12, common
mode, 100 x 100, 4 runs). The nodes' residuals are taken independent; neighbouring pixels' are not quite
(the texture and the rendering blur them), so the information is somewhat overstated and the
bound a little low: still a bound, but a loose one. A uniform error distribution (the default)
has no prior Fisher information of its own; its Gaussian of the same spread stands in.
"""

from __future__ import annotations

import numpy as np

from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.algorithms import search
from workbench.experiments.terrain.config import TerrainConfig


def state_bound(problem: search.Problem, state: np.ndarray, cfg: TerrainConfig) -> tuple[np.ndarray, float]:
    """The bound on the error state ``(n, n)`` and the residual variance R used: the images'
    information ``sum J J' / R`` from the residuals' own slopes (:func:`residual_slopes`) and
    the prior's."""
    x = np.asarray(state, float)
    hh, _, rr = search.sums(problem, x[None])
    r = float(rr[0] / len(problem.nodes))
    prior = navigation.prior_covariance(cfg)
    model = np.linalg.inv(hh[0] / r + np.linalg.inv(prior))
    j = residual_slopes(problem, x, 0.5 * np.sqrt(np.diag(model)))
    info = j @ j.T / r + np.linalg.inv(prior)
    P = np.linalg.inv(info)
    return 0.5 * (P + P.T), r


def residual_slopes(problem: search.Problem, state: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """``J (n, N)``: every node's residual's derivative along each state component, by central
    differences over ``steps`` of the measurement model itself (image II read bilinearly where
    image I's node lands), not the model's ``H`` (image II's central-difference gradient,
    interpolated: smoother, and 1.9-3 times less information on a 100 x 100 synthetic pair). An
    estimator that reads the images' own slopes (the search's posterior, whose sandwich uses
    them) would otherwise beat a bound taken from ``H``."""
    n = len(state)
    centres = np.concatenate([state + np.diag(steps), state - np.diag(steps)])
    r0, _ = search.rows(problem, centres)
    return -(r0[:n] - r0[n:]) / (2.0 * np.asarray(steps, float)[:, None])


def variances(P: np.ndarray, cfg: TerrainConfig, interval: float) -> dict[str, float]:
    """Image II's bounds: ``position`` (the 3D error's ``var x + var y + var h``, m^2), ``x``, ``y``,
    ``h`` and ``attitude`` (the three angles', rad^2)."""
    m = navigation.error_map(cfg.mode, interval)[1]    # image II's pose errors from the state
    C = m @ P @ m.T                                     # (6, 6): dX, dY, dH, dpsi, dtheta, dgamma
    return {"position": float(np.trace(C[:3, :3])), "x": float(C[0, 0]), "y": float(C[1, 1]),
            "h": float(C[2, 2]), "attitude": float(np.trace(C[3:, 3:]))}


def bundle_adjustment(cfg: TerrainConfig, scene, extras: dict) -> dict[str, float] | None:
    """The bound of the bundle adjustment's own data: its graph (:func:`ba._graph`: the pose
    factors, each kept tie point's two projections with the pixel sigma and its DEM height
    factor with the height sigma the adjustment estimated) built at the true orientation, the
    tie points' ground points where image I's true rays meet the DEM; GTSAM's marginals there.
    Image II's variances as :func:`variances` gives them, or None without tie points."""
    import gtsam
    from gtsam.symbol_shorthand import L, X

    from workbench.experiments.terrain import camera
    from workbench.experiments.terrain.algorithms import ba
    from workbench.experiments.terrain.dem import Dem

    if not extras or "tie_points" not in extras or extras.get("sigmas") is None:
        return None
    uv1, uv2 = extras["tie_points"]
    origin = np.array([np.round(scene.position[0, 0]), np.round(scene.position[0, 1]), 0.0])
    dem = Dem(scene.dem.heights, scene.dem.x0 - origin[0], scene.dem.y0 - origin[1], scene.dem.dx, scene.dem.dy)
    pos = scene.position - origin
    rot = camera.rotation(scene.angles)
    pair = ba._Pair(dem, scene.k, pos, rot, np.asarray(scene.angles, float), scene.interval)
    graph = ba._graph(cfg, pair, uv1, uv2, np.ones(len(uv1), bool), *extras["sigmas"])
    values = gtsam.Values()
    for i in range(2):
        values.insert(X(i), gtsam.Pose3(gtsam.Rot3(rot[i]), gtsam.Point3(*pos[i])))
    points = camera.ground_points(dem, scene.k, pos[0], rot[0], uv1[:, 0], uv1[:, 1], what="the tie points")
    for j, p in enumerate(points):
        values.insert(L(j), gtsam.Point3(*p))
    try:
        C = gtsam.Marginals(graph, values).marginalCovariance(X(1))   # Pose3 tangent: rotation, translation
    except RuntimeError:
        return None
    r2 = rot[1]
    position = r2 @ C[3:, 3:] @ r2.T
    # the attitude's Euler angles against the body-frame rotation vector, by central differences
    eps = 1e-6
    J = np.stack([(camera.angles_from_rotation(r2 @ _exp(eps * e)) - camera.angles_from_rotation(r2 @ _exp(-eps * e)))
                  / (2 * eps) for e in np.eye(3)], axis=1)
    attitude = J @ C[:3, :3] @ J.T
    return {"position": float(np.trace(position)), "x": float(position[0, 0]), "y": float(position[1, 1]),
            "h": float(position[2, 2]), "attitude": float(np.trace(attitude))}


def _exp(w: np.ndarray) -> np.ndarray:
    """The rotation matrix of a small rotation vector (Rodrigues)."""
    a = float(np.linalg.norm(w))
    K = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(a) / a * K + (1 - np.cos(a)) / a**2 * K @ K
