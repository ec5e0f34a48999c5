"""What an experiment gets for a part it does not declare (the defaults of
:class:`~workbench.core.parts.Parts`): a run's summary with its metrics alone (``summarise``,
``statistics``) and a recording of every time-series metric, run 0's and over the runs, beside the
results (``layout``, ``record_run``, ``record_runs``); the table's default is
:func:`workbench.metrics.tables.default_table`. A new experiment declares the parts where it has
something of its own to say (a map, a paper's table) and takes these for the rest.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.core.results import RunResult, RunSummary
from workbench.metrics import curves as plots
from workbench.recording import layout as views

TL = "time"


# --- evaluate ------------------------------------------------------------------------------------

def summarise(result: RunResult, cfg: Any, run: int) -> RunSummary:
    """A run's summary: its number and what failed (the contract adds the metrics' samples)."""
    return RunSummary(run, failed=dict(result.failed))


def statistics(exp: Any, cfg: Any, runs: list[RunSummary], stats: dict) -> None:
    """Nothing beyond the metrics' figures."""


# --- record --------------------------------------------------------------------------------------

def _series(first: RunResult, runs: list[RunSummary]) -> tuple[dict[str, views.Curves], dict[str, views.Curves]]:
    """Every time-series metric: run 0's values (``/run0/<metric>``) and over the runs
    (``/metrics/<metric>``), as the plots show them."""
    zero, over = {}, {}
    for m in first.metrics:
        c = plots.over_runs(m, runs[:1])  # run 0's own values (a chi-square metric with its one-run band)
        if c is not None:
            zero[f"/run0/{m.name}"] = c
        c = plots.over_runs(m, runs)
        if c is not None:
            over[f"/metrics/{m.name}"] = c
    return zero, over


def _span(curves: dict[str, views.Curves]) -> tuple[float, float]:
    t = np.concatenate([c.t for c in curves.values()]) if curves else np.zeros(1)
    return float(np.min(t)), float(max(np.max(t), np.min(t) + 1e-9))


def layout(first: RunResult, runs: list[RunSummary]) -> rrb.Blueprint:
    """Tabs: run 0's metrics, the metrics over runs, the results."""
    zero, over = _series(first, runs)
    span = _span({**zero, **over})
    known = plots.by_name(first.metrics)
    tabs = []
    for name, curves, n in (("run 0", zero, None), ("over runs", over, len(runs))):
        if curves:
            titles = plots.titles(known, curves, n)
            tabs.append(rrb.Vertical(*[views.plot(o, titles[o], span, c, legend=i == 0)
                                       for i, (o, c) in enumerate(curves.items())], name=name))
    tabs.append(rrb.TextDocumentView(origin="/summary", name="results"))
    return rrb.Blueprint(rrb.Tabs(*tabs), collapse_panels=True)


def record_run(rec: rr.RecordingStream, first: RunResult, zero: RunSummary) -> None:
    """Run 0's time-series metrics, each estimator in its colour."""
    plots.draw_curves(rec, _series(first, [zero])[0], first.estimators, over_runs=False, timeline=TL)


def record_runs(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """The metrics over runs (the chi-square bands grey) and the results table."""
    plots.draw_curves(rec, _series(first, runs)[1], first.estimators, over_runs=True, timeline=TL)
    note = [*plots.how_to_read(first, "the truth is not drawn"),
            "- run 0: each time-series metric of run 0; over runs: at each step their RMS (an error) or mean over "
            f"the {len(runs)} runs; a grey pair of lines is a chi-square metric's 95 % band (inside it the "
            "estimator is consistent, above it overconfident)."]
    plots.summary(rec, table_md + "\n\n" + "\n".join(note))

