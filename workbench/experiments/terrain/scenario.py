"""A stereo scene: the DEM, the true exterior orientation of both exposures, the camera, and
the two images. The synthetic one ray-casts a textured, shaded DEM through the true
orientation (spec: "two exposures rendered by ray casting the textured DEM").
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.experiments.terrain import camera
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.dem import Dem, _band_noise, synthetic
from workbench.experiments.terrain.estimate import Estimate

SUN = np.array([-0.5, 0.5, 0.7071])  # from the north-west, 45 deg up


@dataclass
class Scene:
    """Exposure 0 is the paper's image I, exposure 1 its image II."""

    label: str
    dem: Dem
    k: Intrinsics
    position: np.ndarray          # (2, 3) true projection centres
    angles: np.ndarray            # (2, 3) true (psi, theta, gamma)
    images: np.ndarray            # (2, H, W) irradiance in [0, 1]
    interval: float               # seconds between the exposures
    albedo: Dem | None = None     # the synthetic texture (None for real frames)
    extras: dict = field(default_factory=dict)

    @property
    def rotations(self) -> np.ndarray:
        return camera.rotation(self.angles)


def intrinsics(cfg: TerrainConfig) -> Intrinsics:
    """Pixel focal lengths from the frame size: the footprint is fixed, the pixels scale with
    ``--size`` (so 400 x 500 has 4 x 2.4 m pixels, like the paper's non-square 4 x 2 m)."""
    w, h = cfg.image_size
    fx = cfg.focal_mm * w / cfg.sensor_mm[0]
    fy = cfg.focal_mm * h / cfg.sensor_mm[1]
    return Intrinsics(fx, fy, (w - 1) / 2.0, (h - 1) / 2.0, w, h)


def texture(rng: np.random.Generator, dem: Dem, scale: float, spacing: float) -> Dem:
    """Albedo in [0.05, 0.95] at ``spacing``: band-limited noise at 4, 1 and 0.3 times ``scale``
    plus field-like patches with sharp edges (thresholded noise at 6 times ``scale``)."""
    x_min, x_max, y_min, y_max = dem.extent
    cols = int(np.ceil((x_max - x_min) / spacing)) + 1
    rows = int(np.ceil((y_max - y_min) / spacing)) + 1
    shape = (rows, cols)
    a = (0.6 * _band_noise(rng, shape, spacing, 4 * scale) + 1.0 * _band_noise(rng, shape, spacing, scale)
         + 0.35 * _band_noise(rng, shape, spacing, 0.3 * scale)
         + 0.9 * np.sign(_band_noise(rng, shape, spacing, 6 * scale)))
    a = 0.05 + 0.9 / (1.0 + np.exp(-0.9 * a))
    return Dem(a, x_min, y_min, spacing, spacing)


def render(dem: Dem, albedo: Dem, k: Intrinsics, position: np.ndarray, angles: np.ndarray,
           supersample: int, rng: np.random.Generator | None, noise: float) -> np.ndarray:
    """One exposure: every pixel's ``supersample^2`` sub-rays cast onto the DEM, albedo times
    Lambertian shading, averaged; then Gaussian noise of ``noise`` standard deviation."""
    s = supersample
    offs = (np.arange(s) + 0.5) / s - 0.5
    u, v = k.pixel_grid()
    acc = np.zeros(u.size)
    r_wc = camera.rotation(angles)
    for du in offs:
        for dv in offs:
            g = camera.ground_points(dem, k, position, r_wc, u + du, v + dv)
            _, hx, hy = dem.sample(g[:, 0], g[:, 1], strict=False)
            n = np.stack([-hx, -hy, np.ones_like(hx)], axis=1)
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            shade = 0.35 + 0.65 * np.clip(n @ SUN, 0.0, None)
            alb, _, _ = albedo.sample(g[:, 0], g[:, 1], strict=False)
            acc += alb * shade
    img = (acc / (s * s)).reshape(k.height, k.width)
    if rng is not None and noise > 0:
        img = img + noise * rng.standard_normal(img.shape)
    return img


def synthetic_scene(cfg: TerrainConfig, rng: np.random.Generator) -> Scene:
    """The synthetic pair: flight along +X at ``height`` over the mean terrain, small true
    attitudes (up to 0.02 rad), the DEM reaching well past both footprints and the errors."""
    k = intrinsics(cfg)
    base = 200.0
    foot_x = cfg.height * cfg.sensor_mm[0] / cfg.focal_mm
    foot_y = cfg.height * cfg.sensor_mm[1] / cfg.focal_mm
    b = cfg.baseline
    margin = 3.0 * cfg.max_linear + 0.3 * foot_x + 3.0 * cfg.max_angular * cfg.height + 3 * cfg.relief
    extent = (-foot_x / 2 - margin, b + foot_x / 2 + margin, -foot_y / 2 - margin, foot_y / 2 + margin)
    dem = synthetic(rng, extent, cfg.dem_spacing, cfg.relief, base)
    gsd = min(foot_x / k.width, foot_y / k.height)
    albedo = texture(rng, dem, cfg.texture_scale, max(1.0, gsd / 2.0))
    position = np.array([[0.0, 0.0, base + cfg.height], [b, 0.0, base + cfg.height]])
    angles = rng.uniform(-0.02, 0.02, size=(2, 3))
    images = np.stack([render(dem, albedo, k, position[i], angles[i], cfg.supersample, rng, cfg.image_noise)
                       for i in range(2)])
    label = f"synthetic {k.width}x{k.height}, {foot_x / k.width:.1f} x {foot_y / k.height:.1f} m pixels"
    return Scene(label, dem, k, position, angles, images, cfg.interval, albedo)


@dataclass
class TerrainData:
    """One run's dataset: the dataset every terrain estimator reads.

    ``scene``: the stereo pair (``images (2, H, W)`` irradiance in [0, 1], intrinsics ``k``,
    the ``dem``, the exposures' ``interval`` s; ``scene.position`` / ``scene.angles`` are the
    true orientation, for evaluation). ``measured``: the navigation system's orientation of
    both exposures, the estimators' start. ``state``: the true navigation error state (for
    evaluation), in the error mode ``mode`` (:data:`navigation.STATE`). ``hypothesis_rng()``:
    the run's generator where the scene and the errors left it (the sampled hypotheses draw
    from it).
    """

    scene: Scene
    measured: Estimate
    state: np.ndarray
    mode: str
    rng_state: dict

    @property
    def label(self) -> str:
        return self.scene.label

    def hypothesis_rng(self) -> np.random.Generator:
        rng = np.random.default_rng()
        rng.bit_generator.state = self.rng_state
        return rng
