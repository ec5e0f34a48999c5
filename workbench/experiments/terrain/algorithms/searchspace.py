"""What the recurrent search runs over (:mod:`.search`): the problem (the node points of image I
that land inside image II under the measured orientation, with a margin for the largest error;
image II's gradient stack read bilinearly; the DEM) and the hypotheses D_pq about the mean of the
navigation errors, the cells of the confidence cube or samples drawn in it."""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass

import numpy as np

from workbench.errors import require
from workbench.experiments.terrain import camera, navigation
from workbench.experiments.terrain.algorithms import radiometry
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.dem import Dem


@dataclass
class Problem:
    """Everything the bank needs: the measured orientation, the images, the nodes, the model.

    Coordinates are relative to ``origin`` (small numbers on a real map grid)."""

    mode: str
    k: Intrinsics
    dem: Dem                  # shifted to the local origin
    origin: np.ndarray        # (3,) subtracted from world coordinates
    position: np.ndarray      # (2, 3) measured, local
    angles: np.ndarray        # (2, 3) measured
    m: np.ndarray             # (2, 6, n) pose errors = m @ state
    nodes: np.ndarray         # (N, 2) node pixels (u, v) in image I
    z: np.ndarray             # (N,) image I at the nodes
    t0: np.ndarray            # (N,) ray parameters of the nodes under the measured orientation
    h0: np.ndarray            # (N,) their ground heights (Newton's start under a hypothesis)
    image2: np.ndarray        # (H, W, 3): image II, d/du, d/dv
    dem_stack: np.ndarray     # (rows, cols, 3): h, dh/dcol, dh/drow
    r: float                  # measurement noise variance R
    radiometry: tuple[float, float] = (1.0, 0.0)  # image II's gain and offset onto image I's scale

    @property
    def n(self) -> int:
        return self.m.shape[2]

    @functools.cached_property
    def node_table(self) -> np.ndarray:
        """``(N, 5)`` per node: its camera ray's x and y (z = 1), ``Z``, ``h0``, ``t0`` (the
        compiled kernel's one node input)."""
        ray = self.k.rays(self.nodes[:, 0], self.nodes[:, 1])
        return np.ascontiguousarray(np.column_stack([ray[:, 0], ray[:, 1], self.z, self.h0, self.t0]))


def gradient_stack(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)``: the image and its central-difference derivatives along u and v."""
    gv, gu = np.gradient(np.asarray(image, float))
    return np.ascontiguousarray(np.stack([image, gu, gv], axis=-1), dtype=float)


def bilinear(stack: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The channels of ``stack (rows, cols, ch)`` at column ``x``, row ``y`` (any shape), read
    bilinearly with the edges held; shape ``(*x.shape, ch)``."""
    rows, cols = stack.shape[:2]
    xc = np.clip(x, 0.0, cols - 1.0)
    yc = np.clip(y, 0.0, rows - 1.0)
    x0 = np.minimum(xc.astype(int), cols - 2)
    y0 = np.minimum(yc.astype(int), rows - 2)
    a = (xc - x0)[..., None]
    b = (yc - y0)[..., None]
    top = stack[y0, x0] + a * (stack[y0, x0 + 1] - stack[y0, x0])
    bottom = stack[y0 + 1, x0] + a * (stack[y0 + 1, x0 + 1] - stack[y0 + 1, x0])
    return top + b * (bottom - top)


def make_problem(cfg: TerrainConfig, k: Intrinsics, dem: Dem, position: np.ndarray, angles: np.ndarray,
                 images: np.ndarray, interval: float) -> Problem:
    """Nodes of image I every ``node_step`` pixels that fall inside image II, under the measured
    orientation, with a margin of the largest displacement the errors can cause."""
    m = navigation.error_map(cfg.mode, interval)
    origin = np.array([np.round(position[0, 0]), np.round(position[0, 1]), 0.0])
    local = Dem(dem.heights, dem.x0 - origin[0], dem.y0 - origin[1], dem.dx, dem.dy)
    position = np.asarray(position, float) - origin
    u, v = k.pixel_grid(cfg.node_step)
    r_wc = camera.rotation(angles)
    d = k.rays(u, v) @ r_wc[0].T
    t = camera.intersect(local, np.broadcast_to(position[0], d.shape), d, what="image I's footprint")
    g = position[0] + t[:, None] * d
    uv = camera.project(k, position[1], r_wc[1], g)
    depth = position[1, 2] - local.mean_height
    spread = 3.0 if cfg.distribution == "gaussian" else 1.0
    lin = spread * (cfg.max_linear + cfg.max_velocity * interval) * max(k.fx, k.fy) / depth
    ang = spread * cfg.max_angular * max(k.fx, k.fy)
    margin = min(lin + ang + 2.0, 0.45 * min(k.width, k.height))
    inside = ((uv[:, 0] >= margin) & (uv[:, 0] <= k.width - 1 - margin)
              & (uv[:, 1] >= margin) & (uv[:, 1] <= k.height - 1 - margin))
    require(int(inside.sum()) >= 50,
            "fewer than 50 nodes of image I fall inside image II: the pair does not overlap enough "
            "for these error maxima")
    nodes = np.stack([u[inside], v[inside]], axis=1)
    z = images[0][nodes[:, 1].astype(int), nodes[:, 0].astype(int)]
    image2 = np.asarray(images[1], float)
    if cfg.radiometry == "local":
        image2 = radiometry.flatten(image2)
        z = radiometry.flatten(images[0])[nodes[:, 1].astype(int), nodes[:, 0].astype(int)]
    gain, offset = 1.0, 0.0
    if cfg.radiometry != "none":
        gain, offset = radiometry.match(z, bilinear(image2[..., None], uv[inside, 0], uv[inside, 1])[..., 0])
        image2 = gain * image2 + offset
    hr, hc = np.gradient(local.heights)
    dem_stack = np.ascontiguousarray(np.stack([local.heights, hc, hr], axis=-1), dtype=float)
    return Problem(cfg.mode, k, local, origin, position, np.asarray(angles, float), m, nodes, z, t[inside],
                   g[inside, 2], gradient_stack(image2), dem_stack, cfg.sigma_r ** 2, (gain, offset))


@dataclass
class Hypotheses:
    centres: np.ndarray   # (n_h, n) state-space cell centres m_pq
    prior: np.ndarray     # (n, n) G: the spread of the errors inside a cell
    kind: str


def hypotheses(cfg: TerrainConfig, rng: np.random.Generator) -> Hypotheses:
    """The full grid (``levels_linear^3 x levels_angular^3`` cells of the confidence cube and
    "spherical cube"), or ``samples`` centres drawn uniformly in them (the paper's number of
    functionals in the sample); G is the variance of a uniform error over one cell (for
    samples, a cell of the cube's volume over N). Velocity errors are not searched: their
    hypothesis mean is 0 and G holds their whole spread."""
    names = navigation.STATE[cfg.mode]
    top = navigation.maxima(cfg)
    lin_axes = [i for i, n in enumerate(names) if n in navigation.LINEAR]
    ang_axes = [i for i, n in enumerate(names) if n in navigation.ANGULAR]
    vel_axes = [i for i, n in enumerate(names) if n in navigation.VELOCITY]
    n = len(names)
    if cfg.hypotheses == "grid":
        levels = np.ones(n, int)
        levels[lin_axes] = cfg.levels_linear
        levels[ang_axes] = cfg.levels_angular
        width = 2.0 * top / levels
        axes = [(-top[i] + width[i] * (np.arange(levels[i]) + 0.5)) if i not in vel_axes else np.zeros(1)
                for i in range(n)]
        centres = np.array(list(itertools.product(*axes)))
    else:
        centres = rng.uniform(-top, top, size=(cfg.samples, n))
        width = 2.0 * top / cfg.samples ** (1.0 / 6.0)
        centres[:, vel_axes] = 0.0
    var = width ** 2 / 12.0
    var[vel_axes] = (top[vel_axes] * navigation.sigma_fraction(cfg)) ** 2
    var = np.maximum(var, 1e-12)
    return Hypotheses(centres, np.diag(var), cfg.hypotheses)
