"""The sea recording: map, angles, range and errors for every estimator, side by side.

Entity layout (timeline ``time``, seconds of the recorded run):

* ``map/observer`` (true path, current camera), ``map/truth`` (object), ``map/line_of_sight``,
  ``map/<estimator>/{track,position,ellipse,forecast}``;
* ``series/{alpha,beta,range}/<name>`` (truth, measured and each estimator; arcmin / m);
* ``errors/{x,y,alpha,beta}/<estimator>``;
* ``monte_carlo/position_rmse/<estimator>`` (RMSE over runs against time),
  ``monte_carlo/nees/ekf`` with ``monte_carlo/nees/bound_{lo,hi}``;
* ``summary`` (the results table as markdown).
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.estimation import metrics
from workbench.estimation.angles import to_arcmin
from workbench.experiments.sea.run import RunResult, RunSummary
from workbench.recording import draw

TL = "time"


def blueprint(names: list[str]) -> rrb.Blueprint:
    """Map on the left; angles, range and errors on the right; Monte Carlo and table in tabs."""
    series = rrb.Vertical(
        rrb.TimeSeriesView(origin="/series/alpha", name="azimuth alpha (arcmin)"),
        rrb.TimeSeriesView(origin="/series/beta", name="elevation beta (arcmin)"),
        rrb.TimeSeriesView(origin="/series/range", name="range d (m)"),
    )
    errors = rrb.Vertical(
        rrb.TimeSeriesView(origin="/errors/x", name="error x (m)"),
        rrb.TimeSeriesView(origin="/errors/y", name="error y (m)"),
        rrb.TimeSeriesView(origin="/errors/alpha", name="error alpha (arcmin)"),
        rrb.TimeSeriesView(origin="/errors/beta", name="error beta (arcmin)"),
    )
    mc = rrb.Vertical(
        rrb.TimeSeriesView(origin="/monte_carlo/position_rmse", name="position RMSE over runs (m)"),
        rrb.TimeSeriesView(origin="/monte_carlo/nees", name="EKF NEES over runs, 95 % band"),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/map", name="map (top-down, m)"),
            rrb.Tabs(series, errors, mc, rrb.TextDocumentView(origin="/summary", name="results")),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def record(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log run 0 in full, the Monte Carlo curves over all runs, and the results table."""
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

    draw.scalars(rec, "/series/alpha/truth", TL, t, to_arcmin(d.alpha), "truth", draw.color("truth"))
    draw.scalars(rec, "/series/alpha/measured", TL, t, to_arcmin(d.alpha_meas), "measured",
                 draw.color("measured"), 1.0)
    draw.scalars(rec, "/series/beta/truth", TL, t, to_arcmin(d.beta), "truth", draw.color("truth"))
    draw.scalars(rec, "/series/beta/measured", TL, t, to_arcmin(d.beta_meas), "measured",
                 draw.color("measured"), 1.0)
    draw.scalars(rec, "/series/range/truth", TL, t, d.range, "truth", draw.color("truth"))

    for name, est in first.estimates.items():
        rgb = draw.color(name)
        base = f"/map/{name}"
        draw.track(rec, f"{base}/track", est.position, rgb, 0.5)
        draw.moving_point(rec, f"{base}/position", TL, t, est.position, rgb, 3.0, name)
        if est.covariance is not None:
            draw.covariance_ellipses(rec, f"{base}/ellipse", TL, t, est.position, est.covariance, rgb)
        if est.forecast is not None:
            draw.polylines(rec, f"{base}/forecast", TL, t, est.forecast, rgb, 0.5)
        draw.scalars(rec, f"/series/alpha/{name}", TL, t, to_arcmin(est.alpha), name, rgb)
        draw.scalars(rec, f"/series/beta/{name}", TL, t, to_arcmin(est.beta), name, rgb)
        draw.scalars(rec, f"/series/range/{name}", TL, t, est.range, name, rgb)
        e = first.errors[name]
        draw.scalars(rec, f"/errors/x/{name}", TL, t, e[:, 0], name, rgb)
        draw.scalars(rec, f"/errors/y/{name}", TL, t, e[:, 1], name, rgb)
        draw.scalars(rec, f"/errors/alpha/{name}", TL, t, to_arcmin(e[:, 2]), name, rgb)
        draw.scalars(rec, f"/errors/beta/{name}", TL, t, to_arcmin(e[:, 3]), name, rgb)

    for name in first.estimates:
        E = np.stack([r.errors[name][:, :2] for r in runs])
        with np.errstate(invalid="ignore"):
            curve = np.sqrt(np.nanmean(np.sum(E**2, axis=2), axis=0)) if np.isfinite(E).any() else None
        if curve is not None:
            draw.scalars(rec, f"/monte_carlo/position_rmse/{name}", TL, t, curve, name, draw.color(name))
    for name in runs[0].nees:
        N = np.nanmean(np.stack([r.nees[name] for r in runs]), axis=0)
        draw.scalars(rec, f"/monte_carlo/nees/{name}", TL, t, N, f"{name} ANEES", draw.color(name))
    if runs[0].nees:
        lo, hi = metrics.chi2_band(4, len(runs))
        draw.scalars(rec, "/monte_carlo/nees/bound_lo", TL, t, np.full_like(t, lo), "95 % low",
                     (150, 150, 150), 1.0)
        draw.scalars(rec, "/monte_carlo/nees/bound_hi", TL, t, np.full_like(t, hi), "95 % high",
                     (150, 150, 150), 1.0)
    rec.log("/summary", rr.TextDocument(table_md, media_type=rr.MediaType.MARKDOWN), static=True)
