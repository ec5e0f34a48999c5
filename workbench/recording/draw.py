"""Columnar drawing helpers: everything logged per step goes through ``send_columns``.

Maps are drawn in a top-down 3D view (z up, the sea at z = 0): 2D views are y-down and
``Ellipses2D`` has no rotation, so covariance ellipses are flat ``Ellipsoids3D``.
"""

from __future__ import annotations

import numpy as np
import rerun as rr

PALETTE = {"truth": (230, 230, 230), "truth on white": (40, 40, 40), "observer": (80, 160, 255),
           "measured": (140, 140, 140)}
"""Colours of what is not an estimator; each estimator's colour is its row of the estimator table.
The truth is near-white on the maps' dark background and near-black in the (light) plots."""


def color(name: str) -> tuple[int, int, int]:
    return PALETTE[name]


NAMED = {"red": (230, 70, 70), "orange": (255, 170, 0), "yellow": (255, 230, 60), "green": (60, 200, 90),
         "cyan": (0, 210, 200), "blue": (0, 100, 255), "violet": (190, 90, 240), "pink": (255, 110, 200),
         "brown": (165, 95, 35), "grey": (150, 150, 150), "white": (235, 235, 235), "black": (30, 30, 30),
         "lime": (150, 220, 0), "magenta": (255, 0, 255), "teal": (0, 150, 110), "purple": (120, 60, 200),
         "sky blue": (0, 190, 255)}
"""Colour words for the recordings' "how to read this" notes (the viewer shows no colour in text)."""


def colour_name(rgb: tuple[int, int, int]) -> str:
    """The nearest colour word of :data:`NAMED` (its hex code where none is near)."""
    name, ref = min(NAMED.items(), key=lambda kv: sum((a - b) ** 2 for a, b in zip(kv[1], rgb, strict=True)))
    near = sum((a - b) ** 2 for a, b in zip(ref, rgb, strict=True)) <= 60**2
    return name if near else "#{:02x}{:02x}{:02x}".format(*rgb)


def colour_key(estimators: dict, plugin: str = "a plugin, drawn wider") -> str:
    """``ekf red, gtsam violet, ...``: each estimator's colour in words, a plugin's marked
    ``(<plugin>)`` (where the experiment draws plugins as the built-ins, say only that)."""
    return ", ".join(f"{n} {colour_name(e.color)}" + ("" if e.builtin else f" ({plugin})")
                     for n, e in estimators.items())


def emphasis(estimator) -> float:
    """How much wider a line (larger a marker) an estimator gets: a researcher's own plugin,
    what they came to look at, is drawn 2.5 times as wide as the built-ins it sits among (at
    1.8 a browser review still found it under the built-ins' lines)."""
    return 1.0 if estimator.builtin else 2.5


def plot_series(rec: rr.RecordingStream, timeline: str, curves: dict, estimators: dict, keep=lambda origin: True,
                others: dict | None = None) -> None:
    """Every series of the plots' ``curves`` (view origin -> ``layout.Curves``) whose origin
    ``keep`` accepts, at ``<origin>/<key>``: an estimator's in its colour (a plugin's wider), the
    rest by ``others`` (key -> (colour, width)), else grey and thin (a consistency band)."""
    others = others or {}
    for origin, c in curves.items():
        if not keep(origin):
            continue
        for key, values in c.series.items():
            est = estimators.get(key)
            rgb, w = (est.color, 1.5 * emphasis(est)) if est is not None else others.get(key, ((150, 150, 150), 1.0))
            scalars(rec, f"{origin}/{key}", timeline, c.t, values, c.label(key), rgb, w, key in c.points)


def times(timeline: str, seconds: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(timeline, duration=np.asarray(seconds, float))


def scalars(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, values: np.ndarray,
            name: str, rgb: tuple[int, int, int], width: float = 1.5, points: bool = False) -> int:
    """A time series (NaNs dropped), styled once statically (a line, or ``points`` at least 3 px,
    twice ``width``); returns the row count."""
    values = np.asarray(values, float)
    ok = np.isfinite(values)
    style = (rr.SeriesPoints(colors=[rgb], names=[name], marker_sizes=[max(3.0, 2.0 * width)]) if points
             else rr.SeriesLines(colors=[rgb], names=[name], widths=[width]))
    rec.log(path, style, static=True)
    if ok.any():
        rec.send_columns(path, indexes=[times(timeline, t[ok])],
                         columns=rr.Scalars.columns(scalars=values[ok]))
    return int(ok.sum())


def _xyz(xy: np.ndarray, z: float = 0.0) -> np.ndarray:
    xy = np.asarray(xy, float)
    return np.concatenate([xy, np.full(xy.shape[:-1] + (1,), z)], axis=-1)


def track(rec: rr.RecordingStream, path: str, xy: np.ndarray, rgb, radius: float = 0.6, z: float = 0.0) -> None:
    """A whole path as one static line strip (segments split at NaNs), at height ``z`` (a map
    seen from above shows what is higher on top: the truth over the estimates). A negative
    ``radius`` is in UI points (the same width at any zoom)."""
    xy = np.asarray(xy, float)
    ok = np.isfinite(xy).all(axis=1)
    strips, cur = [], []
    for p, good in zip(_xyz(xy, z), ok, strict=True):
        if good:
            cur.append(p)
        elif cur:
            strips.append(np.array(cur))
            cur = []
    if cur:
        strips.append(np.array(cur))
    rec.log(path, rr.LineStrips3D(strips, colors=[rgb], radii=[radius]), static=True)


def moving_point(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, xy: np.ndarray,
                 rgb, radius: float = 3.0, label: str | None = None, z: float = 0.0) -> int:
    """One point per step (NaN steps skipped), at height ``z``."""
    ok = np.isfinite(xy).all(axis=1)
    if label:
        rec.log(path, rr.Points3D.from_fields(colors=[rgb], radii=[radius], labels=[label],
                                              show_labels=False), static=True)
    else:
        rec.log(path, rr.Points3D.from_fields(colors=[rgb], radii=[radius]), static=True)
    if ok.any():
        rec.send_columns(path, indexes=[times(timeline, t[ok])],
                         columns=rr.Points3D.columns(positions=_xyz(xy[ok], z)))
    return int(ok.sum())


def strip_array(strips: np.ndarray) -> np.ndarray:
    """Line strips of one length ``(n, k, 2 or 3)`` as rerun takes them fastest: one contiguous float
    array, which it converts in one piece; a list of strips it converts one by one (50,000 strips:
    0.007 s against 0.88 s, the same Arrow array)."""
    return np.ascontiguousarray(strips, float)


def segments(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, start: np.ndarray,
             end: np.ndarray, rgb, radius: float = 0.3, z: float = 0.0) -> int:
    """One line segment per step (e.g. the line of sight), at height ``z``."""
    ok = np.isfinite(start).all(axis=1) & np.isfinite(end).all(axis=1)
    rec.log(path, rr.LineStrips3D.from_fields(colors=[rgb], radii=[radius]), static=True)
    strips = np.stack([_xyz(start[ok], z), _xyz(end[ok], z)], axis=1)
    if ok.any():
        rec.send_columns(path, indexes=[times(timeline, t[ok])],
                         columns=rr.LineStrips3D.columns(strips=strip_array(strips)))
    return int(ok.sum())


def polylines(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, paths: np.ndarray,
              rgb, radius: float = 0.4) -> int:
    """One polyline per step, ``paths (T, L, 2)`` (e.g. a forecast drawn ahead of the present)."""
    ok = np.isfinite(paths).all(axis=(1, 2))
    rec.log(path, rr.LineStrips3D.from_fields(colors=[rgb], radii=[radius]), static=True)
    if ok.any():
        rec.send_columns(path, indexes=[times(timeline, t[ok])],
                         columns=rr.LineStrips3D.columns(strips=strip_array(_xyz(paths[ok]))))
    return int(ok.sum())


def covariance_ellipses(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray,
                        centers: np.ndarray, cov: np.ndarray, rgb, n_sigma: float = 2.4477) -> int:
    """Flat ellipsoids of the 2D position covariance (95 % by default), one per step."""
    ok = np.isfinite(centers).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    if not ok.any():
        return 0
    vals, vecs = np.linalg.eigh(cov[ok])
    half = n_sigma * np.sqrt(np.clip(vals, 0.0, None))
    angle = np.arctan2(vecs[:, 1, 1], vecs[:, 0, 1])  # direction of the major axis
    quats = np.stack([np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2),
                      np.cos(angle / 2)], axis=1)
    half_sizes = np.stack([half[:, 1], half[:, 0], np.full(len(half), 0.05)], axis=1)
    rec.log(path, rr.Ellipsoids3D.from_fields(colors=[rgb], fill_mode=rr.components.FillMode.MajorWireframe),
            static=True)
    rec.send_columns(path, indexes=[times(timeline, t[ok])],
                     columns=rr.Ellipsoids3D.columns(centers=_xyz(centers[ok]), half_sizes=half_sizes,
                                                     quaternions=quats))
    return int(ok.sum())


def _ellipse_geometry(cov: np.ndarray, n_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Half sizes ``(M, 3)`` and z-rotations as quaternions ``(M, 4)`` of 2D covariances ``(M, 2, 2)``."""
    vals, vecs = np.linalg.eigh(cov)
    half = n_sigma * np.sqrt(np.clip(vals, 0.0, None))
    angle = np.arctan2(vecs[:, 1, 1], vecs[:, 0, 1])
    quats = np.stack([np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2), np.cos(angle / 2)], axis=1)
    return np.stack([half[:, 1], half[:, 0], np.full(len(half), 0.02)], axis=1), quats


def point_sets(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, xy: np.ndarray,
               rgb, radius: float = 0.3, z: float = 0.0) -> int:
    """A set of points per step, ``xy (T, N, 2)``; NaN points left out (an empty set clears)."""
    ok = np.isfinite(xy).all(axis=2)
    rec.log(path, rr.Points3D.from_fields(colors=[rgb], radii=[radius]), static=True)
    pts = _xyz(xy[ok], z) if ok.any() else np.zeros((0, 3))
    rec.send_columns(path, indexes=[times(timeline, t)],
                     columns=rr.Points3D.columns(positions=pts).partition(ok.sum(axis=1)))
    return len(t)


def ellipse_sets(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, centers: np.ndarray,
                 cov: np.ndarray, rgb, n_sigma: float = 2.4477) -> int:
    """A set of covariance ellipses per step: ``centers (T, N, 2)``, ``cov (T, N, 2, 2)`` (95 %)."""
    ok = np.isfinite(centers).all(axis=2) & np.isfinite(cov).all(axis=(2, 3))
    rec.log(path, rr.Ellipsoids3D.from_fields(colors=[rgb], fill_mode=rr.components.FillMode.MajorWireframe),
            static=True)
    if ok.any():
        half, quats = _ellipse_geometry(cov[ok], n_sigma)
        cols = rr.Ellipsoids3D.columns(centers=_xyz(centers[ok]), half_sizes=half, quaternions=quats)
    else:
        cols = rr.Ellipsoids3D.columns(centers=np.zeros((0, 3)), half_sizes=np.zeros((0, 3)),
                                       quaternions=np.zeros((0, 4)))
    rec.send_columns(path, indexes=[times(timeline, t)], columns=cols.partition(ok.sum(axis=1)))
    return len(t)


def segment_sets(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, counts: np.ndarray,
                 start: np.ndarray, end: np.ndarray, rgb, radius: float = 0.05) -> int:
    """``counts[i]`` segments at ``t[i]``; ``start``/``end`` ``(sum(counts), 2)`` (e.g. bearing rays)."""
    rec.log(path, rr.LineStrips3D.from_fields(colors=[rgb], radii=[radius]), static=True)
    strips = strip_array(np.stack([_xyz(start), _xyz(end)], axis=1))
    rec.send_columns(path, indexes=[times(timeline, t)],
                     columns=rr.LineStrips3D.columns(strips=strips).partition(np.asarray(counts)))
    return len(t)


def poses(rec: rr.RecordingStream, path: str, timeline: str, t: np.ndarray, pose: np.ndarray, rgb,
          length: float = 2.0, z: float = 0.0) -> int:
    """A vehicle per step: an arrow from ``(x, y)`` along the heading ``pose (T, 3)``, at height ``z``."""
    ok = np.isfinite(pose).all(axis=1)
    p = pose[ok]
    rec.log(path, rr.Arrows3D.from_fields(colors=[rgb], radii=[0.15 * length / 2]), static=True)
    if ok.any():
        vec = np.stack([length * np.cos(p[:, 2]), length * np.sin(p[:, 2]), np.zeros(len(p))], axis=1)
        rec.send_columns(path, indexes=[times(timeline, t[ok])],
                         columns=rr.Arrows3D.columns(origins=_xyz(p[:, :2], z), vectors=vec))
    return int(ok.sum())


# --- static scenes: cameras, textured meshes, value images ---------------------------------

LABEL = (120, 120, 120)
"""Text drawn inside a view (a legend's ticks and title): readable on the light and the dark theme."""
NICE = (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
"""A legend's possible tops, times a power of ten (:func:`nice_ceiling`)."""


def ui_points(points: float) -> float:
    """A radius in UI points (the same on screen at any zoom) rather than scene units."""
    return float(rr.components.Radius.ui_points(points))


def gray8(image: np.ndarray) -> np.ndarray:
    """A grey image with values in [0, 1] as ``uint8`` (clipped)."""
    return (255 * np.clip(image, 0.0, 1.0)).astype(np.uint8)


def stride(image: np.ndarray, max_side: int) -> int:
    """Every how-many-th pixel keeps ``image`` at most ``max_side`` pixels on its longer side."""
    return max(1, -(-max(image.shape[:2]) // max_side))


def nice_ceiling(x: float) -> float:
    """The smallest of 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8 times a power of ten at or above ``x``
    (a legend's top: at most a third above the largest value, the widest step of :data:`NICE`)."""
    if not np.isfinite(x) or x <= 0:
        return 1.0
    p = 10.0 ** np.floor(np.log10(x))
    return float(next(m * p for m in NICE if m * p >= x * (1 - 1e-9)))


def frustum(rec: rr.RecordingStream, path: str, position: np.ndarray, rotation: np.ndarray,
            focal: tuple[float, float], principal: tuple[float, float], size: tuple[int, int],
            rgb: tuple[int, int, int], line_width: float, plane: float, image: np.ndarray | None = None) -> None:
    """A pinhole camera at ``position`` with ``rotation`` (camera to world, 3x3), static: its
    frustum in ``rgb`` reaching ``plane`` scene units, no axes, and ``image`` (any array
    ``rr.Image`` takes) on it. ``focal`` and ``principal`` in pixels with pixel centres at
    integers (OpenCV's convention), ``size`` (width, height); the principal point moves by half
    a pixel to Rerun's, whose pixel centres are at half-integers."""
    rec.log(path, rr.Transform3D(translation=position, mat3x3=rotation), rr.TransformAxes3D(0.0), static=True)
    rec.log(path, rr.Pinhole(focal_length=list(focal), principal_point=[principal[0] + 0.5, principal[1] + 0.5],
                             width=size[0], height=size[1], image_plane_distance=plane, color=rgb,
                             line_width=line_width), static=True)
    if image is not None:
        rec.log(path, rr.Image(image), static=True)


def textured_mesh(rec: rr.RecordingStream, path: str, vertices: np.ndarray, triangles: np.ndarray,
                  texcoords: np.ndarray, texture: np.ndarray) -> None:
    """A static triangle mesh, ``vertices (N, 3)``, ``triangles (M, 3)``, with an image draped
    on it: ``texture (H, W, 3)`` uint8 and each vertex's ``texcoords (N, 2)`` in it (u right,
    v down, 0-1 over the whole image)."""
    rec.log(path, rr.Mesh3D(vertex_positions=vertices, triangle_indices=triangles, vertex_texcoords=texcoords,
                            albedo_texture=texture), static=True)


def error_image(rec: rr.RecordingStream, path: str, values: np.ndarray, name: str, unit: str = "m",
                colormap: str = "Viridis", max_side: int = 1024) -> None:
    """A per-pixel error map (non-negative; NaN where there is none) as a colour-mapped depth
    image from 0 to a nice top (:func:`nice_ceiling`; hovering reads the value in ``unit``), with
    a colour bar under it at ``<path>/legend``, three ticks and a title line (``name``, the RMS
    and the largest value) under the bar; static. A map larger than ``max_side`` on its longer
    side is thinned (the title's statistics are the full map's)."""
    full = np.asarray(values, np.float32)
    thin = stride(full, max_side)
    shown = full[::thin, ::thin]
    rows, cols = shown.shape
    top = nice_ceiling(float(np.nanmax(full)))
    rec.log(path, rr.DepthImage(shown, meter=1.0, colormap=colormap, depth_range=(0.0, top)), static=True)
    gap, bar_h = max(1, rows // 30), max(4, rows // 10)
    bar = np.repeat(((np.arange(cols) + 0.5) / cols * top).astype(np.float32)[None], bar_h, axis=0)
    rec.log(f"{path}/legend", rr.Transform3D(translation=[0.0, rows + gap, 0.0]),
            rr.DepthImage(bar, meter=1.0, colormap=colormap, depth_range=(0.0, top)), static=True)
    at = np.array([0.2, 0.5, 0.8])          # three ticks: five overlap on a small map
    rec.log(f"{path}/legend/ticks", rr.Points2D(np.stack([at * cols, np.full(len(at), bar_h + 0.05 * rows)], 1),
                                                radii=[0.0], labels=[f"{t * top:.3g} {unit}" for t in at],
                                                colors=[LABEL]), static=True)
    rms, worst = float(np.sqrt(np.nanmean(np.square(full)))), float(np.nanmax(full))
    # the title, and an unlabelled point under it: a view fits its points, not their labels
    rec.log(f"{path}/legend/title", rr.Points2D([[cols / 2.0, bar_h + 0.14 * rows], [cols / 2.0, bar_h + 0.3 * rows]],
                                                radii=[0.0], colors=[LABEL],
                                                labels=[f"{name}: rmse {rms:.2f} {unit}, max {worst:.2f} {unit}", ""]),
            static=True)
