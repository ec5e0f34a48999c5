"""The terrain recording's ground products of image II: each estimator's halftone model (image II
draped on the ground coordinates its orientation gives), its per-pixel ground error map with a
colour bar, and the orthophoto with the best orientation (entities ``world/halftone/<estimator>``,
``errors/<estimator>``, ``orthophoto``: :mod:`.record`)."""

from __future__ import annotations

import numpy as np
import rerun as rr

from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.products import halftone
from workbench.experiments.terrain.recording.scene import ground_sample_distance
from workbench.experiments.terrain.run import RunResult
from workbench.experiments.terrain.scenario import Scene
from workbench.recording import draw

ERROR_COLORMAP = "Viridis"
MAX_PIXELS_SIDE = 1024              # textures and error maps thinned to this (the 2 Mpx frames would be 8 MB each)


def _rgb(image: np.ndarray) -> np.ndarray:
    return np.repeat(draw.gray8(image)[..., None], 3, axis=-1)


def _stride(image: np.ndarray) -> int:
    """Every how-many-th pixel keeps an image at most ``MAX_PIXELS_SIDE`` on its longer side."""
    return draw.stride(image, MAX_PIXELS_SIDE)


def halftone_texcoords(k: Intrinsics, step: int) -> np.ndarray:
    """Texture coordinates of :func:`halftone.ground`'s grid in the full-resolution image."""
    vv, uu = np.mgrid[0:k.height:step, 0:k.width:step]
    return np.stack([(uu.ravel() + 0.5) / k.width, (vv.ravel() + 0.5) / k.height], axis=1)


def record_halftones(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """Image II draped on the ground coordinates each estimator's orientation gives it."""
    sc = first.scene
    k = sc.k
    step = max(1, min(k.width, k.height) // 100)
    thin = _stride(sc.images[1])
    tex, uv = _rgb(sc.images[1][::thin, ::thin]), halftone_texcoords(k, step)
    for name, e in first.estimates.items():
        mh = halftone.mesh(halftone.ground(sc.dem, k, e.position[1], e.angles[1], step=step))
        draw.textured_mesh(rec, f"/world/halftone/{name}", mh.vertices - origin, mh.triangles, uv, tex)


def record_error_map(rec: rr.RecordingStream, name: str, err: np.ndarray) -> None:
    """One ground error map (metres, hovering reads the error) with its colour bar, ticks and
    title line, thinned to ``MAX_PIXELS_SIDE`` (:func:`draw.error_image`)."""
    draw.error_image(rec, f"/errors/{name}", err, name, "m", ERROR_COLORMAP, MAX_PIXELS_SIDE)


def record_orthophoto(rec: rr.RecordingStream, sc: Scene, best: Estimate, bounds: tuple[float, float, float, float]
                      ) -> None:
    """Image II on a north-up ground grid at its own pixel size, transparent outside it."""
    span = max(bounds[1] - bounds[0], bounds[3] - bounds[2])
    gsd = max(ground_sample_distance(sc), span / 1500.0)
    ortho = halftone.orthophoto(sc.dem, sc.k, best.position[1], best.angles[1], sc.images[1], bounds, gsd)
    rgba = np.concatenate([_rgb(np.nan_to_num(ortho, nan=0.0)),
                           np.where(np.isfinite(ortho), 255, 0).astype(np.uint8)[..., None]], axis=-1)
    rec.log("/orthophoto", rr.Image(rgba, color_model="RGBA"), static=True)
