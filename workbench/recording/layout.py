"""Blueprint pieces every experiment's default layout is made of, so they read at first sight:
time plots that open on the whole run with the legend in a corner, maps truly top-down over
the whole scene, and an axis that one diverging estimator does not set for all the others."""

from __future__ import annotations

import numpy as np
import rerun.blueprint as rrb

MAP_BACKGROUND = (24, 28, 34)
"""The maps' background: the estimators' colours and the truth's near-white read on it."""
OFF_SCALE = 10.0
"""An estimator whose largest value is this many times the others' median largest is off the scale."""


def plot(origin: str, name: str, span: tuple[float, float], timeline: str = "time",
         top: float | None = None, bottom: float | None = None) -> rrb.TimeSeriesView:
    """A time plot opening on the whole run ``span`` (s), the legend at the top right; with
    ``top``/``bottom`` its value axis starts at that range (the user can still zoom out)."""
    axis_y = None
    if top is not None:
        axis_y = rrb.ScalarAxis(range=(bottom if bottom is not None else 0.0, top), zoom_lock=False)
    view_range = rrb.TimeRange(start=rrb.TimeRangeBoundary.absolute(seconds=float(span[0])),
                               end=rrb.TimeRangeBoundary.absolute(seconds=float(span[1])))
    return rrb.TimeSeriesView(origin=origin, name=name, axis_x=rrb.TimeAxis(view_range=view_range),
                              axis_y=axis_y, plot_legend=rrb.PlotLegend(corner=rrb.Corner2D.RightTop))


def top_down(origin: str, name: str, xy: np.ndarray, contents: list[str] | None = None, margin: float = 1.25
             ) -> rrb.Spatial3DView:
    """A 3D view looking straight down (x east to the right, y north up) on everything in
    ``xy (N, 2)``, north up: the eye straight above the centre with its up along +y (with up
    along +z, ill-defined looking straight down, the web viewer showed north at the bottom)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    lo, hi = (xy.min(axis=0), xy.max(axis=0)) if len(xy) else (np.zeros(2), np.ones(2))
    centre = (lo + hi) / 2
    # the viewer's field of view sees about 0.7 times the height across (measured in a browser
    # on a 900 x 730 px view): frame the larger side with a margin
    height = margin * max(float(np.max(hi - lo)), 1.0) / 0.7
    kw = {"contents": contents} if contents is not None else {}
    return rrb.Spatial3DView(
        origin=origin, name=name, background=MAP_BACKGROUND, **kw,
        eye_controls=rrb.EyeControls3D(position=(float(centre[0]), float(centre[1]) - 1e-3, height),
                                       look_target=(float(centre[0]), float(centre[1]), 0.0), eye_up=(0.0, 1.0, 0.0)))


def scale(series: dict[str, np.ndarray]) -> tuple[float | None, dict[str, float]]:
    """A value axis top for curves ``name -> values`` that no diverging one sets: 1.1 times the
    largest value among those whose largest is within ``OFF_SCALE`` times the median largest;
    and the ones left above it, with their largest. ``(None, {})`` when none diverges."""
    peaks = {n: float(np.nanmax(np.abs(v))) for n, v in series.items() if np.isfinite(v).any()}
    if len(peaks) < 2:
        return None, {}
    median = float(np.median(list(peaks.values())))
    off = {n: p for n, p in peaks.items() if p > OFF_SCALE * max(median, 1e-12)}
    if not off:
        return None, {}
    return 1.1 * max(p for n, p in peaks.items() if n not in off), off


def off_scale_note(off: dict[str, float], unit: str) -> str:
    """``"; ekf-paper off the scale, up to 3088 m"`` for a view's name."""
    return "".join(f"; {n} off the scale, up to {p:.3g} {unit}" for n, p in off.items())
