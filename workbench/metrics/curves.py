"""The recording's curves of the metrics (:mod:`.metric`), for every experiment's ``record.py``:
a time-series metric's values at each step of run 0, and its value at each step over the runs
(the RMS of an error, the mean of a NEES), with the chi-square band of a metric that has one.

An experiment draws the metrics it shows in its own views (by name, at the origins it chooses);
the others it lists in its ``metrics.CURVES``, and every plugin's time-series metric, go to the
recording's "metrics" tab (:func:`extra`), without a line of the experiment's written for them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from workbench.estimation.metrics import chi2_band
from workbench.metrics import base as metric
from workbench.metrics import diagnosis
from workbench.metrics import statistics as figures
from workbench.recording.layout import Curves

BAND = {"band_lo": "95 % low", "band_hi": "95 % high"}
OVER_RUNS = ("/monte_carlo", "/metrics")
"""The plots of the curves over runs (drawn when every run is done); the others are run 0's."""


def over_runs(m: metric.Metric, summaries: Sequence[Any], names: Iterable[str] | None = None) -> Curves | None:
    """The metric at each step over the runs, per estimator (``names``: those only), with its
    band for that many runs; None where it is no time series."""
    t, series = figures.curves(m, [s.metrics for s in summaries])
    if names is not None:
        series = {n: v for n, v in series.items() if n in set(names)}
    if not series:
        return None
    c = Curves(t, series, m.unit)
    dof = m.dimension or (_dof(m, summaries) if m.dimension == 0 else None)
    if dof:
        lo, hi = chi2_band(dof, len(summaries))
        c.series.update(band_lo=np.full_like(t, lo), band_hi=np.full_like(t, hi))
        c.fixed, c.labels = tuple(BAND), dict(BAND)
    return c


def _dof(m: metric.Metric, summaries: Sequence[Any]) -> int | None:
    """The samples' own degrees of freedom (the first estimate's that says them)."""
    return next((row[m.name].dof for s in summaries for row in s.metrics.values() if m.name in row), None)


def by_name(metrics: Iterable[metric.Metric]) -> dict[str, metric.Metric]:
    return {m.name: m for m in metrics}


def extra(metrics: Iterable[metric.Metric], summaries: Sequence[Any], listed: Sequence[str] = ()
          ) -> dict[str, Curves]:
    """The "metrics" tab's curves over runs, at ``/metrics/<metric>``: the built-ins ``listed``
    and every plugin metric that is a time series."""
    out = {}
    for m in metrics:
        if m.name in listed or m.source != "built-in":
            c = over_runs(m, summaries)
            if c is not None:
                out[f"/metrics/{m.name}"] = c
    return out


def titles(metrics: Mapping[str, metric.Metric], curves: Mapping[str, Curves], runs: int | None = None
           ) -> dict[str, str]:
    """Each metric plot's title: the metric's name, its description and unit, how the runs combine
    at each step (``runs``: over that many; None: run 0 alone), and its band."""
    out = {}
    for origin in curves:
        m = metrics[origin.rsplit("/", 1)[1]]
        what = m.description.split(",")[0].split(" (")[0]
        how = "run 0" if runs is None else ("RMS" if m.reduce == "rms" else m.reduce) + f" over {runs} runs"
        band = ", grey: 95 % band" if m.dimension is not None else ""
        out[origin] = f"{m.name}: {what}" + (f" ({m.unit})" if m.unit else "") + f", {how}{band}"
    return out


def tab(curves: Mapping[str, Curves], metrics: Iterable[metric.Metric], span: tuple[float, float],
        runs: int | None = None) -> Any:
    """The "metrics" tab (a view per ``/metrics/...`` curve, each fitted to its values), or None."""
    import rerun.blueprint as rrb

    from workbench.recording import layout

    mine = {o: c for o, c in curves.items() if o.startswith("/metrics/")}
    if not mine:
        return None
    names = titles(by_name(metrics), mine, runs)
    return rrb.Vertical(*[layout.plot(o, names[o], span, c, legend=i == 0) for i, (o, c) in enumerate(mine.items())],
                        name="metrics")


def draw_curves(rec: Any, curves: Mapping[str, Curves], estimators: Mapping[str, Any], over_runs: bool,
                others: Mapping[str, tuple] | None = None, timeline: str = "time") -> None:
    """Run 0's plots (``over_runs`` False: as soon as it is done) or those over the runs."""
    from workbench.recording import draw

    draw.plot_series(rec, timeline, dict(curves), dict(estimators),
                     lambda o: o.startswith(OVER_RUNS) == over_runs, dict(others or {}))


def summary(rec: Any, text: str, columns: int = 6) -> None:
    """The results (markdown) in the recording's "results" view, a table wider than ``columns``
    split into several (the view is a narrow panel; a wide table is cut off there)."""
    import rerun as rr

    rec.log("/summary", rr.TextDocument(narrow_tables(text, columns), media_type=rr.MediaType.MARKDOWN),
            static=True)


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


GROUP_OVER = 4
"""More estimators than this in one plot and their curves hide each other (seven noisy error lines
in the browser could not be told apart, and the legend was cut after six): the plot becomes small
multiples, one per group (:func:`groups`)."""
GROUPS = ("filters", "no covariance", "smoothers", "plugins")


def groups(estimators: Mapping[str, Any], names: Iterable[str]) -> dict[str, list[str]] | None:
    """The estimators ``names`` (those of ``estimators`` among them, in order) by kind, for
    :func:`workbench.recording.layout.grouped`: ``filters`` (causal: each step's estimate from the
    data up to it, with its covariance), ``no covariance`` (causal point estimates, the papers'
    geometric and least-squares ones: noisier, they would hide the filters), ``smoothers`` (they
    use later data too: a fixed lag or the whole run) and ``plugins`` (a researcher's own, whatever
    its kind, apart so it is never lost among the built-ins; the workbench's own entry points are
    built-ins here). None where there are at most :data:`GROUP_OVER` (one plot reads)."""
    names = [n for n in names if n in estimators]
    if len(names) <= GROUP_OVER:
        return None
    out: dict[str, list[str]] = {g: [] for g in GROUPS}
    for n in names:
        e = estimators[n]
        ours = e.builtin or str(getattr(e.run, "__module__", "")).startswith("workbench.")
        kind = ("plugins" if not ours else "smoothers" if e.delay > 0 else
                "filters" if e.covariances else "no covariance")
        out[kind].append(n)
    return {g: v for g, v in out.items() if v}


def flagged(title: str, stats: Mapping | None, truth: bool) -> str:
    """A view's title with the estimators that fail their consistency tests (``truth``: with the
    truth, the NEES; else without it, :func:`.markdown.verdicts`, each with its diagnosis) named
    after it; with the truth, every estimator's truth-free diagnosis too (:mod:`.diagnosis`)."""
    key = "consistent_with_truth" if truth else "consistent_without_truth"
    failing = [n + ("" if truth or not e.get("diagnosis") else f" ({diagnosis.line(e['diagnosis'])})")
               for n, e in (stats or {}).get("estimators", {}).items() if e.get(key) is False]
    title += f"; failing: {', '.join(failing)}" if failing else ""
    found = [f"{n} {diagnosis.line(e['diagnosis'])}" for n, e in (stats or {}).get("estimators", {}).items()
             if e.get("diagnosis")]
    return title + (f"; diagnosed without truth: {', '.join(found)}" if truth and found else "")


def how_to_read(first: Any, truth: str) -> list[str]:
    """The head of a recording's "how to read" note: run 0 drawn in full, the time line, and each
    estimator's colour in words (``truth``: how the truth is drawn)."""
    from workbench.recording import draw

    shown = {n: e for n, e in first.estimators.items() if n in first.estimates}
    return ["**How to read this recording** (run 0 drawn in full; scrub the `time` timeline, seconds)", "",
            f"- colours: {draw.colour_key(shown)}; {truth}."]
