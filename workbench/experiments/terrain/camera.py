"""The camera model (1): collinearity equations, their inverse on the DEM, and derivatives.

Frames: the world is (X east, Y north, H up), metres. The camera frame is x right, y down,
z along the optical axis (OpenCV's and GTSAM's ``Pose3`` convention). Exterior orientation
is the projection centre ``C = (X^S, Y^S, H^S)`` and the attitude ``(psi, theta, gamma)``
(yaw about H, pitch about Y, roll about X): ``R_wc = Rz(psi) Ry(theta) Rx(gamma) R_nadir``,
where ``R_nadir`` points the optical axis down with image x along +X and image y along -Y,
so a level camera at zero attitude sees a north-up image. Pixel ``(u, v)`` = (column, row),
pixel centres at integers.

Equation (1), forward: ``p = R_wc^T (G - C)``, ``u = cx + fx p_x / p_z``,
``v = cy + fy p_y / p_z``. Inverse: the ray ``C + t R_wc (ray)`` met with ``H = h(X, Y)``
by Newton iteration on the DEM (the paper's "iterate on the DEM").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.errors import require

R_NADIR = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole interior orientation in pixels; ``width`` x ``height`` pixels."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def rays(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Camera-frame ray directions ``((u-cx)/fx, (v-cy)/fy, 1)`` for pixel coordinates."""
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        return np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones_like(u)], axis=-1)

    def pixel_grid(self, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Pixel centres ``(u, v)`` of every ``step``-th column and row, flattened row-major."""
        vv, uu = np.mgrid[0:self.height:step, 0:self.width:step]
        return uu.ravel().astype(float), vv.ravel().astype(float)


def _rz(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    m = np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)
    d = np.stack([np.stack([-s, -c, z], -1), np.stack([c, -s, z], -1), np.stack([z, z, z], -1)], -2)
    return m, d


def _ry(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    m = np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)
    d = np.stack([np.stack([-s, z, c], -1), np.stack([z, z, z], -1), np.stack([-c, z, -s], -1)], -2)
    return m, d


def _rx(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    m = np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)
    d = np.stack([np.stack([z, z, z], -1), np.stack([z, -s, -c], -1), np.stack([z, c, -s], -1)], -2)
    return m, d


def rotation(angles: np.ndarray) -> np.ndarray:
    """``R_wc`` for attitudes ``(..., 3)`` = (psi, theta, gamma); shape ``(..., 3, 3)``."""
    return rotation_and_derivatives(angles)[0]


def rotation_and_derivatives(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``R_wc (..., 3, 3)`` and its derivatives by psi, theta, gamma ``(..., 3, 3, 3)`` (first
    trailing axis: which angle)."""
    a = np.asarray(angles, float)
    z, dz = _rz(a[..., 0])
    y, dy = _ry(a[..., 1])
    x, dx = _rx(a[..., 2])
    r = z @ y @ x @ R_NADIR
    d = np.stack([dz @ y @ x @ R_NADIR, z @ dy @ x @ R_NADIR, z @ y @ dx @ R_NADIR], axis=-3)
    return r, d


def axes(angles: np.ndarray) -> np.ndarray:
    """World-frame rotation axes of psi, theta, gamma ``(..., 3, 3)`` (first trailing axis:
    which angle): ``dR_wc/da = [w_a]x R_wc``, so derivatives become cross products."""
    a = np.asarray(angles, float)
    cz, sz, cy, sy = np.cos(a[..., 0]), np.sin(a[..., 0]), np.cos(a[..., 1]), np.sin(a[..., 1])
    zero, one = np.zeros_like(cz), np.ones_like(cz)
    w_psi = np.stack([zero, zero, one], -1)
    w_theta = np.stack([-sz, cz, zero], -1)
    w_gamma = np.stack([cz * cy, sz * cy, -sy], -1)
    return np.stack([w_psi, w_theta, w_gamma], axis=-2)


def angles_from_rotation(r_wc: np.ndarray) -> np.ndarray:
    """The inverse of :func:`rotation`: (psi, theta, gamma) of ``R_wc`` (ZYX Euler angles)."""
    m = np.asarray(r_wc, float) @ R_NADIR.T
    psi = np.arctan2(m[..., 1, 0], m[..., 0, 0])
    theta = -np.arcsin(np.clip(m[..., 2, 0], -1.0, 1.0))
    gamma = np.arctan2(m[..., 2, 1], m[..., 2, 2])
    return np.stack([psi, theta, gamma], axis=-1)


def project(k: Intrinsics, position: np.ndarray, r_wc: np.ndarray, ground: np.ndarray) -> np.ndarray:
    """Equation (1), forward: pixel ``(u, v)`` of ground points ``(..., 3)``."""
    p = np.einsum("...ji,...j->...i", r_wc, ground - position)
    return np.stack([k.cx + k.fx * p[..., 0] / p[..., 2], k.cy + k.fy * p[..., 1] / p[..., 2]], axis=-1)


def intersect(dem, origin: np.ndarray, direction: np.ndarray, iterations: int = 8,
              what: str = "the image footprint") -> np.ndarray:
    """Equation (1), inverse: ray parameters ``t`` with ``origin + t direction`` on the DEM.

    Newton's method on ``f(t) = o_z + t d_z - h(o_xy + t d_xy)``, started on the DEM's mean
    height; rays where it has not converged to a centimetre (steep relief, oblique rays) are
    bisected between the DEM's highest and lowest heights. Rays leaving the DEM, or meeting it
    behind the camera (looking up), raise a one-line error naming ``what``.
    """
    o = np.asarray(origin, float)
    d = np.asarray(direction, float)
    t = (float(dem.mean_height) - o[..., 2]) / d[..., 2]

    def f_and_slope(tt):
        xy = o[..., :2] + tt[..., None] * d[..., :2]
        h, hx, hy = dem.sample(xy[..., 0], xy[..., 1], strict=False)
        return o[..., 2] + tt * d[..., 2] - h, d[..., 2] - hx * d[..., 0] - hy * d[..., 1]

    for _ in range(iterations):
        f, fp = f_and_slope(t)
        t = t - f / fp
    f, _ = f_and_slope(t)
    bad = ~(np.abs(f) < 0.01)
    if bad.any():
        top, bottom = float(np.nanmax(dem.heights)), float(np.nanmin(dem.heights))
        ob, db = o[bad] if o.shape == d.shape else np.broadcast_to(o, d.shape)[bad], d[bad]
        lo = (top + 1.0 - ob[:, 2]) / db[:, 2]        # above every hill: f > 0
        hi = (bottom - 1.0 - ob[:, 2]) / db[:, 2]     # below every valley: f < 0
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            xy = ob[:, :2] + mid[:, None] * db[:, :2]
            h, _, _ = dem.sample(xy[:, 0], xy[:, 1], strict=False)
            above = ob[:, 2] + mid * db[:, 2] - h > 0
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        t = np.array(t, float)
        t[bad] = 0.5 * (lo + hi)
    require(bool(np.all(t > 0.0)), f"{what}: rays meet the ground behind the camera, not in front of it "
                                   "(an orientation looking at the sky, or a camera below the terrain)")
    xy = o[..., :2] + t[..., None] * d[..., :2]
    require(bool(dem.covers(xy[..., 0], xy[..., 1]).all()), f"the DEM does not cover {what}")
    return t


def ground_points(dem, k: Intrinsics, position: np.ndarray, r_wc: np.ndarray, u: np.ndarray,
                  v: np.ndarray, what: str = "the image footprint") -> np.ndarray:
    """Ground coordinates ``(N, 3)`` of pixels ``(u, v)`` seen from one pose (the inverse of (1))."""
    d = k.rays(u, v) @ np.asarray(r_wc).T
    o = np.broadcast_to(np.asarray(position, float), d.shape)
    t = intersect(dem, o, d, what=what)
    return o + t[..., None] * d
