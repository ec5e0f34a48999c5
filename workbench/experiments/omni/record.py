"""The omni recording: one top-down map per estimator side by side, and the curves.

Entity layout (timeline ``time``, seconds of the recorded run 0):

* ``world/{walls,landmarks}`` (static), ``world/truth/{path,vehicle}``;
* ``map/<estimator>/{path,vehicle,pose_ellipse,landmarks,landmark_ellipses,rays}`` and, for
  the filters, ``map/<estimator>/pending`` (the UT sigma images of each initialisation try);
* ``errors/{position,heading}/<estimator>``, ``sigma/{position,heading}/<estimator>``,
  ``nees/<estimator>`` with ``nees/band_{lo,hi}`` (one run, 3 dof, 95 %);
* ``monte_carlo/{position,heading,nees}/<estimator>`` over all runs, with the band for that
  many runs; ``summary`` (the results table).
"""

from __future__ import annotations

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.estimation import metrics
from workbench.experiments.omni.evaluate import RunSummary, mc_curves, on_grid, pose_errors, pose_nees
from workbench.experiments.omni.run import RunResult
from workbench.recording import draw
from workbench.recording import layout as views

TL = "time"


def _map_view(name: str, centre: tuple[float, float], height: float) -> rrb.Spatial3DView:
    return rrb.Spatial3DView(
        origin="/", contents=["/world/**", f"/map/{name}/**"], name=f"{name} (top-down, m)",
        eye_controls=rrb.EyeControls3D(position=(centre[0], centre[1] - 1e-3, height),
                                       look_target=(centre[0], centre[1], 0.0), eye_up=(0.0, 1.0, 0.0)),
    )


def blueprint(names: list[str], centre: tuple[float, float] = (40.0, 40.0), height: float = 110.0,
              with_images: bool = False, span: tuple[float, float] = (0.0, 500.0),
              scales: dict[str, tuple[float | None, dict[str, float]]] | None = None) -> rrb.Blueprint:
    """Maps in a grid on the left (and the round camera image, when there is one); errors,
    sigmas, NEES and the Monte Carlo curves on the right, every plot on the whole run ``span``.
    ``scales`` (view -> value-axis top and the estimators off it, :func:`views.scale`) keeps one
    diverging estimator from flattening the others."""
    scales = scales or {}

    def plot(origin: str, name: str, unit: str = "") -> rrb.TimeSeriesView:
        top, off = scales.get(origin, (None, {}))
        return views.plot(origin, name + views.off_scale_note(off, unit), span, top=top)

    panes = [_map_view(n, centre, height) for n in names]
    if with_images:
        panes.insert(0, rrb.Spatial2DView(origin="/camera", name="round image, detected lines"))
    maps = rrb.Grid(*panes)
    one_run = rrb.Vertical(
        plot("/errors/position", "position error (m)", "m"),
        plot("/errors/heading", "heading error (deg)", "deg"),
        plot("/nees", "pose NEES (3 dof), 95 % band"),
        name="run 0",
    )
    sigmas = rrb.Vertical(
        plot("/sigma/position", "own sigma, position (m)", "m"),
        plot("/sigma/heading", "own sigma, heading (deg)", "deg"),
        name="sigmas",
    )
    mc = rrb.Vertical(
        plot("/monte_carlo/position", "RMS position error over runs (m)", "m"),
        plot("/monte_carlo/heading", "RMS heading error over runs (deg)", "deg"),
        plot("/monte_carlo/nees", "ANEES over runs, 95 % band"),
        name="Monte Carlo",
    )
    return rrb.Blueprint(
        rrb.Horizontal(maps, rrb.Tabs(one_run, sigmas, mc, rrb.TextDocumentView(origin="/summary", name="results")),
                       column_shares=[3, 2]),
        collapse_panels=True,
    )


def layout(first: RunResult) -> rrb.Blueprint:
    """The default layout: maps framed on the walls (the simulation) or the landmarks (MRCLAM)."""
    d = first.data
    if d.walls is not None:
        centre, height = tuple(d.walls.mean(axis=0)), 1.4 * float(d.walls.max() - d.walls.min())
    else:
        lo, hi = np.nanmin(d.landmarks, axis=0), np.nanmax(d.landmarks, axis=0)
        centre, height = tuple((lo + hi) / 2), 1.6 * float(max(hi - lo))
    grid, truth = first.grid, d.truth[first.grid]
    position, heading, nees = {}, {}, {}
    for name, est in first.estimates.items():
        pose, cov = on_grid(est, grid)
        e = pose_errors(truth, pose)
        position[name], heading[name], nees[name] = np.hypot(e[:, 0], e[:, 1]), np.degrees(e[:, 2]), pose_nees(e, cov)
    scales = {"/errors/position": views.scale(position), "/errors/heading": views.scale(heading),
              "/nees": views.scale(nees)}
    # the curves over runs diverge where run 0 does: the same estimators off their scale
    scales["/monte_carlo/position"], scales["/monte_carlo/heading"] = scales["/errors/position"], \
        scales["/errors/heading"]
    scales["/monte_carlo/nees"] = scales["/nees"]
    span = (float(d.t[grid[0]]), float(d.t[grid[-1]]))
    return blueprint(list(first.estimates), centre, height, first.images is not None, span, scales)


def _rays(first: RunResult, pose: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bearing rays drawn from an estimate's pose at each epoch: times, counts, starts, ends."""
    d = first.data
    epochs = d.epochs()
    where = {int(s): i for i, s in enumerate(first.grid)}
    t, counts, starts, ends = [], [], [], []
    for step, idx in epochs:
        p = pose[where[step]] if step in where else np.full(3, np.nan)
        if not np.isfinite(p).all():
            continue
        a = p[2] + d.meas_bearing[idx]
        t.append(d.t[step])
        counts.append(len(idx))
        starts.append(np.repeat(p[None, :2], len(idx), axis=0))
        ends.append(p[:2] + length * np.stack([np.cos(a), np.sin(a)], axis=1))
    if not t:
        return np.zeros(0), np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2))
    return np.array(t), np.array(counts), np.concatenate(starts), np.concatenate(ends)


def _pending(first: RunResult, attempts: list) -> tuple[np.ndarray, np.ndarray]:
    """Sigma images of the initialisation tries, grouped per step: times and ``(S, P, 2)``."""
    by_step: dict[int, list[np.ndarray]] = {}
    for step, _lm, points, _ok in attempts:
        by_step.setdefault(int(step), []).append(points)
    steps = sorted(by_step)
    width = max((sum(len(p) for p in by_step[s]) for s in steps), default=0)
    xy = np.full((len(steps), width, 2), np.nan)
    for i, s in enumerate(steps):
        pts = np.concatenate(by_step[s])
        xy[i, :len(pts)] = pts
    return first.data.t[np.array(steps, int)] if steps else np.zeros(0), xy


def record(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log run 0 in full (``runs[0]`` is its evaluation), the Monte Carlo curves over all
    runs, and the results table."""
    d, grid = first.data, first.grid
    zero = runs[0]
    t = d.t[grid]
    truth = d.truth[grid]
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    if d.walls is not None:
        rec.log("/world/walls", rr.LineStrips3D([np.c_[d.walls, np.zeros(len(d.walls))]],
                                                colors=[(120, 120, 120)], radii=[0.1]), static=True)
    rec.log("/world/landmarks", rr.Points3D(np.c_[d.landmarks, np.zeros(len(d.landmarks))],
                                            colors=[draw.color("truth")], radii=[0.25],
                                            labels=[str(i) for i in d.landmark_ids], show_labels=False),
            static=True)
    draw.track(rec, "/world/truth/path", truth[:, :2], draw.color("truth"), 0.06)
    draw.poses(rec, "/world/truth/vehicle", TL, t, truth, draw.color("truth"))
    ray_len = float(min(d.max_range, 30.0)) if np.isfinite(d.max_range) else 10.0
    band1 = metrics.chi2_band(3, 1)
    for name, est in first.estimates.items():
        rgb, x = first.estimators[name].color, draw.emphasis(first.estimators[name])
        base, w = f"/map/{name}", 1.5 * x
        pose, cov = on_grid(est, grid)
        draw.track(rec, f"{base}/path", pose[:, :2], rgb, 0.08 * x)
        draw.poses(rec, f"{base}/vehicle", TL, t, pose, rgb)
        draw.covariance_ellipses(rec, f"{base}/pose_ellipse", TL, t, pose[:, :2], cov[:, :2, :2], rgb)
        if len(est.map_steps):
            draw.point_sets(rec, f"{base}/landmarks", TL, d.t[est.map_steps], est.map_mean, rgb, 0.35, 0.05)
            if est.map_cov is not None:
                draw.ellipse_sets(rec, f"{base}/landmark_ellipses", TL, d.t[est.map_steps], est.map_mean,
                                  est.map_cov, rgb)
        rt, counts, starts, ends = _rays(first, pose, ray_len)
        if len(rt):
            draw.segment_sets(rec, f"{base}/rays", TL, rt, counts, starts, ends, (255, 255, 120), 0.03)
        if est.attempts:
            pt, clouds = _pending(first, est.attempts)
            draw.point_sets(rec, f"{base}/pending", TL, pt, clouds, (255, 140, 0), 0.12, 0.1)
        e, s = zero.errors[name], zero.sigmas[name]
        draw.scalars(rec, f"/errors/position/{name}", TL, t, np.hypot(e[:, 0], e[:, 1]), name, rgb, w)
        draw.scalars(rec, f"/errors/heading/{name}", TL, t, np.degrees(e[:, 2]), name, rgb, w)
        draw.scalars(rec, f"/sigma/position/{name}", TL, t, np.hypot(s[:, 0], s[:, 1]), name, rgb, w)
        draw.scalars(rec, f"/sigma/heading/{name}", TL, t, np.degrees(s[:, 2]), name, rgb, w)
        draw.scalars(rec, f"/nees/{name}", TL, t, zero.nees[name], name, rgb, w)
    grey = (150, 150, 150)
    draw.scalars(rec, "/nees/band_lo", TL, t, np.full_like(t, band1[0]), "95 % low", grey, 1.0)
    draw.scalars(rec, "/nees/band_hi", TL, t, np.full_like(t, band1[1]), "95 % high", grey, 1.0)

    curves = mc_curves(runs)
    mt = runs[0].t
    for name, c in curves.items():
        rgb, w = first.estimators[name].color, 1.5 * draw.emphasis(first.estimators[name])
        draw.scalars(rec, f"/monte_carlo/position/{name}", TL, mt, c["position"], name, rgb, w)
        draw.scalars(rec, f"/monte_carlo/heading/{name}", TL, mt, c["heading"], name, rgb, w)
        draw.scalars(rec, f"/monte_carlo/nees/{name}", TL, mt, c["nees"], name, rgb, w)
    lo, hi = metrics.chi2_band(3, len(runs))
    draw.scalars(rec, "/monte_carlo/nees/band_lo", TL, mt, np.full_like(mt, lo), "95 % low", grey, 1.0)
    draw.scalars(rec, "/monte_carlo/nees/band_hi", TL, mt, np.full_like(mt, hi), "95 % high", grey, 1.0)
    if first.images is not None and first.images.frames:
        _images(rec, first)
    rec.log("/summary", rr.TextDocument(table_md, media_type=rr.MediaType.MARKDOWN), static=True)


def _images(rec: rr.RecordingStream, first: RunResult) -> None:
    """The round images (JPEG, the sample the stage kept) with the detected lines drawn as rays."""
    frames = first.images.frames
    t = first.data.t[np.array([s for s, _, _ in frames], int)]
    size = frames[0][1].shape[0]
    blobs = [cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 85])[1].tobytes() for _, img, _ in frames]
    rec.send_columns("/camera/round", indexes=[draw.times(TL, t)],
                     columns=rr.EncodedImage.columns(blob=blobs, media_type=["image/jpeg"] * len(blobs)))
    c = (size - 1) / 2
    strips, counts = [], []
    for _, _, found in frames:
        for a in found:
            strips.append([[c, c], [c + 0.5 * size * np.cos(a), c - 0.5 * size * np.sin(a)]])
        counts.append(len(found))
    for step, reason in first.images.stats["bad_frames"]:
        rec.set_time(TL, duration=float(first.data.t[step]))
        rec.log("/camera/status", rr.TextLog(f"frame refused: {reason}; the estimators coast",
                                             level=rr.TextLogLevel.WARN))
    rec.reset_time()
    rec.log("/camera/detections", rr.LineStrips2D.from_fields(colors=[(80, 255, 80)], radii=[0.6]), static=True)
    rec.send_columns("/camera/detections", indexes=[draw.times(TL, t)],
                     columns=rr.LineStrips2D.columns(strips=strips).partition(counts))
