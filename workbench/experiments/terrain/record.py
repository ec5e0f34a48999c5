"""The terrain recording: the scene in 3D and the search over its own timeline.

Everything 3D is in one world frame (X east, Y north, Z up, metres) under ``/world``; for real
data far from the origin a round local origin is subtracted (float32 in the viewer would
otherwise quantise the cameras to decimetres), and the summary says which. Entity layout
(run 0 in full):

* ``world/dem`` (the DEM mesh, textured with both true-orientation orthophotos where the images
  see it and a hillshade elsewhere), ``world/cameras/<who>/<I|II>`` for ``truth`` (with the
  images and the baseline's tie points on them), ``navigation`` and every estimator (frusta in
  its colour);
* ``world/search/hypotheses``: every hypothesis drawn at the image II position it implies,
  its attitude error as a small offset (:class:`Glyph`), coloured by the rank of its
  functional; one row per evaluated chunk on the timelines ``hypothesis`` (the last hypothesis
  of the chunk) and ``search`` (the chunk's step); the views accumulate them up to the cursor.
  ``world/search/winner`` and ``world/search/winner_cell`` (the lowest hypothesis so far and
  its position cell, a row where it changes: the winner at the end), ``world/search/markers``
  (truth and every estimate in the same drawing);
* ``world/ba/{tie_points,rays}`` (the baseline's landmarks and rays from both BA cameras to a
  subset of them);
* ``world/halftone/<estimator>`` (image II draped on its ground coordinates: the halftone
  model, a textured mesh); ``errors/<estimator>`` (its per-pixel ground error map in metres, a
  colour-mapped depth image with its own legend); ``orthophoto`` (image II resampled north-up
  on the ground with the best orientation, transparent outside the image);
* ``functional`` (I_pq - min per hypothesis), ``functional/lowest`` (lowest so far) and
  ``functional/winner`` on the same timelines; ``summary`` (the table and how to read all this).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.errors import WorkbenchError
from workbench.estimation.angles import wrap
from workbench.experiments.terrain import camera, halftone, navigation
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.estimators import ITERATED, POSTERIOR, REFINED, SEARCH, TABLE
from workbench.experiments.terrain.evaluate import RunSummary
from workbench.experiments.terrain.model import PREFERRED
from workbench.experiments.terrain.run import RunResult
from workbench.experiments.terrain.scenario import SUN, Scene
from workbench.recording import draw

TRUTH = (240, 240, 240)
COLOUR_NAMES = {"truth": draw.colour_name(TRUTH), **{n: draw.colour_name(e.color) for n, e in TABLE.items()}}
"""The truth's and the built-ins' colours in words (:func:`draw.colour_name` of their own colours)."""
BACKGROUND = (24, 28, 34)           # the 3D views' background: the palette reads on it in either theme
ERROR_COLORMAP = "Viridis"
TIMELINES = ("hypothesis", "search")
MAX_PIXELS_SIDE = 1024              # textures and error maps thinned to this (the 2 Mpx frames would be 8 MB each)
MAX_RAYS = 30                       # tie points whose rays are drawn (all tie points are drawn)
NICE = (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)  # legend tops, times a power of ten
LABEL = (120, 120, 120)             # legend text: readable on the light and the dark theme


def color(first: RunResult, name: str) -> tuple[int, int, int]:
    """The truth's or an estimator's colour (frusta, markers): its row of the estimator table."""
    if name == "truth":
        return TRUTH
    est = first.estimators.get(name) or TABLE.get(name)
    return est.color if est is not None else (200, 200, 200)


def _best(names: list[str]) -> str:
    """The estimator whose halftone model and orthophoto are shown by default."""
    return next((n for n in (POSTERIOR, ITERATED, REFINED, "gtsam-ba", SEARCH) if n in names), "navigation")


def _accumulate() -> rrb.VisibleTimeRanges:
    """Everything from the start of the search up to the time cursor, on both timelines."""
    return rrb.VisibleTimeRanges([rrb.VisibleTimeRange(t, start=rrb.TimeRangeBoundary.infinite(),
                                                       end=rrb.TimeRangeBoundary.cursor_relative())
                                  for t in TIMELINES])


def blueprint(names: list[str]) -> rrb.Blueprint:
    """The 3D scene (and the halftone model) on the left; the search (hypothesis cloud and the
    functional), the images, the ground error maps, the orthophoto and the table on the right."""
    cloud = {"/world/search/hypotheses": _accumulate()}
    quiet = rr.Points3D.from_fields(show_labels=False)   # the markers' labels only in the search view
    scene = rrb.Spatial3DView(origin="/world", contents=["+ $origin/**", "- $origin/halftone/**"],
                              name="scene (m, z up): DEM, frusta, tie points, hypotheses", background=BACKGROUND,
                              overrides={**cloud, "/world/search/markers": quiet, "/world/search/winner": quiet})
    best = next((n for n in PREFERRED if n in names), _best(names))  # the estimator the model files are built from
    model = rrb.Spatial3DView(
        origin="/world", contents=["+ $origin/halftone/**", "+ $origin/ba/tie_points"],
        name=f"halftone model ({best}; others hidden)", background=BACKGROUND,
        overrides={f"/world/halftone/{n}": rrb.EntityBehavior(visible=False) for n in names if n != best})
    search = rrb.Spatial3DView(
        origin="/world", contents=["+ $origin/search/**"], background=BACKGROUND, overrides=cloud,
        name="hypotheses: image II position + attitude offset, colour = I_pq rank (yellow lowest)")
    whole = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    functional = rrb.TimeSeriesView(origin="/functional", name="functional I_pq - min I per hypothesis",
                                    plot_legend=rrb.Corner2D.RightTop, axis_x=rrb.TimeAxis(view_range=whole))
    images = rrb.Vertical(
        rrb.Spatial2DView(origin="/world/cameras/truth/I", name="image I + tie points"),
        rrb.Spatial2DView(origin="/world/cameras/truth/II", name="image II + tie points, measurements"),
        name="images")
    errors = rrb.Grid(*[rrb.Spatial2DView(origin=f"/errors/{n}", name=n) for n in names], name="ground error (m)")
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(scene, model),
            rrb.Tabs(rrb.Vertical(search, functional, row_shares=[3, 2], name="search"), images, errors,
                     rrb.Spatial2DView(origin="/orthophoto", name="orthophoto"),
                     rrb.TextDocumentView(origin="/summary", name="results")),
            column_shares=[3, 2]),
        rrb.TimePanel(state="collapsed", timeline="hypothesis"),
        collapse_panels=True,
    )


# --- colours and images -------------------------------------------------------------------

def _ramp(rank: np.ndarray) -> np.ndarray:
    """A viridis-like ramp for ``rank`` in [0, 1], reversed: 0 (the lowest functional) bright
    yellow, 1 dark purple (fading into the dark background). uint8 RGB."""
    stops = np.array([[253, 231, 37], [94, 201, 98], [33, 145, 140], [59, 82, 139], [68, 1, 84]], float)
    x = np.clip(np.nan_to_num(rank), 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(x.astype(int), len(stops) - 2)
    f = (x - i)[..., None]
    return (stops[i] * (1 - f) + stops[i + 1] * f).round().astype(np.uint8)


def _ui(points: float) -> float:
    """A radius in UI points (constant on screen) rather than metres."""
    return float(rr.components.Radius.ui_points(points))


def _gray(image: np.ndarray) -> np.ndarray:
    return (255 * np.clip(image, 0.0, 1.0)).astype(np.uint8)


def _rgb(image: np.ndarray) -> np.ndarray:
    return np.repeat(_gray(image)[..., None], 3, axis=-1)


def _nice_ceiling(x: float) -> float:
    """The smallest of 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8 times a power of ten at or above ``x``
    (a legend's top: at most a third above the largest value, the widest step of ``NICE``)."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    p = 10.0 ** np.floor(np.log10(x))
    return float(next(m * p for m in NICE if m * p >= x * (1 - 1e-9)))


# --- the world frame, the DEM and the cameras --------------------------------------------

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


def _dem(rec: rr.RecordingStream, sc: Scene, origin: np.ndarray) -> tuple[float, float, float, float]:
    """The DEM mesh around both footprints, textured; returns its bounds."""
    bounds = footprint_bounds(sc)
    step = max(1, int(np.ceil((bounds[1] - bounds[0]) / abs(sc.dem.dx) / 150)))
    dm = halftone.dem_mesh(sc.dem, step, bounds)
    span = max(bounds[1] - bounds[0], bounds[3] - bounds[2])
    spacing = max(span / 1024.0, ground_sample_distance(sc) / 2.0)
    tex = dem_texture(sc, bounds, spacing)
    rows, cols = tex.shape[:2]
    uv = np.stack([(dm.vertices[:, 0] - bounds[0] + 0.5 * spacing) / (cols * spacing),
                   (bounds[3] - dm.vertices[:, 1] + 0.5 * spacing) / (rows * spacing)], axis=1)
    rec.log("/world/dem", rr.Mesh3D(vertex_positions=dm.vertices - origin, triangle_indices=dm.triangles,
                                    vertex_texcoords=uv, albedo_texture=tex), static=True)
    return bounds


def _camera(rec: rr.RecordingStream, path: str, k: Intrinsics, position: np.ndarray, angles: np.ndarray,
            rgb: tuple[int, int, int], image: np.ndarray | None, plane: float, width: float) -> None:
    """A frustum (and its image). The principal point moves by half a pixel: the camera model
    puts pixel centres at integers, Rerun at half-integers."""
    rec.log(path, rr.Transform3D(translation=position, mat3x3=camera.rotation(angles)), rr.TransformAxes3D(0.0),
            static=True)
    rec.log(path, rr.Pinhole(focal_length=[k.fx, k.fy], principal_point=[k.cx + 0.5, k.cy + 0.5], width=k.width,
                             height=k.height, image_plane_distance=plane, color=rgb, line_width=width), static=True)
    if image is not None:
        rec.log(path, rr.Image(_gray(image)), static=True)


def _cameras(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    sc = first.scene
    plane = 0.25 * (sc.position[0, 2] - sc.dem.mean_height)
    for i, ex in enumerate(("I", "II")):
        _camera(rec, f"/world/cameras/truth/{ex}", sc.k, sc.position[i] - origin, sc.angles[i], color(first, "truth"),
                sc.images[i], plane, 3.0)
        for name, e in first.estimates.items():
            _camera(rec, f"/world/cameras/{name}/{ex}", sc.k, e.position[i] - origin, e.angles[i], color(first, name),
                    None, plane, 1.5)


# --- the search ---------------------------------------------------------------------------

@dataclass
class Glyph:
    """How a hypothesis (image II's six pose errors ``dX, dY, dH, dpsi, dtheta, dgamma``) is
    drawn in 3D: at the position it implies (measured minus the position error) moved by
    ``scale`` metres per radian of its attitude error, pitch along X, roll along Y, yaw along Z.
    On a grid the attitude cells form a small cube (35 % of a position cell) around each
    position cell."""

    measured: np.ndarray      # (3,) image II's measured position (world frame of the recording)
    scale: float              # m per rad
    cell: np.ndarray          # (3,) the position cell's size, m

    def __call__(self, pose_errors: np.ndarray) -> np.ndarray:
        p = np.asarray(pose_errors, float)
        return self.measured - p[..., :3] - self.scale * p[..., [4, 5, 3]]


def pose_errors(first: RunResult, centres: np.ndarray) -> np.ndarray:
    """Image II's pose errors ``(..., 6)`` of error states (the search's hypotheses)."""
    m = navigation.error_map(first.scene_mode, first.scene.interval)[1]
    return np.asarray(centres, float) @ m.T


def estimate_errors(first: RunResult, e: Estimate | tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Image II's pose errors (measured - this pose), as the search would state them."""
    pos, ang = (e.position, e.angles) if isinstance(e, Estimate) else e
    return np.concatenate([first.measured.position[1] - pos[1], wrap(first.measured.angles[1] - ang[1])])


def glyph(first: RunResult, origin: np.ndarray) -> Glyph:
    """The drawing of this run's hypotheses (their grid's cell, or for samples the cube's
    volume shared among them)."""
    s = first.search
    pose = pose_errors(first, s.centres)
    lin, ang = pose[:, :3], pose[:, 3:]
    ptp = np.ptp(lin, axis=0)
    if s.kind == "grid":
        levels = np.array([len(np.unique(np.round(lin[:, a], 6))) for a in range(3)])
        cell = np.where(levels > 1, ptp / np.maximum(levels - 1, 1), np.nan)
    else:
        cell = np.where(ptp > 0, ptp / len(lin) ** (1.0 / 3.0), np.nan)
    cell = np.where(np.isfinite(cell), cell, np.nanmax(cell) if np.isfinite(cell).any() else 1.0)
    spread = float(np.ptp(ang, axis=0).max())
    scale = 0.35 * float(cell.min()) / spread if spread > 0 else 0.0
    return Glyph(first.measured.position[1] - origin, scale, cell)


def lowest_so_far(f: np.ndarray) -> np.ndarray:
    """For every hypothesis, the index of the lowest functional up to it (the first on ties)."""
    low = np.minimum.accumulate(f)
    new = np.r_[True, low[1:] < low[:-1]]
    return np.maximum.accumulate(np.where(new, np.arange(len(f)), 0))


def _search(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """The hypothesis cloud over the search's timelines, the winner and its cell, the truth and
    every estimate drawn the same way, and the functional."""
    s = first.search
    g = glyph(first, origin)
    pose = pose_errors(first, s.centres)
    pts = g(pose)
    f = np.asarray(s.functional, float)
    n = len(f)
    rank = np.argsort(np.argsort(f, kind="stable"), kind="stable") / max(1, n - 1)
    starts = np.arange(0, n, max(1, s.chunk))
    counts = np.diff(np.r_[starts, n])
    radius = 0.04 * float(g.cell.min())
    rec.log("/world/search/hypotheses", rr.Points3D.from_fields(radii=[radius]), static=True)
    rec.send_columns("/world/search/hypotheses",
                     indexes=[rr.TimeColumn("hypothesis", sequence=starts + counts - 1),
                              rr.TimeColumn("search", sequence=np.arange(len(starts)))],
                     columns=rr.Points3D.columns(positions=pts, colors=_ramp(rank)).partition(counts))
    # the lowest hypothesis so far (and its position cell), a row wherever it changes; the last is the winner
    w = s.winner
    ends = starts + counts - 1
    best = lowest_so_far(f)[ends]
    best[-1] = w
    change = np.flatnonzero(np.r_[True, best[1:] != best[:-1]])
    labels = [f"lowest so far #{b}" for b in best[change]]
    labels[-1] = f"winner #{w}"
    steps = [rr.TimeColumn("hypothesis", sequence=ends[change]), rr.TimeColumn("search", sequence=change)]
    rec.log("/world/search/winner", rr.Points3D.from_fields(radii=[2.5 * radius], colors=[color(first, SEARCH)]),
            static=True)
    rec.send_columns("/world/search/winner", indexes=steps,
                     columns=rr.Points3D.columns(positions=pts[best[change]], labels=labels))
    rec.log("/world/search/winner_cell",
            rr.Boxes3D.from_fields(half_sizes=[g.cell / 2.0], colors=[color(first, SEARCH)], radii=[_ui(1.5)],
                                   fill_mode="MajorWireframe"), static=True)
    rec.send_columns("/world/search/winner_cell", indexes=steps,
                     columns=rr.Boxes3D.columns(centers=g.measured - pose[best[change], :3]))
    names = ["truth"] + [name for name in first.estimates if name != SEARCH]
    poses = [estimate_errors(first, (first.scene.position, first.scene.angles))]
    poses += [estimate_errors(first, first.estimates[name]) for name in names[1:]]
    rec.log("/world/search/markers", rr.Points3D(g(np.stack(poses)), radii=[2.0 * radius], labels=names,
                                                 colors=[color(first, name) for name in names]), static=True)
    # the functional: every hypothesis, the lowest so far, the winner
    hyp = np.arange(n)
    indexes = [rr.TimeColumn("hypothesis", sequence=hyp), rr.TimeColumn("search", sequence=hyp // max(1, s.chunk))]
    rel = f - f.min()
    rec.log("/functional", rr.SeriesLines(colors=[color(first, SEARCH)], names=["I_pq - min I"]), static=True)
    rec.send_columns("/functional", indexes=indexes, columns=rr.Scalars.columns(scalars=rel))
    rec.log("/functional/lowest", rr.SeriesLines(colors=[(40, 140, 255)], names=["lowest so far"], widths=[2.0]),
            static=True)
    rec.send_columns("/functional/lowest", indexes=indexes,
                     columns=rr.Scalars.columns(scalars=np.minimum.accumulate(rel)))
    rec.log("/functional/winner", rr.SeriesPoints(colors=[(200, 30, 30)], names=[f"winner #{w}"], marker_sizes=[6.0]),
            static=True)
    rec.send_columns("/functional/winner",
                     indexes=[rr.TimeColumn("hypothesis", sequence=[w]),
                              rr.TimeColumn("search", sequence=[w // max(1, s.chunk)])],
                     columns=rr.Scalars.columns(scalars=[rel[w]]))


# --- the baseline, the halftone models, the error maps ------------------------------------

def _baseline(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """The BA's landmarks, rays from its two cameras to a subset of them, and the tie points on
    the images (pixel centres moved to Rerun's half-integers)."""
    ba = first.estimates.get("gtsam-ba")
    if ba is None or "landmarks" not in ba.extras:
        return
    lm = np.asarray(ba.extras["landmarks"], float) - origin
    rgb = color(first, "gtsam-ba")
    rec.log("/world/ba/tie_points", rr.Points3D(lm, radii=[_ui(3.0)], colors=[rgb]),
            static=True)
    pick = np.unique(np.linspace(0, len(lm) - 1, min(len(lm), MAX_RAYS)).round().astype(int))
    strips = [np.stack([ba.position[i] - origin, lm[j]]) for i in range(2) for j in pick]
    rec.log("/world/ba/rays", rr.LineStrips3D(strips, radii=[_ui(0.5)],
                                              colors=[(125, 95, 165)]), static=True)
    uv = ba.extras.get("tie_points")
    if uv is not None:
        for ex, pts in zip(("I", "II"), uv, strict=True):
            rec.log(f"/world/cameras/truth/{ex}/tie_points",
                    rr.Points2D(np.asarray(pts, float) + 0.5, radii=[_ui(2.5)],
                                colors=[rgb]), static=True)


def halftone_texcoords(k: Intrinsics, step: int) -> np.ndarray:
    """Texture coordinates of :func:`halftone.ground`'s grid in the full-resolution image."""
    vv, uu = np.mgrid[0:k.height:step, 0:k.width:step]
    return np.stack([(uu.ravel() + 0.5) / k.width, (vv.ravel() + 0.5) / k.height], axis=1)


def _halftones(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """Image II draped on the ground coordinates each estimator's orientation gives it."""
    sc = first.scene
    k = sc.k
    step = max(1, min(k.width, k.height) // 100)
    thin = _stride(sc.images[1])
    tex, uv = _rgb(sc.images[1][::thin, ::thin]), halftone_texcoords(k, step)
    for name, e in first.estimates.items():
        mh = halftone.mesh(halftone.ground(sc.dem, k, e.position[1], e.angles[1], step=step))
        rec.log(f"/world/halftone/{name}", rr.Mesh3D(vertex_positions=mh.vertices - origin,
                                                     triangle_indices=mh.triangles, vertex_texcoords=uv,
                                                     albedo_texture=tex), static=True)


def _stride(image: np.ndarray) -> int:
    """Every how-many-th pixel keeps an image at most ``MAX_PIXELS_SIDE`` on its longer side."""
    return max(1, -(-max(image.shape[:2]) // MAX_PIXELS_SIDE))


def _error_map(rec: rr.RecordingStream, name: str, err: np.ndarray) -> None:
    """One ground error map (metres, a colour-mapped depth image: hovering reads the error) with
    a colour bar below it, its ticks and a title line under the bar (large maps thinned to
    ``MAX_PIXELS_SIDE``; the title's statistics are the full map's)."""
    full = np.asarray(err, np.float32)
    thin = _stride(full)
    err = full[::thin, ::thin]
    rows, cols = err.shape
    top = _nice_ceiling(float(np.nanmax(full)))
    path = f"/errors/{name}"
    rec.log(path, rr.DepthImage(err, meter=1.0, colormap=ERROR_COLORMAP, depth_range=(0.0, top)), static=True)
    gap, bar_h = max(1, rows // 30), max(4, rows // 10)
    bar = np.repeat(((np.arange(cols) + 0.5) / cols * top).astype(np.float32)[None], bar_h, axis=0)
    rec.log(f"{path}/legend", rr.Transform3D(translation=[0.0, rows + gap, 0.0]),
            rr.DepthImage(bar, meter=1.0, colormap=ERROR_COLORMAP, depth_range=(0.0, top)), static=True)
    at = np.array([0.2, 0.5, 0.8])          # three ticks: five overlap on a small map
    rec.log(f"{path}/legend/ticks", rr.Points2D(np.stack([at * cols, np.full(len(at), bar_h + 0.05 * rows)], 1),
                                                radii=[0.0], labels=[f"{t * top:.3g} m" for t in at],
                                                colors=[LABEL]), static=True)
    rms, worst = float(np.sqrt(np.nanmean(np.square(full)))), float(np.nanmax(full))
    # the title, and an unlabelled point under it: a view fits its points, not their labels
    rec.log(f"{path}/legend/title", rr.Points2D([[cols / 2.0, bar_h + 0.14 * rows], [cols / 2.0, bar_h + 0.3 * rows]],
                                                radii=[0.0], colors=[LABEL],
                                                labels=[f"{name}: rmse {rms:.2f} m, max {worst:.2f} m", ""]),
            static=True)


def _orthophoto(rec: rr.RecordingStream, sc: Scene, best: Estimate, bounds: tuple[float, float, float, float]
                ) -> None:
    """Image II on a north-up ground grid at its own pixel size, transparent outside it."""
    span = max(bounds[1] - bounds[0], bounds[3] - bounds[2])
    gsd = max(ground_sample_distance(sc), span / 1500.0)
    ortho = halftone.orthophoto(sc.dem, sc.k, best.position[1], best.angles[1], sc.images[1], bounds, gsd)
    rgba = np.concatenate([_rgb(np.nan_to_num(ortho, nan=0.0)),
                           np.where(np.isfinite(ortho), 255, 0).astype(np.uint8)[..., None]], axis=-1)
    rec.log("/orthophoto", rr.Image(rgba, color_model="RGBA"), static=True)


def legend(first: RunResult, origin: np.ndarray) -> str:
    """How to read the recording (markdown, after the table)."""
    shown = {n: first.estimators.get(n) or TABLE[n] for n in first.estimates}
    frusta = f"truth {draw.colour_name(TRUTH)}, " + draw.colour_key(shown, plugin="a plugin")
    tie_points, winner = (draw.colour_name(color(first, n)) for n in ("gtsam-ba", SEARCH))
    where = ("" if not origin.any() else
             f"; local origin at X = {origin[0]:.0f} m, Y = {origin[1]:.0f} m of the data's projection")
    lines = [
        "",
        "**Reading the recording** (run 0, error mode `" + first.scene_mode + "`; world X east, Y north, "
        "Z up, metres" + where + ")",
        "",
        f"- frusta: {frusta}; the truth's carry the images (tie points {tie_points}).",
        "- DEM: textured with both images at the true orientation; warm hillshade where no image sees it.",
    ]
    if first.search is not None:
        g = glyph(first, origin)
        lines.append(
            f"- search: each hypothesis at the image II position it implies, its attitude error as an offset of "
            f"{g.scale / 1000.0:.3g} m per mrad (pitch along X, roll along Y, yaw along Z); colour = rank of I_pq "
            f"(yellow lowest, dark purple highest); the {winner} point and box: the lowest hypothesis so far and its "
            "position cell (the winner at the end); markers: truth and every estimate drawn the same way. Scrub the "
            "`hypothesis` (or `search` step) timeline.")
    lines.append("- ground error maps: per-pixel horizontal error of each halftone model over image II, "
                 "each on its own colour scale (bar in metres).")
    return "\n".join(lines)


def narrow_tables(markdown: str, columns: int = 5) -> str:
    """Markdown tables wider than ``columns`` split into several, each repeating the first
    column (the right-hand panel is narrow; a wide table is cut off there)."""
    out: list[str] = []
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].lstrip().startswith("|"):
            out.append(lines[i])
            i += 1
            continue
        j = i
        while j < len(lines) and lines[j].lstrip().startswith("|"):
            j += 1
        rows = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines[i:j]]
        width = max(len(r) for r in rows)
        if width <= columns:
            out.extend(lines[i:j])
        else:
            parts = -(-(width - 1) // (columns - 1))
            per = -(-(width - 1) // parts)          # balanced: 9 columns in 3 tables of 3, not 4 + 4 + 1
            for start in range(1, width, per):
                cols = [0, *range(start, min(width, start + per))]
                out.extend("| " + " | ".join(r[c] if c < len(r) else "" for c in cols) + " |" for r in rows)
                out.append("")
        i = j
    return "\n".join(out)


def layout(first: RunResult, runs: list[RunSummary]) -> rrb.Blueprint:
    """The default layout of a run's recording."""
    return blueprint(list(first.estimates))


def record_run(rec: rr.RecordingStream, first: RunResult, zero: RunSummary) -> None:
    """Log run 0 (``zero`` is its evaluation): scene, cameras, the search, the baseline's
    tie points, the halftone models and their ground error maps."""
    sc = first.scene
    origin = local_origin(sc)
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    bounds = _dem(rec, sc, origin)
    _cameras(rec, first, origin)
    if first.search is not None:
        _search(rec, first, origin)
    _baseline(rec, first, origin)
    _halftones(rec, first, origin)
    for name, err in zero.ground_maps.items():
        _error_map(rec, name, err)
    _orthophoto(rec, sc, first.estimates[_best(list(first.estimates))], bounds)
    _measurements(rec, first, origin)


MEASURE_RGB = (255, 235, 60)


def _measurements(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """A few measurements in the run's halftone model (:func:`.measure.examples`): on image II
    (pixels) and on the model's surface in 3D (the edges' ground points, along the terrain,
    lifted a little above it to stay in sight), labelled value +- sigma."""
    from workbench.experiments.terrain import measure, model

    try:
        m = model.from_run(first)
        found = measure.examples(m)
    except WorkbenchError:
        return  # a model the DEM does not hold: the recording goes without its measurements
    lift = np.array([0.0, 0.0, 0.002 * (m.position[2] - m.dem.mean_height)])
    for i, ms in enumerate(found):
        q = ms.quantities[{"point": 2, "line": 0, "polygon": 0}[ms.kind]]
        label = q.text().replace(" +- ", " ± ").replace("m^2", "m²")
        if ms.kind == "point":
            rec.log(f"/world/cameras/truth/II/measurements/{i}",
                    rr.Points2D(np.array(ms.pixels) + 0.5, radii=[_ui(5)], colors=[MEASURE_RGB], labels=[label]),
                    static=True)
            rec.log(f"/world/halftone/measurements/{i}", rr.Points3D(ms.ground - origin + lift, radii=[_ui(6)],
                                                                     colors=[MEASURE_RGB], labels=[label]),
                    static=True)
            continue
        closed = ms.kind == "polygon"
        px = np.array(ms.pixels + ms.pixels[:1] if closed else ms.pixels) + 0.5  # Rerun's pixel centres: +0.5
        along = measure.edge_pixels(ms.pixels, closed)
        g = m.ground(along[:, 0], along[:, 1]) - origin + lift
        rec.log(f"/world/cameras/truth/II/measurements/{i}",
                rr.LineStrips2D([px], radii=[_ui(2)], colors=[MEASURE_RGB], labels=[label]), static=True)
        rec.log(f"/world/halftone/measurements/{i}",
                rr.LineStrips3D([g], radii=[_ui(3)], colors=[MEASURE_RGB], labels=[label]), static=True)


def measurements_markdown(first: RunResult) -> str:
    """The recorded measurements as a table, beside what the same pixels measure under the
    true orientation (the scene's truth; for NGI its published orientation)."""
    from workbench.experiments.terrain import measure, model

    try:
        m = model.from_run(first)
        found = measure.examples(m)
        sc = first.scene
        truth = measure.examples(model.Model("truth", sc.dem, sc.k, sc.position[1], sc.angles[1], None))
    except WorkbenchError:
        return ""
    rows = ["", f"**halftone model** (image II under {m.estimator}'s orientation, model {m.model_id}; "
            "`workbench measure` reads its files): a few measurements, +- the orientation covariance's sigma",
            "", "| measurement | value | sigma | true orientation | error / sigma |", "|---|---|---|---|---|"]
    for a, b in zip(found, truth, strict=True):
        for q, r in zip(a.quantities, b.quantities, strict=True):
            z = f"{(q.value - r.value) / q.sigma:+.2f}" if q.sigma else "-"
            sig = f"{q.sigma:.3g}" if q.sigma is not None else "-"
            rows.append(f"| {a.kind} {q.name} ({q.unit}) | {q.value:.6g} | {sig} | {r.value:.6g} | {z} |")
    return "\n".join(rows) + "\n"


def record_runs(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log the results table (the Monte Carlo statistics) and how to read the recording."""
    text = narrow_tables(table_md) + "\n" + legend(first, local_origin(first.scene)) + measurements_markdown(first)
    rec.log("/summary", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
