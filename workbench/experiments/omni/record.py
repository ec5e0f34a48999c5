"""The omni recording: one top-down map per estimator side by side, and the curves.

Entity layout (timeline ``time``, seconds of the recorded run 0):

* ``world/{walls,landmarks}`` (static), ``world/truth/{path,vehicle}``;
* ``map/<estimator>/{path,vehicle,pose_ellipse,landmarks,landmark_ellipses,rays,gated}``
  (``gated``: the bearings its gate left out, red; ``path``: the pose it knew at each step),
  ``map/isam2/smoothed`` (its whole trajectory as held at the end, pale) and, for the filters,
  ``map/<estimator>/pending`` (the UT sigma images of each initialisation try);
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
from workbench.experiments.omni import metrics as omni_metrics
from workbench.experiments.omni.evaluate import RunSummary, on_grid, smoothed_on_grid
from workbench.experiments.omni.run import RunResult
from workbench.metrics import curves as metric_plots
from workbench.metrics import diagnosis, truthfree
from workbench.recording import draw
from workbench.recording import layout as views

TL = "time"
BOUNDS = {"bound_filtering": ((110, 110, 110), 2.0), "bound_smoothing": ((40, 40, 40), 2.0)}
"""The Cramér-Rao bounds' curves: a filter's light grey, a smoother's dark."""


def plots(first: RunResult, runs: list[RunSummary]) -> dict[str, views.Curves]:
    """Every time plot's curves, by view origin: run 0's errors, own sigmas and NEES (with the
    one-run 95 % band), the metrics' curves over runs (RMS position and heading errors with the
    Cramér-Rao bounds beside them, the ANEES with its band for that many runs) and the metrics
    of the "metrics" tab. The blueprint's axes and legends and the drawn series come from these."""
    zero = runs[0]
    t = zero.t
    one = metrics.chi2_band(3, 1)
    band = {"band_lo": "95 % low", "band_hi": "95 % high"}

    def curves(values: dict[str, np.ndarray], unit: str = "", lohi: tuple[float, float] | None = None
               ) -> views.Curves:
        c = views.Curves(t, dict(values), unit)
        if lohi is not None:
            c.series.update(band_lo=np.full_like(t, lohi[0]), band_hi=np.full_like(t, lohi[1]))
            c.fixed, c.labels = tuple(band), band
        return c

    e, s = zero.errors, zero.sigmas
    known = metric_plots.by_name(first.metrics)
    over = {origin: metric_plots.over_runs(known[name], runs) or views.Curves(t, {}, known[name].unit)
            for origin, name in DRAWN.items()}
    if runs[0].bounds:  # the Cramér-Rao bounds beside the RMS errors over runs
        for key, delay in (("bound_filtering", 0.0), ("bound_smoothing", float("inf"))):
            if delay in runs[0].bounds:
                V = {q: np.stack([r.bounds[delay][q] for r in runs]).mean(axis=0) for q in ("position", "heading")}
                for origin, values in (("/monte_carlo/position", np.sqrt(V["position"])),
                                       ("/monte_carlo/heading", np.degrees(np.sqrt(V["heading"])))):
                    c = over[origin]
                    c.series[key] = values
                    c.fixed += (key,)
                    c.labels[key] = f"Cramér-Rao, {key[6:]}"
    return _switch_curves(first.data) | {
        "/errors/position": curves({n: np.hypot(v[:, 0], v[:, 1]) for n, v in e.items()}, "m"),
        "/errors/heading": curves({n: np.degrees(v[:, 2]) for n, v in e.items()}, "deg"),
        "/nees": curves(dict(zero.nees), "", one),
        "/sigma/position": curves({n: np.hypot(v[:, 0], v[:, 1]) for n, v in s.items()}, "m"),
        "/sigma/heading": curves({n: np.degrees(v[:, 2]) for n, v in s.items()}, "deg"),
    } | over | metric_plots.extra(first.metrics, runs, omni_metrics.CURVES)


DRAWN = {"/monte_carlo/position": "position_rmse", "/monte_carlo/heading": "heading_rmse",
         "/monte_carlo/nees": "anees"}
"""The metrics the "over runs" tab draws, by view origin."""


SWITCH_SHOWN = 0.05
"""The smallest heading sigma (deg) of a step's unknown command switch the odometry plot shows."""


def _switch_curves(d) -> dict[str, views.Curves]:
    """A real log's odometry steps whose command switched at a time the log does not say
    (:func:`.real.between`): the heading sigma that adds over the step (deg), at the step's start,
    where it is at least ``SWITCH_SHOWN``; the estimators lean on the bearings there."""
    if d.control_var is None or np.ndim(d.control_var) != 2:  # (increments carry a covariance, no switch)
        return {}
    dt = np.diff(d.t)
    sigma = np.degrees(np.sqrt(d.control_var[:, 1]) * dt)
    shown = sigma >= SWITCH_SHOWN
    if not shown.any():
        return {}
    key = "switch_heading_sigma"
    return {"/odometry/switch": views.Curves(d.t[:-1][shown], {key: sigma[shown]}, "deg",
                                             labels={key: "heading sigma of the command's unknown switch"},
                                             points=(key,))}


def blueprint(names: list[str], scene: np.ndarray, curves: dict[str, views.Curves], with_images: bool = False,
              span: tuple[float, float] = (0.0, 500.0), extra: rrb.Vertical | None = None,
              reference: str | None = None, stats: dict | None = None,
              groups: dict[str, list[str]] | None = None) -> rrb.Blueprint:
    """Maps in a grid on the left, each top-down over ``scene`` (points, m), one per estimator
    (and the round camera image, when there is one); errors, sigmas, NEES and the Monte Carlo
    curves on the right in named tabs, every plot on the whole run ``span`` with its axis and
    legend fitted to its ``curves`` (one diverging estimator does not flatten the others); ``extra``:
    the "metrics" tab. The legend is in the first plot of each tab: the colours are the same below it.
    ``reference``: a log without truth, whose run-0 plots are each estimate's departure from this
    smoother and each causal one's disagreement with it; ``stats``: the metrics, whose failed
    consistency verdicts the NEES and disagreement views name, and each estimator's truth-free
    diagnosis its map's title ends with (:mod:`..diagnosis`); ``groups`` (many estimators,
    :func:`.plots.groups`): run 0's errors and sigmas as small multiples, a plot per group on one
    axis, and the NEES in a tab of its own."""

    def plot(origin: str, name: str, legend: bool = True) -> rrb.TimeSeriesView:
        return views.plot(origin, name, span, curves.get(origin), legend=legend)

    found = {n: e.get("diagnosis") for n, e in (stats or {}).get("estimators", {}).items()}
    panes = [views.top_down("/", f"{n} (top-down, m)" + (f": {diagnosis.line(found[n])}"
                                                         if found.get(n) else ""),
                            scene, contents=["/world/**", f"/map/{n}/**"])
             for n in names]
    if with_images:
        panes.insert(0, rrb.Spatial2DView(origin="/camera", name="round image, detected lines"))
    maps = rrb.Grid(*panes, name="maps")

    def pair(origins: tuple[str, str], titles: tuple[str, str], tab: str, below: list,
             apart: tuple[str, list] | None = None) -> list[rrb.Vertical]:
        """Position and heading (a plot each, or with ``groups`` small multiples of each, side by side) and the
        plots ``below`` them in the tab ``tab``; ``apart`` (a tab's name and its plots): with
        ``groups``, in a tab of their own, else below the others."""
        if groups:
            columns = [rrb.Vertical(*views.grouped(o, t, span, curves.get(o), groups, legend=i == 0),
                                    name=o.rsplit("/", 1)[1])
                       for i, (o, t) in enumerate(zip(origins, titles, strict=True))]
            mine = (rrb.Horizontal(*columns, name=tab) if not below else
                    rrb.Vertical(rrb.Horizontal(*columns, name="by group"), *below, row_shares=[3, *[1] * len(below)],
                                 name=tab))
            return [mine, *([rrb.Vertical(*apart[1], name=apart[0])] if apart else [])]
        return [rrb.Vertical(plot(origins[0], titles[0]), plot(origins[1], titles[1], legend=False), *below,
                             *(apart[1] if apart else []), name=tab)]

    if reference is None:
        nees = views.plot("/nees", metric_plots.flagged("pose NEES (3 dof), grey: 95 % band", stats, True), span,
                          curves.get("/nees"), legend=bool(groups))
        one_run = pair(("/errors/position", "/errors/heading"), ("position error (m)", "heading error (deg)"),
                       "errors (run 0)" if groups else "run 0", [], ("NEES (run 0)", [nees]))
    else:  # no truth: the smoother is the reference
        nees = views.plot("/nees", metric_plots.flagged(f"disagreement with {reference} (3 dof, grey band)",
                                                        stats, False), span, curves.get("/nees"), legend=bool(groups))
        one_run = pair(("/errors/position", "/errors/heading"),
                       (f"departure from {reference}, position (m)", f"departure from {reference}, heading (deg)"),
                       f"departure from {reference} (run 0)", [], (f"disagreement with {reference} (run 0)", [nees]))
    switch = ([plot("/odometry/switch", "odometry gaps: heading sigma of an unknown switch (deg)", legend=False)]
              if "/odometry/switch" in curves else [])
    sigmas = pair(("/sigma/position", "/sigma/heading"), ("own sigma, position (m)", "own sigma, heading (deg)"),
                  "own sigmas (run 0)", switch)
    mc = rrb.Vertical(
        plot("/monte_carlo/position", "RMS position error over runs (m), grey: Cramér-Rao bounds"),
        plot("/monte_carlo/heading", "RMS heading error over runs (deg)", legend=False),
        plot("/monte_carlo/nees", metric_plots.flagged("ANEES over runs, grey: 95 % band", stats, True),
             legend=False),
        name="over runs",
    )
    tabs = [*one_run, *sigmas, *([mc] if reference is None else [])]  # (no truth: nothing to draw over runs)
    tabs += [extra] if extra is not None else []
    return rrb.Blueprint(
        rrb.Horizontal(maps, rrb.Tabs(*tabs, rrb.TextDocumentView(origin="/summary", name="results"), name="plots"),
                       column_shares=[3, 2]),
        collapse_panels=True,
    )


def layout(first: RunResult, runs: list[RunSummary], stats: dict | None = None) -> rrb.Blueprint:
    """The default layout: maps framed on the walls (the simulation) or the landmarks (MRCLAM)
    and the true path; the plots fitted to their curves; the estimators that fail their
    consistency tests (``stats``, once every run is in) named in the views that show the tests."""
    span = (float(runs[0].t[0]), float(runs[0].t[-1]))
    curves = plots(first, runs)
    return blueprint(list(first.estimates), scene(first), curves, first.images is not None, span,
                     metric_plots.tab(curves, first.metrics, span, len(runs)), runs[0].reference, stats,
                     metric_plots.groups(first.estimators, [n for n in first.estimates if n != runs[0].reference]))


def scene(first: RunResult) -> np.ndarray:
    """What the maps frame: the walls (the simulation) or the landmarks (MRCLAM), and the true path;
    a log without its truth, the smoother's path (the reference), else the box of each estimate's
    5-95 % quantiles (a filter that runs away does not shrink every map to a dot; what is not
    finite left out)."""
    d = first.data
    parts = [d.walls if d.walls is not None else survey(first), d.truth[first.grid, :2]]
    if not np.isfinite(d.truth[first.grid]).any():  # the smoother's path, else each estimate's bulk
        ref = truthfree.smoother(first.estimators, first.estimates)
        if ref is not None:
            parts.append(first.estimates[ref].pose[:, :2])
        else:
            for e in first.estimates.values():
                xy = e.pose[:, :2][np.isfinite(e.pose[:, :2]).all(axis=1)]
                if len(xy):
                    parts.append(np.quantile(xy, [0.05, 0.95], axis=0))
    xy = np.concatenate(parts)
    xy = xy[np.isfinite(xy).all(axis=1)]
    return xy if len(xy) else np.zeros((1, 2))


def survey(first: RunResult) -> np.ndarray:
    """The landmarks' surveyed places as the maps draw them: as given, or, for a log without the
    robot's truth (its frame is the first pose's, not the survey's), moved onto the smoother's map
    by their best rigid alignment (as ``aligned_map_rmse`` scores it) so they sit where the
    estimates put them."""
    d = first.data
    if np.isfinite(d.truth[first.grid]).any():
        return d.landmarks
    ref = truthfree.smoother(first.estimators, first.estimates)
    if ref is None:
        return d.landmarks
    from workbench.estimation.alignment import umeyama

    mine = first.estimates[ref].final_map
    both = np.isfinite(mine).all(axis=1) & np.isfinite(d.landmarks).all(axis=1)
    if both.sum() < 3:
        return d.landmarks
    a = umeyama(d.landmarks[both], mine[both])
    return a.apply(np.column_stack([d.landmarks, np.zeros(len(d.landmarks))]))[:, :2]


def _rays(first: RunResult, pose: np.ndarray, length: float, only: np.ndarray | None = None
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Bearing rays drawn from an estimate's pose at each epoch: times, counts, starts, ends
    (``only``: just these bearings, the dataset's indices)."""
    d = first.data
    epochs = d.epochs()
    if only is not None:
        chosen = set(int(i) for i in only if i >= 0)
        epochs = [(s, np.array([i for i in idx if int(i) in chosen], int)) for s, idx in epochs]
        epochs = [(s, idx) for s, idx in epochs if len(idx)]
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


FAR_OFF = (255, 0, 200)
"""The colour of the landmarks far off the survey, labelled (:mod:`.survey`)."""
UNPLACED, CONTRADICTED = (255, 160, 0), (255, 40, 40)
"""The colours of the landmarks the data cannot place and of those their own bearings reject (:mod:`.placed`)."""


def _ring(rec: rr.RecordingStream, path: str, est, ids: np.ndarray, which: list[int], labels: list[str],
          colour: tuple[int, int, int], radius: float, height: float) -> None:
    """Landmarks ``which`` (ids) of a map ringed at their final estimate, labelled."""
    if not which:
        return
    index = {int(i): k for k, i in enumerate(ids)}
    xy = est.final_map[[index[i] for i in which]]
    rec.log(path, rr.Points3D(np.c_[xy, np.full(len(xy), height)], colors=[colour], radii=[radius], labels=labels,
                              show_labels=True), static=True)


def _far_off(rec: rr.RecordingStream, path: str, est, found: dict | None, ids: np.ndarray) -> None:
    """The landmarks of a map far off the survey, ringed and labelled: by id and error, and the
    pair the survey or the ids look to have swapped."""
    if not found:
        return
    partner = {a: b for a, b in found["swapped"]} | {b: a for a, b in found["swapped"]}
    labels = [f"id {i}: {found['errors'][str(i)]:.1f} m off"
              + (f", swapped with id {partner[i]}?" if i in partner else "") for i in found["far"]]
    _ring(rec, path, est, ids, found["far"], labels, FAR_OFF, 0.6, 0.2)


def _unplaced(rec: rr.RecordingStream, base: str, est, found: dict | None, ids: np.ndarray) -> None:
    """The landmarks of a map its data cannot place (:mod:`.placed`), ringed and labelled by id and
    their 95 % ellipse's reach over their range, and those its own bearings reject (``contradicted``,
    by the share that miss them), with no truth."""
    if found:
        _ring(rec, f"{base}/unplaced", est, ids, found["ids"],
              [f"id {i}: cannot place ({found['reach'][str(i)]:.1f}x)" for i in found["ids"]], UNPLACED, 0.5, 0.25)
        bad = found.get("contradicted") or []
        _ring(rec, f"{base}/contradicted", est, ids, bad,
              [f"id {i}: contradicted ({100 * found['missed'][str(i)]:.0f} %)" for i in bad], CONTRADICTED, 0.55, 0.3)


def record_run(rec: rr.RecordingStream, first: RunResult, zero: RunSummary) -> None:
    """Log run 0 in full (``zero`` is its evaluation): the maps, its errors, sigmas and NEES, the
    round images; what the Monte Carlo runs add comes with :func:`record_runs`."""
    d, grid = first.data, first.grid
    t = d.t[grid]
    truth = d.truth[grid]
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    if d.walls is not None:
        rec.log("/world/walls", rr.LineStrips3D([np.c_[d.walls, np.zeros(len(d.walls))]],
                                                colors=[(120, 120, 120)], radii=[0.1]), static=True)
    marks = survey(first)  # (a log without its truth: the survey aligned to the smoother's map)
    known = np.isfinite(marks).all(axis=1)  # (a log may not know where its landmarks are)
    rec.log("/world/landmarks", rr.Points3D(np.c_[marks[known], np.zeros(known.sum())],
                                            colors=[draw.color("truth")], radii=[0.25],
                                            labels=[str(i) for i in d.landmark_ids[known]], show_labels=False),
            static=True)
    # seen from above, what is higher is drawn on top: the truth, thin, over the estimate, wider
    top = views.on_top(scene(first))
    arrow = 0.03 * float(np.ptp(scene(first), axis=0).max())  # the vehicle: 3 % of the scene (2.4 m in 80 m)
    draw.track(rec, "/world/truth/path", truth[:, :2], draw.color("truth"), -0.6, z=top)
    draw.poses(rec, "/world/truth/vehicle", TL, t, truth, draw.color("truth"), arrow, z=top)
    ray_len = float(min(d.max_range, 30.0)) if np.isfinite(d.max_range) else 10.0
    for name, est in first.estimates.items():
        rgb, x = first.estimators[name].color, draw.emphasis(first.estimators[name])
        base = f"/map/{name}"
        pose, cov = on_grid(est, grid)
        draw.track(rec, f"{base}/path", pose[:, :2], rgb, -1.25 * x)
        draw.poses(rec, f"{base}/vehicle", TL, t, pose, rgb, arrow)
        if est.smoothed is not None:
            # a smoother's whole trajectory as it holds it at the end, paler and thinner than
            # the path of what it knew at each step
            final = smoothed_on_grid(est, grid)
            pale = tuple(int(c + (255 - c) * 0.55) for c in rgb[:3])
            draw.track(rec, f"{base}/smoothed", final[:, :2], pale, -0.75 * x)
        draw.covariance_ellipses(rec, f"{base}/pose_ellipse", TL, t, pose[:, :2], cov[:, :2, :2], rgb)
        if len(est.map_steps):
            draw.point_sets(rec, f"{base}/landmarks", TL, d.t[est.map_steps], est.map_mean, rgb, 0.35, 0.05)
            if est.map_cov is not None:
                draw.ellipse_sets(rec, f"{base}/landmark_ellipses", TL, d.t[est.map_steps], est.map_mean,
                                  est.map_cov, rgb)
        _far_off(rec, f"{base}/far_off", est, getattr(zero, "survey", {}).get(name), d.landmark_ids)
        _unplaced(rec, base, est, getattr(zero, "unplaced", {}).get(name), d.landmark_ids)
        rt, counts, starts, ends = _rays(first, pose, ray_len)
        if len(rt):
            draw.segment_sets(rec, f"{base}/rays", TL, rt, counts, starts, ends, (255, 255, 120), 0.03)
        if est.gated:
            # the bearings the gate left out, red, each shown for the step it came in (misreads:
            # MRCLAM robot 3 at 255 s, robot 5 at 582 and 682 s)
            rt, counts, starts, ends = _rays(first, pose, ray_len, est.gated_bearings)
            if len(rt):
                # each cleared at the next grid time (an empty set there), so it shows for its step only
                after = t[np.minimum(np.searchsorted(t, rt, side="right"), len(t) - 1)]
                clear = np.setdiff1d(after, rt)
                gt = np.r_[rt, clear]
                order = np.argsort(gt, kind="stable")
                gc = np.r_[counts, np.zeros(len(clear), int)][order]
                draw.segment_sets(rec, f"{base}/gated", TL, gt[order], gc, starts, ends, (255, 40, 40), 0.06)
        if est.attempts:
            pt, clouds = _pending(first, est.attempts)
            draw.point_sets(rec, f"{base}/pending", TL, pt, clouds, (255, 140, 0), 0.12, 0.1)
    metric_plots.draw_curves(rec, plots(first, [zero]), first.estimators, over_runs=False, timeline=TL)
    if first.images is not None and first.images.frames:
        _images(rec, first)


def record_runs(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log the curves over all runs and the results table with how to read the recording."""
    metric_plots.draw_curves(rec, plots(first, runs), first.estimators, True, BOUNDS, TL)
    metric_plots.summary(rec, table_md + "\n\n" + how_to_read(first, len(runs)))


def first_reference(first: RunResult) -> str | None:
    """Run 0's reference where it has no truth of the robot: the run's smoother."""
    from workbench.metrics import truthfree

    if np.isfinite(first.data.truth[first.grid]).any():
        return None
    return truthfree.smoother(first.estimators, first.estimates)


def how_to_read(first: RunResult, runs: int) -> str:
    """The note under the results table: what each view shows and how to read it."""
    one, many = metrics.chi2_band(3, 1), metrics.chi2_band(3, runs)
    lines = [
        *metric_plots.how_to_read(first, "the truth white"),
        "- maps, top-down (x east, y north, m), one per estimator, on the same world: walls grey, the true "
                "landmarks and path white; the estimator's path, pose and 95 % pose ellipse, its landmarks with their "
        "95 % ellipses (iSAM2's path is what it knew at each step; its whole trajectory as it holds it at the "
        "end, smoothed, is drawn paler), the bearings of the step as yellow rays, those its gate left out "
        "(misread barcodes, outliers) as red rays, and (the filters) the unscented-transform "
        "sigma points of each landmark initialisation try in orange.",
        (f"- run 0: position and heading error, and the pose NEES (3 dof) with its one-run 95 % band "
         f"({one[0]:.2f}-{one[1]:.2f})" if first_reference(first) is None else
         f"- no truth of the robot: the run 0 tab shows, for each estimator, the smoother's ({first_reference(first)}) "
         "pose minus its own (its departure from the smoother: where a filter and the smoother part ways), and each "
         f"causal estimator's disagreement with the smoother, the difference weighted by the difference of their "
         f"covariances (3 dof, inside its 95 % band {one[0]:.2f}-{one[1]:.2f} where both are consistent); the "
         "frame is the first pose's, and the landmark survey (white) is drawn moved onto the smoother's map by its "
         "best rigid alignment")
        + "; own sigmas: the standard deviations each estimator claims"
        + ("; below them (a real log), the heading sigma each odometry step adds where a logged command "
           "switched at a time the log does not say (its gaps): there the estimators lean on the bearings."
           if first.data.control_var is not None else "."),
        ("- no truth: nothing to draw over runs; the truth-free tests are in the results' Consistency lines and "
         "the metrics tab." if first_reference(first) is not None else
         f"- over runs ({runs} runs): RMS position and heading error at each step, and the ANEES with its 95 % band "
        f"({many[0]:.2f}-{many[1]:.2f}): inside it the covariance is consistent with the errors, above it the "
        "estimator is overconfident; beside the RMS errors the Cramér-Rao bounds of a filter (light grey) and a "
        "smoother (dark grey): no estimator can be below the one it is held to for long (the results' efficiency "
        "is RMSE / bound)."),
        "- a plot's title names an estimator that is off its scale (its own values would flatten the others); "
        "the legend is in the first plot of each tab, the colours are the same below it.",
    ]
    return "\n".join(lines)


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
