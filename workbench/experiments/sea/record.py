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
from workbench.experiments.sea import metrics as sea_metrics
from workbench.experiments.sea.evaluate import RunSummary, bound_variances
from workbench.experiments.sea.run import RunResult
from workbench.metrics import curves as metric_plots
from workbench.metrics import truthfree
from workbench.recording import draw
from workbench.recording import layout as views

TL = "time"
SERIES = {"truth": (draw.color("truth on white"), 1.5), "measured": (draw.color("measured"), 1.0),
          "bound_filtering": ((110, 110, 110), 2.0), "bound_smoothing": ((40, 40, 40), 2.0)}
"""(the Cramér-Rao bounds' curves: a filter's light grey, a smoother's dark)"""
"""What is not an estimator in the plots (colour, width); the bands are grey."""


def plots(first: RunResult, runs: list[RunSummary]) -> dict[str, views.Curves]:
    """Every time plot's curves, by view origin: the angles and range (truth, measured and each
    estimator), run 0's errors, and the RMSE and NEES over runs (with the 95 % band). The
    blueprint's axes and legends and the drawn series both come from these."""
    d, zero = first.data, runs[0]
    t = d.t
    series = {"alpha": {"truth": to_arcmin(d.alpha), "measured": to_arcmin(d.alpha_meas)},
              "beta": {"truth": to_arcmin(d.beta), "measured": to_arcmin(d.beta_meas)},
              "range": {"truth": d.range}}
    for name, est in first.estimates.items():
        series["alpha"][name], series["beta"][name] = to_arcmin(est.alpha), to_arcmin(est.beta)
        series["range"][name] = est.range
    e = zero.errors
    out = {"/series/alpha": views.Curves(t, series["alpha"], "arcmin"),
           "/series/beta": views.Curves(t, series["beta"], "arcmin"),
           "/series/range": views.Curves(t, series["range"], "m"),
           "/errors/position": views.Curves(t, {n: np.hypot(v[:, 0], v[:, 1]) for n, v in e.items()}, "m"),
           "/errors/x": views.Curves(t, {n: v[:, 0] for n, v in e.items()}, "m"),
           "/errors/y": views.Curves(t, {n: v[:, 1] for n, v in e.items()}, "m"),
           "/errors/alpha": views.Curves(t, {n: to_arcmin(v[:, 2]) for n, v in e.items()}, "arcmin"),
           "/errors/beta": views.Curves(t, {n: to_arcmin(v[:, 3]) for n, v in e.items()}, "arcmin")}
    known = metric_plots.by_name(first.metrics)
    rmse = metric_plots.over_runs(known["position_rmse"], runs) or views.Curves(t, {}, "m")
    for key, delay in (("bound_filtering", 0.0), ("bound_smoothing", float("inf"))):
        V = bound_variances(runs, delay)
        if V is not None:
            rmse.series[key] = np.sqrt(V["position"].mean(axis=0))
            rmse.fixed += (key,)
            rmse.labels[key] = f"Cramér-Rao, {key[6:]}"
    out["/monte_carlo/position_rmse"] = rmse
    nees = metric_plots.over_runs(known["anees"], runs)
    if nees is not None:  # the band's keys as the recording has always named them
        nees.series["bound_lo"], nees.series["bound_hi"] = nees.series.pop("band_lo"), nees.series.pop("band_hi")
        nees.fixed, nees.labels = ("bound_lo", "bound_hi"), {"bound_lo": "95 % low", "bound_hi": "95 % high"}
    out["/monte_carlo/nees"] = nees if nees is not None else views.Curves(t, {})
    return out | metric_plots.extra(first.metrics, runs, sea_metrics.CURVES)


def blueprint(curves: dict[str, views.Curves], images: bool = False, span: tuple[float, float] = (0.0, 72.0),
              scene: np.ndarray | None = None, extra: rrb.Vertical | None = None,
              reference: str | None = None, stats: dict | None = None,
              groups: dict[str, list[str]] | None = None) -> rrb.Blueprint:
    """The top-down map on the left (framed on ``scene``, the observer's and the object's
    tracks); named tabs of angles and range, errors, the curves over runs and the results on
    the right; every plot opens on the whole run ``span``, its axis and legend fitted to its
    ``curves``; ``extra``: the "metrics" tab. The legend is in the first plot of each tab: the colours are the
    same below it. ``stats``: the metrics, whose failed NEES verdicts the NEES view names.
    ``groups`` (many estimators, :func:`.plots.groups`): run 0's errors as small multiples, a plot
    per group on one axis, position in one tab and the angles in another; else the four
    components of Table 2 in one tab, every estimator in each plot."""

    def plot(origin: str, name: str, legend: bool = True) -> rrb.TimeSeriesView:
        return views.plot(origin, name, span, curves.get(origin), legend=legend)

    series = rrb.Vertical(
        plot("/series/alpha", "azimuth alpha (arcmin)"),
        plot("/series/beta", "elevation beta (arcmin)", legend=False),
        plot("/series/range", "range d (m)", legend=False),
        name="angles and range", row_shares=[1.6, 1, 1],  # (the legend of every series needs the height)
    )
    what = "error" if reference is None else f"departure from {reference},"  # (no truth: the smoother)
    one = "run 0" if reference is None else f"from {reference}, run 0"
    if groups:
        def small(origin: str, title: str, legend: bool = True) -> list[rrb.TimeSeriesView]:
            return views.grouped(origin, title, span, curves.get(origin), groups, legend)

        head = "position error (m)" if reference is None else f"departure from {reference} (m)"
        errors = [rrb.Vertical(*small("/errors/position", head),
                               name=f"{'errors' if reference is None else 'departures'} ({one})"),
                  rrb.Horizontal(rrb.Vertical(*small("/errors/alpha", "alpha (')"), name="alpha"),
                                 rrb.Vertical(*small("/errors/beta", "beta (')", legend=False), name="beta"),
                                 name=f"angle {'errors' if reference is None else 'departures'} ({one})")]
    else:
        errors = [rrb.Vertical(
            plot("/errors/x", f"{what} x (m)"),
            plot("/errors/y", f"{what} y (m)", legend=False),
            plot("/errors/alpha", f"{what} alpha (arcmin)", legend=False),
            plot("/errors/beta", f"{what} beta (arcmin)", legend=False),
            name="errors (run 0)" if reference is None else f"departure from {reference} (run 0)",
        )]
    mc = rrb.Vertical(
        plot("/monte_carlo/position_rmse", "position RMSE over runs (m), grey: Cramér-Rao bounds"),
        plot("/monte_carlo/nees", metric_plots.flagged("NEES over runs (4 states), grey: 95 % band", stats, True)),
        name="over runs",
    )
    tabs = [series, *errors, *([mc] if reference is None else []),  # (no truth: nothing to draw over runs)
            *([extra] if extra is not None else []), rrb.TextDocumentView(origin="/summary", name="results")]
    scene = np.zeros((1, 2)) if scene is None else scene
    left: rrb.Container | rrb.SpaceView = views.top_down("/map", "map (top-down, m)", scene, margin=1.3)
    if images:
        left = rrb.Vertical(
            left,
            rrb.Spatial2DView(origin="/camera", name="camera (detections)"),
            row_shares=[1, 1], name="map and camera",
        )
        tabs.insert(len(tabs) - 1 - (extra is not None), rrb.Vertical(
            views.plot("/images/error", "image stage error (arcmin)", span),
            views.plot("/images/detected", "detected", span),
            rrb.TextLogView(origin="/camera/status", name="no detection"),
            name="image stage"))
    return rrb.Blueprint(
        rrb.Horizontal(left, rrb.Tabs(*tabs, name="plots"), column_shares=[3, 2]),
        collapse_panels=True,
    )


def layout(first: RunResult, runs: list[RunSummary], stats: dict | None = None) -> rrb.Blueprint:
    """The default layout of a run's recording; ``stats`` (once every run is in): the estimators
    that fail their consistency tests are named in the views' titles."""
    d = first.data
    span = (float(d.t[0]), float(d.t[-1]))
    curves = plots(first, runs)
    return blueprint(curves, images=first.images is not None, span=span, scene=scene(first),
                     extra=metric_plots.tab(curves, first.metrics, span, len(runs)), reference=runs[0].reference,
                     stats=stats, groups=metric_plots.groups(first.estimators,
                                                             [n for n in first.estimates if n != runs[0].reference]))


def scene(first: RunResult) -> np.ndarray:
    """What the map frames: the observer's and the object's tracks, and where each estimate
    mostly is (the box of its 5-95 % quantiles: a noisy fix's spread, not one that runs away)."""
    d = first.data
    boxes = [np.nanpercentile(e.position, [5, 95], axis=0) for e in first.estimates.values()
             if np.isfinite(e.position).any()]
    return np.concatenate([d.observer, d.target[:, :2], *boxes])


def record_run(rec: rr.RecordingStream, first: RunResult, zero: RunSummary) -> None:
    """Log run 0 in full (``zero`` is its evaluation): the map, the angles and range, its errors,
    the image stage; what the Monte Carlo runs add comes with :func:`record_runs`."""
    d = first.data
    t = d.t
    rec.log("/map", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    top = views.on_top(scene(first))
    # seen from above, what is higher is drawn on top: the truth, thin, over the line of sight over
    # the estimates, wider, so both show; widths in UI points, the same at any zoom (a 600 m scene
    # made 0.6 m lines 1 px wide)
    draw.track(rec, "/map/observer/path", d.observer, draw.color("observer"), -1.0, z=top)
    draw.moving_point(rec, "/map/observer/camera", TL, t, d.observer, draw.color("observer"), -5.0,
                      "camera", z=top)
    draw.track(rec, "/map/truth/path", d.target[:, :2], draw.color("truth"), -0.6, z=top)
    draw.moving_point(rec, "/map/truth/position", TL, t, d.target[:, :2], draw.color("truth"), -5.0,
                      "object", z=top)
    seen = np.where(d.seen[:, None], d.target[:, :2], np.nan)
    draw.segments(rec, "/map/line_of_sight", TL, t, d.observer, seen, (255, 255, 120), -0.75, z=top / 2)

    for name, est in first.estimates.items():
        rgb, x = first.estimators[name].color, draw.emphasis(first.estimators[name])
        base = f"/map/{name}"
        draw.track(rec, f"{base}/track", est.position, rgb, -1.0 * x)
        draw.moving_point(rec, f"{base}/position", TL, t, est.position, rgb, -4.0 * x, name)
        if est.covariance is not None:
            draw.covariance_ellipses(rec, f"{base}/ellipse", TL, t, est.position, est.covariance, rgb)
        if est.forecast is not None:
            draw.polylines(rec, f"{base}/forecast", TL, t, est.forecast, rgb, -0.75 * x)
    metric_plots.draw_curves(rec, plots(first, [zero]), first.estimators, False, SERIES, TL)
    if first.images is not None:
        record_images(rec, first)


def record_runs(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log the curves over all runs and the results table with how to read the recording."""
    metric_plots.draw_curves(rec, plots(first, runs), first.estimators, True, SERIES, TL)
    metric_plots.summary(rec, table_md + "\n\n" + how_to_read(first, len(runs)))


def how_to_read(first: RunResult, runs: int) -> str:
    """The note under the results table: what each view shows and how to read it."""
    lo, hi = metrics.chi2_band(4, runs)
    if not np.isfinite(first.data.target).any():  # a log without truth
        ref = truthfree.smoother(first.estimators, first.estimates)
        return "\n".join([
            *metric_plots.how_to_read(first, "measured angles grey"),
            "- map, top-down (x east, y north, m): the observer's path and camera (blue), the line of sight "
            "(yellow, while the object is seen); each estimator's track, its current position, its 95 % covariance "
            "ellipse and its l-step forecast.",
            "- angles and range: azimuth alpha from the course and elevation beta below the horizon (arcmin), "
            "horizontal range d (m), for the measurements and each estimator.",
            f"- departure from {ref} (run 0): no truth, so the smoother ({ref}) minus each estimate in x, y (m) and "
            "the angles (arcmin): where a filter and the smoother part ways. The truth-free tests (NIS, whiteness, "
            "each causal estimator's disagreement with the smoother) are in the results' Consistency lines and, "
            "over runs, in the metrics tab; with no truth there are no errors over runs to draw.",
            "- a plot's title names an estimator that is off its scale (its own values would flatten the others); "
            "the legend is in the first plot of each tab, the colours are the same below it."])
    lines = [
        *metric_plots.how_to_read(first, "truth white on the map, black in the plots; measured angles grey"),
        "- map, top-down (x east, y north, m): the observer's path and camera (blue), the object (white), "
        "the line of sight (yellow, while the object is seen); each estimator's track, its current position, "
        "its 95 % covariance ellipse and its l-step forecast.",
        "- angles and range: azimuth alpha from the course and elevation beta below the horizon (arcmin), "
        "horizontal range d (m), for the truth, the measurements and each estimator.",
        "- errors (run 0): truth minus estimate in x, y (m) and the angles (arcmin); on a log without truth, "
        "the smoother minus each estimate instead (departure from it: where a filter and the smoother part ways).",
        f"- over runs ({runs} runs): the position RMSE at each step over the runs, with the Cramér-Rao bounds of a "
        "filter (light grey) and of a smoother of the whole run (dark grey): no estimator can be below the one it "
        "is held to for long (the results' efficiency is RMSE / bound); the NEES of the estimators with "
        f"a covariance, averaged over the runs, with its 95 % band ({lo:.2f}-{hi:.2f} for 4 states): inside it "
        "the covariance is consistent with the errors, above it the estimator is overconfident.",
        "- a plot's title names an estimator that is off its scale (its own values would flatten the others); "
        "the legend is in the first plot of each tab, the colours are the same below it.",
    ]
    return "\n".join(lines)


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
                         columns=rr.LineStrips2D.columns(strips=draw.strip_array(strips)))
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
