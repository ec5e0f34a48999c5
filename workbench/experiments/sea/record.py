"""The sea recording: map, angles, range and errors for every estimator, side by side.

Entity layout (timeline ``time``, seconds of the recorded run):

* ``map/observer`` (true path, current camera), ``map/truth`` (object), ``map/line_of_sight``,
  ``map/<estimator>/{track,position,ellipse,forecast}``;
* ``series/{alpha,beta,range}/<name>`` (truth, measured and each estimator; arcmin / m);
* ``errors/{x,y,alpha,beta}/<estimator>``;
* ``monte_carlo/position_rmse/<estimator>`` (RMSE over runs against time),
  ``monte_carlo/nees/ekf`` with ``monte_carlo/nees/bound_{lo,hi}``;
* ``summary`` (the results table as markdown);
* with ``--from-images``: ``camera/image`` (JPEG frames, every ``frame_stride`` steps),
  ``camera/horizon`` (the detected horizon), ``camera/object`` (the blob's box),
  ``camera/waterline`` (the detected point), ``camera/truth`` (the true target point
  projected), ``camera/gate`` (the tracking gate), ``camera/status`` (a text entry for each
  frame without a detection, with the reason), ``images/detected`` (1 / 0 per step) and
  ``images/error/{alpha,beta}`` (arcmin).
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.estimation import metrics
from workbench.estimation.angles import to_arcmin
from workbench.experiments.sea.evaluate import RunSummary, curves
from workbench.experiments.sea.run import RunResult
from workbench.recording import draw
from workbench.recording import layout as views

TL = "time"


def blueprint(names: list[str], images: bool = False, span: tuple[float, float] = (0.0, 72.0),
              scene: np.ndarray | None = None) -> rrb.Blueprint:
    """The top-down map on the left (framed on ``scene``, the observer's and the object's
    tracks); named tabs of angles and range, errors, the curves over runs and the results on
    the right; every plot opens on the whole run ``span``."""
    series = rrb.Vertical(
        views.plot("/series/alpha", "azimuth alpha (arcmin)", span),
        views.plot("/series/beta", "elevation beta (arcmin)", span),
        views.plot("/series/range", "range d (m)", span),
        name="angles and range",
    )
    errors = rrb.Vertical(
        views.plot("/errors/x", "error x (m)", span),
        views.plot("/errors/y", "error y (m)", span),
        views.plot("/errors/alpha", "error alpha (arcmin)", span),
        views.plot("/errors/beta", "error beta (arcmin)", span),
        name="errors (run 0)",
    )
    mc = rrb.Vertical(
        views.plot("/monte_carlo/position_rmse", "position RMSE over runs (m)", span),
        views.plot("/monte_carlo/nees", "NEES over runs (4 states), 95 % band", span),
        name="over runs",
    )
    tabs = [series, errors, mc, rrb.TextDocumentView(origin="/summary", name="results")]
    scene = np.zeros((1, 2)) if scene is None else scene
    left: rrb.Container | rrb.SpaceView = views.top_down("/map", "map (top-down, m)", scene)
    if images:
        left = rrb.Vertical(
            left,
            rrb.Spatial2DView(origin="/camera", name="camera (detections)"),
            row_shares=[1, 1],
        )
        tabs.insert(3, rrb.Vertical(
            views.plot("/images/error", "image stage error (arcmin)", span),
            views.plot("/images/detected", "detected", span),
            rrb.TextLogView(origin="/camera/status", name="no detection"),
            name="image stage"))
    return rrb.Blueprint(
        rrb.Horizontal(left, rrb.Tabs(*tabs), column_shares=[3, 2]),
        collapse_panels=True,
    )


def layout(first: RunResult) -> rrb.Blueprint:
    """The default layout of a run's recording."""
    d = first.data
    return blueprint(list(first.estimates), images=first.images is not None, span=(float(d.t[0]), float(d.t[-1])),
                     scene=np.concatenate([d.observer, d.target[:, :2]]))


def record(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log run 0 in full (``runs[0]`` is its evaluation), the Monte Carlo curves over all
    runs, and the results table."""
    d = first.data
    t = d.t
    rec.log("/map", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    draw.track(rec, "/map/observer/path", d.observer, draw.color("observer"))
    draw.moving_point(rec, "/map/observer/camera", TL, t, d.observer, draw.color("observer"), 4.0,
                      "camera")
    draw.track(rec, "/map/truth/path", d.target[:, :2], draw.color("truth"))
    draw.moving_point(rec, "/map/truth/position", TL, t, d.target[:, :2], draw.color("truth"), 4.0,
                      "object")
    seen = np.where(d.seen[:, None], d.target[:, :2], np.nan)
    draw.segments(rec, "/map/line_of_sight", TL, t, d.observer, seen, (255, 255, 120), 0.25)

    draw.scalars(rec, "/series/alpha/truth", TL, t, to_arcmin(d.alpha), "truth", draw.color("truth on white"))
    draw.scalars(rec, "/series/alpha/measured", TL, t, to_arcmin(d.alpha_meas), "measured",
                 draw.color("measured"), 1.0)
    draw.scalars(rec, "/series/beta/truth", TL, t, to_arcmin(d.beta), "truth", draw.color("truth on white"))
    draw.scalars(rec, "/series/beta/measured", TL, t, to_arcmin(d.beta_meas), "measured",
                 draw.color("measured"), 1.0)
    draw.scalars(rec, "/series/range/truth", TL, t, d.range, "truth", draw.color("truth on white"))

    for name, est in first.estimates.items():
        rgb, x = first.estimators[name].color, draw.emphasis(first.estimators[name])
        base, w = f"/map/{name}", 1.5 * x
        draw.track(rec, f"{base}/track", est.position, rgb, 0.5 * x)
        draw.moving_point(rec, f"{base}/position", TL, t, est.position, rgb, 3.0 * x, name)
        if est.covariance is not None:
            draw.covariance_ellipses(rec, f"{base}/ellipse", TL, t, est.position, est.covariance, rgb)
        if est.forecast is not None:
            draw.polylines(rec, f"{base}/forecast", TL, t, est.forecast, rgb, 0.5 * x)
        draw.scalars(rec, f"/series/alpha/{name}", TL, t, to_arcmin(est.alpha), name, rgb, w)
        draw.scalars(rec, f"/series/beta/{name}", TL, t, to_arcmin(est.beta), name, rgb, w)
        draw.scalars(rec, f"/series/range/{name}", TL, t, est.range, name, rgb, w)
        e = runs[0].errors[name]
        draw.scalars(rec, f"/errors/x/{name}", TL, t, e[:, 0], name, rgb, w)
        draw.scalars(rec, f"/errors/y/{name}", TL, t, e[:, 1], name, rgb, w)
        draw.scalars(rec, f"/errors/alpha/{name}", TL, t, to_arcmin(e[:, 2]), name, rgb, w)
        draw.scalars(rec, f"/errors/beta/{name}", TL, t, to_arcmin(e[:, 3]), name, rgb, w)

    for name, c in curves(runs).items():
        rgb, w = first.estimators[name].color, 1.5 * draw.emphasis(first.estimators[name])
        if "position_rmse" in c:
            draw.scalars(rec, f"/monte_carlo/position_rmse/{name}", TL, t, c["position_rmse"], name, rgb, w)
        if "nees" in c:
            draw.scalars(rec, f"/monte_carlo/nees/{name}", TL, t, c["nees"], f"{name} ANEES", rgb, w)
    if runs[0].nees:
        lo, hi = metrics.chi2_band(4, len(runs))
        draw.scalars(rec, "/monte_carlo/nees/bound_lo", TL, t, np.full_like(t, lo), "95 % low",
                     (150, 150, 150), 1.0)
        draw.scalars(rec, "/monte_carlo/nees/bound_hi", TL, t, np.full_like(t, hi), "95 % high",
                     (150, 150, 150), 1.0)
    rec.log("/summary", rr.TextDocument(table_md, media_type=rr.MediaType.MARKDOWN), static=True)
    if first.images is not None:
        record_images(rec, first)


def record_images(rec: rr.RecordingStream, first: RunResult) -> None:
    """The image stage of run 0: frames with the detections over them, flags and errors."""
    st, d = first.images, first.data
    t = d.t
    s = st.frame_scale
    steps = st.frame_steps
    if len(steps):
        rec.send_columns("/camera/image", indexes=[draw.times(TL, t[steps])],
                         columns=rr.EncodedImage.columns(blob=st.frames, media_type=["image/jpeg"] * len(steps)))
    W = st.camera.width
    ok = np.isfinite(st.horizon).all(axis=1)
    ends = np.array([0.0, W - 1.0])
    if ok.any():
        v = st.horizon[ok, :1] + st.horizon[ok, 1:] * (ends[None, :] - st.camera.cx)
        strips = np.stack([np.broadcast_to(ends, v.shape), v], axis=-1) * s
        rec.log("/camera/horizon", rr.LineStrips2D.from_fields(colors=[(255, 220, 0)], radii=[1.0]), static=True)
        rec.send_columns("/camera/horizon", indexes=[draw.times(TL, t[ok])],
                         columns=rr.LineStrips2D.columns(strips=list(strips)))
    _boxes(rec, "/camera/object", t, st.box * s, (255, 60, 60), "object")
    _boxes(rec, "/camera/gate", t, st.gate * s, (120, 200, 255), None)
    for path, xy, rgb in (("/camera/waterline", st.pixel, (255, 60, 60)), ("/camera/truth", st.true_pixel,
                                                                          (230, 230, 230))):
        good = np.isfinite(xy).all(axis=1)
        rec.log(path, rr.Points2D.from_fields(colors=[rgb], radii=[2.0]), static=True)
        if good.any():
            rec.send_columns(path, indexes=[draw.times(TL, t[good])],
                             columns=rr.Points2D.columns(positions=xy[good] * s))
    missed = np.flatnonzero(~st.detected)
    if missed.size:
        texts = [st.reasons[k] or "no detection" for k in missed]
        # a miss where the object was in view is a warning; one where it was hidden or outside, information
        levels = ["WARN" if (k in st.bad or st.visible[k]) else "INFO" for k in missed]
        rec.send_columns("/camera/status", indexes=[draw.times(TL, t[missed])],
                         columns=rr.TextLog.columns(text=texts, level=levels))
    draw.scalars(rec, "/images/detected", TL, t, st.detected.astype(float), "detected", (60, 200, 90), 1.0)
    e = st.errors(d)
    draw.scalars(rec, "/images/error/alpha", TL, t, to_arcmin(e[:, 0]), "alpha", (255, 170, 0), 1.0)
    draw.scalars(rec, "/images/error/beta", TL, t, to_arcmin(e[:, 1]), "beta", (0, 210, 200), 1.0)


def _boxes(rec: rr.RecordingStream, path: str, t: np.ndarray, box: np.ndarray, rgb, label: str | None) -> None:
    good = np.isfinite(box).all(axis=1)
    rec.log(path, rr.Boxes2D.from_fields(colors=[rgb], radii=[1.0]), static=True)
    if good.any():
        b = box[good]
        rec.send_columns(path, indexes=[draw.times(TL, t[good])],
                         columns=rr.Boxes2D.columns(centers=(b[:, :2] + b[:, 2:]) / 2,
                                                    half_sizes=(b[:, 2:] - b[:, :2]) / 2 + 1.0))
