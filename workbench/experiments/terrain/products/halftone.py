"""The spatial halftone terrain model: every pixel of an image given ground coordinates by (1)
with an orientation and the DEM; its error against the truth; a textured mesh; an orthophoto.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.experiments.terrain import camera
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.dem import Dem


def ground(dem: Dem, k: Intrinsics, position: np.ndarray, angles: np.ndarray, step: int = 1) -> np.ndarray:
    """Ground coordinates ``(rows, cols, 3)`` of every ``step``-th pixel (the inverse of (1))."""
    u, v = k.pixel_grid(step)
    g = camera.ground_points(dem, k, position, camera.rotation(angles), u, v,
                             what="the image footprint under this orientation")
    rows, cols = len(range(0, k.height, step)), len(range(0, k.width, step))
    return g.reshape(rows, cols, 3)


def ground_error(dem: Dem, k: Intrinsics, truth: tuple[np.ndarray, np.ndarray],
                 estimate: tuple[np.ndarray, np.ndarray], step: int = 1) -> np.ndarray:
    """Per-pixel horizontal ground-coordinate error (m), ``(rows, cols)``: the model built with
    ``estimate`` (position, angles) against the one built with the true orientation."""
    g_true = ground(dem, k, *truth, step=step)
    g_est = ground(dem, k, *estimate, step=step)
    return np.hypot(g_est[..., 0] - g_true[..., 0], g_est[..., 1] - g_true[..., 1])


def rmse(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(err))))


@dataclass
class Mesh:
    vertices: np.ndarray      # (V, 3)
    triangles: np.ndarray     # (T, 3)
    texcoords: np.ndarray     # (V, 2) in [0, 1]


def mesh(points: np.ndarray) -> Mesh:
    """A triangle mesh over a grid of ground points ``(rows, cols, 3)`` with texture coordinates
    (the image's own pixels: the halftone model as a textured surface)."""
    rows, cols = points.shape[:2]
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    tri = np.concatenate([np.stack([a, c, b], 1), np.stack([b, c, d], 1)])
    vv, uu = np.mgrid[0:rows, 0:cols]
    tex = np.stack([(uu.ravel() + 0.5) / cols, (vv.ravel() + 0.5) / rows], axis=1)
    return Mesh(points.reshape(-1, 3), tri.astype(np.uint32), tex)


def dem_mesh(dem: Dem, step: int = 1, bounds: tuple[float, float, float, float] | None = None) -> Mesh:
    """The DEM itself as a mesh (every ``step``-th node, cropped to ``bounds``)."""
    z = dem.heights
    rows, cols = z.shape
    xs = dem.x0 + dem.dx * np.arange(cols)
    ys = dem.y0 + dem.dy * np.arange(rows)
    ci = np.arange(0, cols, step)
    ri = np.arange(0, rows, step)
    if bounds is not None:
        ci = ci[(xs[ci] >= bounds[0]) & (xs[ci] <= bounds[1])]
        ri = ri[(ys[ri] >= bounds[2]) & (ys[ri] <= bounds[3])]
    gx, gy = np.meshgrid(xs[ci], ys[ri])
    pts = np.stack([gx, gy, z[np.ix_(ri, ci)]], axis=-1)
    return mesh(pts)


def orthophoto(dem: Dem, k: Intrinsics, position: np.ndarray, angles: np.ndarray, image: np.ndarray,
               bounds: tuple[float, float, float, float], spacing: float) -> np.ndarray:
    """The image resampled on a north-up ground grid (rows from north) over ``bounds``:
    each cell's DEM point projected by (1) and the image read bilinearly; NaN outside it."""
    x_min, x_max, y_min, y_max = bounds
    xs = np.arange(x_min, x_max, spacing)
    ys = np.arange(y_max, y_min, -spacing)
    gx, gy = np.meshgrid(xs, ys)
    h, _, _ = dem.sample(gx, gy, strict=False)
    uv = camera.project(k, position, camera.rotation(angles), np.stack([gx, gy, h], axis=-1))
    u, v = uv[..., 0], uv[..., 1]
    inside = (u >= 0) & (u <= k.width - 1) & (v >= 0) & (v <= k.height - 1)
    uc, vc = np.clip(u, 0, k.width - 1.000001), np.clip(v, 0, k.height - 1.000001)
    u0, v0 = uc.astype(int), vc.astype(int)
    fu, fv = uc - u0, vc - v0
    img = np.asarray(image, float)
    top = img[v0, u0] * (1 - fu) + img[v0, u0 + 1] * fu
    bot = img[v0 + 1, u0] * (1 - fu) + img[v0 + 1, u0 + 1] * fu
    out = top * (1 - fv) + bot * fv
    return np.where(inside, out, np.nan)
