"""The terrain recording's 3D scene: everyone's colour, the world frame (a local origin for real
data), the DEM textured with both images, the frusta and the baseline's tie points and rays
(entities under ``world/``: :mod:`.record`)."""

from __future__ import annotations

import numpy as np
import rerun as rr

from workbench.experiments.terrain import camera
from workbench.experiments.terrain.estimators import TABLE
from workbench.experiments.terrain.products import halftone
from workbench.experiments.terrain.run import RunResult
from workbench.experiments.terrain.scenario import SUN, Scene
from workbench.recording import draw

TRUTH = (240, 240, 240)
COLOUR_NAMES = {"truth": draw.colour_name(TRUTH), **{n: draw.colour_name(e.color) for n, e in TABLE.items()}}
"""The truth's and the built-ins' colours in words (:func:`draw.colour_name` of their own colours)."""
MAX_RAYS = 30                       # tie points whose rays are drawn (all tie points are drawn)


def color(first: RunResult, name: str) -> tuple[int, int, int]:
    """The truth's or an estimator's colour (frusta, markers): its row of the estimator table."""
    if name == "truth":
        return TRUTH
    est = first.estimators.get(name) or TABLE.get(name)
    return est.color if est is not None else (200, 200, 200)


def placement(first: RunResult) -> Scene:
    """The scene as the recording places it: at its true orientation, or, a log without one, at
    the navigation's measured orientation (the frames, the footprints the DEM is cut to)."""
    from dataclasses import replace

    from workbench.experiments.terrain.metrics import truth_known

    sc = first.scene
    if truth_known(sc):
        return sc
    return replace(sc, position=first.measured.position, angles=first.measured.angles)


def local_origin(sc: Scene) -> np.ndarray:
    """Subtracted from every world position: zero for scenes near the origin (synthetic), else
    the cameras' mean position rounded to a kilometre (height kept)."""
    centre = sc.position[:, :2].mean(axis=0)
    if np.max(np.abs(centre)) < 1e4:
        return np.zeros(3)
    return np.array([*np.round(centre, -3), 0.0])


def footprint_bounds(sc: Scene) -> tuple[float, float, float, float]:
    """(x_min, x_max, y_min, y_max): both true footprints with a 15 % margin."""
    k = sc.k
    g = [halftone.ground(sc.dem, k, sc.position[i], sc.angles[i], step=max(1, k.width // 50)) for i in range(2)]
    both = np.concatenate([x.reshape(-1, 3) for x in g])
    pad = 0.15 * max(np.ptp(both[:, 0]), np.ptp(both[:, 1]))
    x0, x1, y0, y1 = sc.dem.extent
    return (max(x0, both[:, 0].min() - pad), min(x1, both[:, 0].max() + pad),
            max(y0, both[:, 1].min() - pad), min(y1, both[:, 1].max() + pad))


def ground_sample_distance(sc: Scene) -> float:
    """Image pixels on the ground (m), at the mean terrain height."""
    return float((sc.position[:, 2].mean() - sc.dem.mean_height) / max(sc.k.fx, sc.k.fy))


def dem_texture(sc: Scene, bounds: tuple[float, float, float, float], spacing: float) -> np.ndarray:
    """A north-up RGB texture over ``bounds``, pixel centres at ``x_min + i spacing`` and
    ``y_max - j spacing`` (the orthophoto grid): image I (else image II) resampled with the
    true orientation, and outside both a warm hillshade of the DEM (no image there)."""
    layers = [halftone.orthophoto(sc.dem, sc.k, sc.position[i], sc.angles[i], sc.images[i], bounds, spacing)
              for i in range(2)]
    x_min, x_max, y_min, y_max = bounds
    gx, gy = np.meshgrid(np.arange(x_min, x_max, spacing), np.arange(y_max, y_min, -spacing))
    _, hx, hy = sc.dem.sample(gx, gy, strict=False)
    n = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
    shade = np.clip((n / np.linalg.norm(n, axis=-1, keepdims=True)) @ SUN, 0.0, 1.0)
    out = (0.25 + 0.6 * shade)[..., None] * np.array([205.0, 180.0, 140.0])
    for layer in layers[::-1]:
        seen = np.isfinite(layer)
        out[seen] = 255.0 * np.clip(layer[seen], 0.0, 1.0)[:, None]
    return out.round().astype(np.uint8)


def record_dem(rec: rr.RecordingStream, sc: Scene, origin: np.ndarray) -> tuple[float, float, float, float]:
    """The DEM mesh around both footprints, textured (:func:`dem_texture`); returns its bounds."""
    bounds = footprint_bounds(sc)
    step = max(1, int(np.ceil((bounds[1] - bounds[0]) / abs(sc.dem.dx) / 150)))
    dm = halftone.dem_mesh(sc.dem, step, bounds)
    span = max(bounds[1] - bounds[0], bounds[3] - bounds[2])
    spacing = max(span / 1024.0, ground_sample_distance(sc) / 2.0)
    tex = dem_texture(sc, bounds, spacing)
    rows, cols = tex.shape[:2]
    uv = np.stack([(dm.vertices[:, 0] - bounds[0] + 0.5 * spacing) / (cols * spacing),
                   (bounds[3] - dm.vertices[:, 1] + 0.5 * spacing) / (rows * spacing)], axis=1)
    draw.textured_mesh(rec, "/world/dem", dm.vertices - origin, dm.triangles, uv, tex)
    return bounds


def record_cameras(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray, placed: Scene | None = None
                   ) -> None:
    """Both exposures' frusta for the truth (with the images; a log without it: at ``placed``, the
    measured orientation) and every estimate, in their colours."""
    sc = placed if placed is not None else first.scene
    k = sc.k
    plane = 0.25 * (sc.position[0, 2] - sc.dem.mean_height)
    for i, ex in enumerate(("I", "II")):
        draw.frustum(rec, f"/world/cameras/truth/{ex}", sc.position[i] - origin, camera.rotation(sc.angles[i]),
                     (k.fx, k.fy), (k.cx, k.cy), (k.width, k.height), color(first, "truth"), 3.0, plane,
                     draw.gray8(sc.images[i]))
        for name, e in first.estimates.items():
            draw.frustum(rec, f"/world/cameras/{name}/{ex}", e.position[i] - origin, camera.rotation(e.angles[i]),
                         (k.fx, k.fy), (k.cx, k.cy), (k.width, k.height), color(first, name), 1.5, plane)


def record_baseline(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """The BA's landmarks, rays from its two cameras to a subset of them, and the tie points on
    the images (pixel centres moved to Rerun's half-integers)."""
    ba = first.estimates.get("gtsam-ba")
    if ba is None or "landmarks" not in ba.extras:
        return
    lm = np.asarray(ba.extras["landmarks"], float) - origin
    rgb = color(first, "gtsam-ba")
    rec.log("/world/ba/tie_points", rr.Points3D(lm, radii=[draw.ui_points(3.0)], colors=[rgb]), static=True)
    pick = np.unique(np.linspace(0, len(lm) - 1, min(len(lm), MAX_RAYS)).round().astype(int))
    strips = [np.stack([ba.position[i] - origin, lm[j]]) for i in range(2) for j in pick]
    rec.log("/world/ba/rays", rr.LineStrips3D(strips, radii=[draw.ui_points(0.5)], colors=[(125, 95, 165)]),
            static=True)
    uv = ba.extras.get("tie_points")
    if uv is not None:
        for ex, pts in zip(("I", "II"), uv, strict=True):
            rec.log(f"/world/cameras/truth/{ex}/tie_points",
                    rr.Points2D(np.asarray(pts, float) + 0.5, radii=[draw.ui_points(2.5)], colors=[rgb]), static=True)
