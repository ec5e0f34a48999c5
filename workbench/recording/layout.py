"""Blueprint pieces every experiment's default layout is made of, so they read at first sight:
time plots that open on the whole run with the legend in the corner where it hides the least
data, maps truly top-down over the whole scene, and a value axis that one diverging estimator
does not set for all the others.

A plot is declared with the curves it will show (:class:`Curves`: name -> values on the view's
time axis), so its value axis, its off-the-scale note and its legend's corner are computed from
the very numbers the recording draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import rerun.blueprint as rrb

MAP_BACKGROUND = (24, 28, 34)
"""The maps' background: the estimators' colours and the truth's near-white read on it."""
OFF_SCALE = 10.0
"""An estimator whose largest value is this many times the second least largest (with three or
more; of two, their median) is off the scale, whatever their number: with two drifting to 300 m
and two at 5 m, the axis fits the two at 5 m and names the others (the median of four set it at
300 m and flattened the good ones)."""
OFF_SCALE_GROUP = 4.0
"""In a group's plot (:func:`grouped`), a curve whose largest value is this many times the group's
least largest is off the scale: the axis fits the group's best (a filters' plot is about the EKF,
not the dead reckoning that drifts 20 times as far; the browser showed the good ones flat)."""
SPIKES = 0.99
"""A plot with a consistency band fits its axis to each curve's 99th percentile: a spike at a few
steps (an update that jumps) does not squeeze the band into a sliver; the spikes are named."""
LEGEND_BOX = (0.3, 0.45)
"""The part of a plot's width and height a legend of a handful of rows covers (measured in the web
viewer: 6-9 rows in plots 200-260 px high, the legend 120-190 px high and 90-110 px wide)."""
CORNERS = {rrb.Corner2D.RightTop: (1, 1), rrb.Corner2D.LeftTop: (0, 1), rrb.Corner2D.RightBottom: (1, 0),
           rrb.Corner2D.LeftBottom: (0, 0)}


@dataclass
class Curves:
    """What one time plot shows: ``t`` (s) and, by series name, its values on ``t``
    (``float`` arrays, NaN where there is none); ``unit`` for the off-the-scale note;
    ``fixed``: names that are reference lines (a consistency band), never off the scale;
    ``labels``: a series' name in the legend where it is not its key (the key names the entity);
    ``points``: names drawn as points, not a line (events: a line between them would invent values)."""

    t: np.ndarray
    series: dict[str, np.ndarray] = field(default_factory=dict)
    unit: str = ""
    fixed: tuple[str, ...] = ()
    labels: dict[str, str] = field(default_factory=dict)
    points: tuple[str, ...] = ()

    def label(self, key: str) -> str:
        return self.labels.get(key, key)


def plot(origin: str, name: str, span: tuple[float, float], curves: Curves | None = None,
         legend: bool = True, timeline: str = "time", contents: list[str] | None = None,
         best: bool = False) -> rrb.TimeSeriesView:
    """A time plot opening on the whole run ``span`` (s). With ``curves``: a value axis that no
    diverging series sets (:func:`scale`; the ones left above it named in the view's title), and
    the legend in the corner where it hides the fewest points (:func:`legend_corner`); without,
    the viewer's own axis and the legend at the top right. ``legend=False`` hides it (a plot
    below another that already names the same colours); ``contents``: the entities it shows
    (default: everything under ``origin``); ``best``: the axis fits the best curves
    (:data:`OFF_SCALE_GROUP`), those above it named briefly (a small multiple's narrow title)."""
    axis_y, corner, title = None, rrb.Corner2D.RightTop, name
    if curves is not None:
        top, off = scale({n: v for n, v in curves.series.items() if n not in curves.fixed}, best)
        values = [v for n, v in curves.series.items() if n not in off]
        shown = np.concatenate([np.ravel(v) for v in values]) if values else np.zeros(0)
        shown = shown[np.isfinite(shown)]
        spikes = ""
        if curves.fixed:
            top, spikes = band_top(curves, off, top)
        if top is not None:
            bottom = min(0.0, float(shown.min())) if shown.size else 0.0
            axis_y = rrb.ScalarAxis(range=(bottom, top), zoom_lock=False)
        title = name + (f"; above: {', '.join(off)}" if best and off else off_scale_note(off, curves.unit)) + spikes
        corner = legend_corner(curves.t, list(curves.series.values()), span, top)
    view_range = rrb.TimeRange(start=rrb.TimeRangeBoundary.absolute(seconds=float(span[0])),
                               end=rrb.TimeRangeBoundary.absolute(seconds=float(span[1])))
    kw = {"contents": contents} if contents is not None else {}
    return rrb.TimeSeriesView(origin=origin, name=title, axis_x=rrb.TimeAxis(view_range=view_range), **kw,
                              axis_y=axis_y, plot_legend=rrb.PlotLegend(corner=corner, visible=legend))


def grouped(origin: str, name: str, span: tuple[float, float], curves: Curves | None,
            groups: dict[str, list[str]], legend: bool = True) -> list[rrb.TimeSeriesView]:
    """Small multiples of one plot: a view per group of series (``groups``: the group's title ->
    its keys), each showing only its own curves and the ``fixed`` ones (a band), titled
    ``"<name>: <group>"``, with its own value axis (:func:`plot`: a group of filters is not
    flattened by the noisier point estimates' axis; the tick labels compare the groups) and its own
    legend (a handful of rows: never cut; ``legend=False``: none, beside views that have it). Keys
    of no group are not shown; an empty group gets no view."""
    out = []
    for g, keys in groups.items():
        keys = [k for k in keys if curves is None or k in curves.series]
        if not keys:
            continue
        mine = None
        if curves is not None:
            shown = [*keys, *[k for k in curves.fixed if k in curves.series]]
            mine = Curves(curves.t, {k: curves.series[k] for k in shown}, curves.unit, curves.fixed,
                          curves.labels, curves.points)
        out.append(plot(origin, f"{name}: {g}", span, mine, legend=legend, best=True,
                        contents=[f"$origin/{k}" for k in (mine.series if mine is not None else keys)]))
    return out


def band_top(curves: Curves, off: dict[str, float], top: float | None) -> tuple[float | None, str]:
    """A banded plot's axis top where a curve spikes (reaches over twice what its ``SPIKES``
    quantiles say): 1.1 times the largest such quantile of the curves shown (not ``off`` the
    scale), at least 1.5 times the band's top, no higher than ``top``; and a note naming the curves
    that spike (their largest value). Without a spike, ``top`` as it was and no note."""
    band = [float(np.nanmax(curves.series[n])) for n in curves.fixed if np.isfinite(curves.series[n]).any()]
    shown = {n: np.asarray(v, float)[np.isfinite(v)] for n, v in curves.series.items()
             if n not in off and n not in curves.fixed}
    shown = {n: v for n, v in shown.items() if v.size}
    if not band or not shown:
        return top, ""
    robust = max(1.1 * max(float(np.quantile(v, SPIKES)) for v in shown.values()), 1.5 * max(band))
    if top is not None and top <= robust:
        return top, ""
    above = {n: float(v.max()) for n, v in shown.items() if v.max() > 2.0 * robust}
    if not above:
        return top, ""
    return robust, "".join(f"; {curves.label(n)} spikes to {p:.3g}" for n, p in above.items())


def legend_corner(t: np.ndarray, values: list[np.ndarray], span: tuple[float, float],
                  top: float | None = None) -> rrb.Corner2D:
    """The corner whose legend-sized box (:data:`LEGEND_BOX`) holds the fewest points of the
    curves as the plot shows them (time over ``span``, values from their least to ``top`` or their
    largest); ties go to the top right, then the top left."""
    t = np.asarray(t, float)
    pts = [(t, np.asarray(v, float)) for v in values if np.shape(v) == t.shape]
    if not pts:
        return rrb.Corner2D.RightTop
    x = np.concatenate([(a - span[0]) / max(span[1] - span[0], 1e-12) for a, _ in pts])
    y = np.concatenate([v for _, v in pts])
    ok = np.isfinite(x) & np.isfinite(y) & (x >= 0) & (x <= 1)
    x, y = x[ok], y[ok]
    if not len(y):
        return rrb.Corner2D.RightTop
    lo, hi = float(y.min()), float(top if top is not None else y.max())
    y = (y - lo) / max(hi - lo, 1e-12)
    w, h = LEGEND_BOX
    counts = {}
    for corner, (right, upper) in CORNERS.items():
        in_x = x >= 1 - w if right else x <= w
        in_y = (y >= 1 - h) & (y <= 1) if upper else y <= h
        counts[corner] = int(np.count_nonzero(in_x & in_y))
    return min(CORNERS, key=lambda c: (counts[c], list(CORNERS).index(c)))


def top_down(origin: str, name: str, xy: np.ndarray, contents: list[str] | None = None, margin: float = 1.15,
             aspect: float = 1.0) -> rrb.Spatial3DView:
    """A 3D view looking straight down (x east to the right, y north up) on everything in
    ``xy (N, 2)``, north up: the eye straight above the centre with its up along +y (with up
    along +z, ill-defined looking straight down, the web viewer showed north at the bottom),
    at the height that frames the scene with ``margin`` in a view ``aspect`` times as wide as
    high (:func:`_frame`)."""
    centre, height = _frame(xy, margin, aspect)
    kw = {"contents": contents} if contents is not None else {}
    return rrb.Spatial3DView(
        origin=origin, name=name, background=MAP_BACKGROUND, **kw,
        eye_controls=rrb.EyeControls3D(position=(float(centre[0]), float(centre[1]) - 1e-3, height),
                                       look_target=(float(centre[0]), float(centre[1]), 0.0), eye_up=(0.0, 1.0, 0.0)))


VISIBLE_HEIGHT = 1.02
"""The ground height a 3D view shows, per metre of the eye's height over it (its vertical field of
view is fixed; measured in the web viewer: a 100 m square framed from 143 m filled 615 of 906 px and
301 of 440 px of two views of different widths)."""


def _frame(xy: np.ndarray, margin: float = 1.15, aspect: float = 1.0) -> tuple[np.ndarray, float]:
    """The centre of the points ``xy (N, 2)`` and the eye height that shows all of them, with
    ``margin``, in a view ``aspect`` times as wide as high (an aspect under the view's own only
    leaves more room at the sides)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    xy = xy[np.isfinite(xy).all(axis=1)]
    lo, hi = (xy.min(axis=0), xy.max(axis=0)) if len(xy) else (np.zeros(2), np.ones(2))
    extent = max(float(hi[0] - lo[0]) / aspect, float(hi[1] - lo[1]), 1.0)
    return (lo + hi) / 2, margin * extent / VISIBLE_HEIGHT


def on_top(xy: np.ndarray) -> float:
    """The height at which to draw what must show over the rest of a top-down map of ``xy``
    (the truth over the estimates): 2 % of the eye's height. The viewer draws the higher of two
    overlapping lines on top only from about that much (measured in a browser: at 0.1 % the lower
    line still covered the higher); the perspective shifts it by 2 % of its distance from the
    centre, under a line's width at the framing of :func:`top_down`."""
    return 0.02 * _frame(xy)[1]


def scale(series: dict[str, np.ndarray], best: bool = False) -> tuple[float | None, dict[str, float]]:
    """A value axis top for curves ``name -> values`` that no diverging one sets: 1.1 times the
    largest value among those whose largest is within ``OFF_SCALE`` times the second least largest
    (``best``: within ``OFF_SCALE_GROUP`` times the least largest); and the ones left above it,
    with their largest. ``(None, {})`` when none diverges."""
    peaks = {n: float(np.nanmax(np.abs(v))) for n, v in series.items() if np.isfinite(v).any()}
    if len(peaks) < 2:
        return None, {}
    if best:
        least = min(peaks.values())
        off = {n: p for n, p in peaks.items() if p > OFF_SCALE_GROUP * max(least, 1e-12)}
    else:  # three or more: the second least largest (one far better curve does not set it); two: their median
        ranked = sorted(peaks.values())
        ref = ranked[1] if len(ranked) >= 3 else float(np.median(ranked))
        off = {n: p for n, p in peaks.items() if p > OFF_SCALE * max(ref, 1e-12)}
    if not off:
        return None, {}
    return 1.1 * max(p for n, p in peaks.items() if n not in off), off


def off_scale_note(off: dict[str, float], unit: str) -> str:
    """``"; ekf-paper off the scale, up to 3088 m"`` for a view's name."""
    return "".join(f"; {n} off the scale, up to {p:.3g} {unit}".rstrip() for n, p in off.items())
