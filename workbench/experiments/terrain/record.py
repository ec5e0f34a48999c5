"""The terrain recording: the scene in 3D and the search over its own timeline.

Entity layout (run 0 in full):

* ``world/dem`` (the DEM mesh, coloured by image I where it sees it), ``world/cameras/<who>/<I|II>``
  for ``truth`` (with the images), ``navigation`` and every estimator (frusta in its colour);
* ``world/search/hypotheses`` (image II's position under each hypothesis, coloured by the
  functional, one chunk per step of the ``search`` timeline), ``world/search/winner``;
* ``world/ba/{tie_points,rays}`` (the baseline's landmarks and the rays from both cameras);
* ``world/halftone/<estimator>`` (image II draped on its ground coordinates: the halftone
  model, a textured mesh); ``errors/<estimator>`` (its per-pixel ground error map, an image);
  ``orthophoto`` (image II resampled on the ground with the refined orientation);
* ``functional`` (I_pq per hypothesis, timeline ``hypothesis``); ``summary`` (the table).
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.experiments.terrain import camera, halftone, navigation
from workbench.experiments.terrain.run import REFINED, SEARCH, RunResult

PALETTE = {"truth": (230, 230, 230), "navigation": (150, 150, 150), SEARCH: (255, 170, 0),
           REFINED: (60, 200, 90), "gtsam-ba": (190, 90, 240)}


def color(name: str) -> tuple[int, int, int]:
    return PALETTE.get(name, (200, 200, 200))


def blueprint(names: list[str]) -> rrb.Blueprint:
    """The 3D scene on the left; images, error maps, the functional and the table on the right."""
    world = rrb.Spatial3DView(origin="/world", name="scene (m, z up)")
    images = rrb.Vertical(
        rrb.Spatial2DView(origin="/world/cameras/truth/I", name="image I"),
        rrb.Spatial2DView(origin="/world/cameras/truth/II", name="image II"),
        name="images")
    errors = rrb.Grid(*[rrb.Spatial2DView(origin=f"/errors/{n}", name=f"ground error, {n}") for n in names],
                      name="ground error maps")
    return rrb.Blueprint(
        rrb.Horizontal(world, rrb.Tabs(
            images, errors, rrb.Spatial2DView(origin="/orthophoto", name="orthophoto"),
            rrb.TimeSeriesView(origin="/functional", name="functional I_pq per hypothesis"),
            rrb.TextDocumentView(origin="/summary", name="results")), column_shares=[3, 2]),
        collapse_panels=True,
    )


def _ramp(values: np.ndarray, top: float) -> np.ndarray:
    """A blue -> yellow -> red colour ramp over ``[0, top]`` as uint8 RGB."""
    x = np.clip(np.nan_to_num(values / max(top, 1e-12)), 0.0, 1.0)[..., None]
    lo, mid, hi = np.array([40, 60, 200]), np.array([250, 220, 60]), np.array([220, 40, 40])
    out = np.where(x < 0.5, lo + (mid - lo) * (2 * x), mid + (hi - mid) * (2 * x - 1))
    return out.astype(np.uint8)


def _gray(image: np.ndarray) -> np.ndarray:
    return (255 * np.clip(image, 0.0, 1.0)).astype(np.uint8)


def _camera(rec: rr.RecordingStream, path: str, k, position: np.ndarray, angles: np.ndarray, rgb,
            image: np.ndarray | None, plane: float) -> None:
    rec.log(path, rr.Transform3D(translation=position, mat3x3=camera.rotation(angles)), static=True)
    rec.log(path, rr.Pinhole(focal_length=[k.fx, k.fy], principal_point=[k.cx, k.cy], width=k.width,
                             height=k.height, image_plane_distance=plane, color=rgb, line_width=2.0), static=True)
    if image is not None:
        rec.log(path, rr.Image(_gray(image)), static=True)


def record(rec: rr.RecordingStream, first: RunResult, table_md: str) -> None:
    """Log run 0: scene, cameras, the search, the baseline's tie points, the halftone models."""
    sc = first.scene
    k = sc.k
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    # the DEM around both footprints, coloured by image I where it sees it
    g1 = halftone.ground(sc.dem, k, sc.position[0], sc.angles[0], step=max(1, k.width // 50))
    g2 = halftone.ground(sc.dem, k, sc.position[1], sc.angles[1], step=max(1, k.width // 50))
    both = np.concatenate([g1.reshape(-1, 3), g2.reshape(-1, 3)])
    pad = 0.15 * np.ptp(both[:, 0])
    bounds = (both[:, 0].min() - pad, both[:, 0].max() + pad, both[:, 1].min() - pad, both[:, 1].max() + pad)
    step = max(1, int(np.ceil((bounds[1] - bounds[0]) / abs(sc.dem.dx) / 150)))
    dm = halftone.dem_mesh(sc.dem, step, bounds)
    uv = camera.project(k, sc.position[0], camera.rotation(sc.angles[0]), dm.vertices)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= k.width - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= k.height - 1)
    shade = np.full(len(uv), 0.35)
    ui = np.clip(uv[:, 0], 0, k.width - 1).astype(int)
    vi = np.clip(uv[:, 1], 0, k.height - 1).astype(int)
    shade[inside] = sc.images[0][vi[inside], ui[inside]]
    rec.log("/world/dem", rr.Mesh3D(vertex_positions=dm.vertices, triangle_indices=dm.triangles,
                                    vertex_colors=np.repeat(_gray(shade)[:, None], 3, axis=1)), static=True)
    plane = 0.25 * (sc.position[0, 2] - sc.dem.mean_height)
    for i, ex in enumerate(("I", "II")):
        _camera(rec, f"/world/cameras/truth/{ex}", k, sc.position[i], sc.angles[i], color("truth"), sc.images[i],
                plane)
        for name, e in first.estimates.items():
            _camera(rec, f"/world/cameras/{name}/{ex}", k, e.position[i], e.angles[i], color(name), None, plane)
    # the search: hypotheses as image II positions, coloured by their functional
    s = first.search
    if s is not None:
        m = navigation.error_map(_mode(s), sc.interval)
        pos_err = np.einsum("pn,cn->cp", m[1, :3], s.centres)
        pts = first.measured.position[1] - pos_err
        f = s.functional
        rank = np.argsort(np.argsort(f)) / max(1, len(f) - 1)
        cols = _ramp(rank, 1.0)
        steps = np.arange(0, len(f), s.chunk)
        counts = np.diff(np.r_[steps, len(f)])
        rec.log("/world/search/hypotheses", rr.Points3D.from_fields(radii=[3.0]), static=True)
        rec.send_columns("/world/search/hypotheses", indexes=[rr.TimeColumn("search", sequence=np.arange(len(steps)))],
                         columns=rr.Points3D.columns(positions=pts, colors=cols).partition(counts))
        rec.log("/world/search/winner", rr.Points3D([pts[s.winner]], radii=[8.0], colors=[color(SEARCH)],
                                                    labels=["winner"]), static=True)
        rec.log("/functional", rr.SeriesLines(colors=[color(SEARCH)], names=["I_pq"]), static=True)
        rec.send_columns("/functional", indexes=[rr.TimeColumn("hypothesis", sequence=np.arange(len(f)))],
                         columns=rr.Scalars.columns(scalars=f - f.min()))
    ba = first.estimates.get("gtsam-ba")
    if ba is not None and "landmarks" in ba.extras:
        lm = ba.extras["landmarks"]
        rec.log("/world/ba/tie_points", rr.Points3D(lm, radii=[4.0], colors=[color("gtsam-ba")]), static=True)
        starts = np.concatenate([np.repeat(ba.position[0][None], len(lm), 0), np.repeat(ba.position[1][None],
                                                                                         len(lm), 0)])
        ends = np.concatenate([lm, lm])
        rec.log("/world/ba/rays", rr.LineStrips3D(np.stack([starts, ends], 1), radii=[0.5],
                                                  colors=[(190, 90, 240, 60)]), static=True)
    # the halftone models and their error maps
    top = max(float(np.max(e)) for e in first.ground_errors.values())
    hstep = max(1, k.width // 100)
    tex = np.repeat(_gray(sc.images[1][::hstep, ::hstep])[..., None], 3, axis=2)
    for name, e in first.estimates.items():
        pts = halftone.ground(sc.dem, k, e.position[1], e.angles[1], step=hstep)
        mh = halftone.mesh(pts)
        rec.log(f"/world/halftone/{name}", rr.Mesh3D(vertex_positions=mh.vertices, triangle_indices=mh.triangles,
                                                     vertex_texcoords=mh.texcoords, albedo_texture=tex), static=True)
        rec.log(f"/errors/{name}", rr.Image(_ramp(first.ground_errors[name], top)), static=True)
    best = first.estimates.get(REFINED) or first.estimates.get("gtsam-ba") or first.estimates["navigation"]
    gsd = (bounds[1] - bounds[0]) / 300.0
    ortho = halftone.orthophoto(sc.dem, k, best.position[1], best.angles[1], sc.images[1], bounds, gsd)
    rec.log("/orthophoto", rr.Image(_gray(np.nan_to_num(ortho, nan=0.0))), static=True)
    rec.log("/summary", rr.TextDocument(table_md, media_type=rr.MediaType.MARKDOWN), static=True)


def _mode(s) -> str:
    return "common" if s.centres.shape[1] == len(navigation.STATE["common"]) else "ii-only"
