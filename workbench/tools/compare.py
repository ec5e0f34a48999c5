"""``workbench compare A.rrd B.rrd [...]``: one recording with the runs side by side and overlaid,
and the differences of their headline error curves (each run against the first).

Every run is copied whole under an entity prefix named by its label (``/lam_0.99/map/...``):
its data chunks, its series named ``"<label>: <name>"`` in the legends, and after the first its
colours in a lighter shade of each estimator's own (the colours stay the estimators'). Its own
default layout comes along too, re-rooted under the prefix, so the "side by side" tab shows each
run exactly as it opens alone. The "overlaid" tab puts every run's curves (and maps) in one view
per plot of the first run's layout; "differences" has, per compared plot of the experiment
(:attr:`Experiment.compared`), each estimator's curve of run k minus run 0's on run 0's times;
"results" the runs' tables and the figures that differ.
"""

from __future__ import annotations

import json
import math
import re
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa

from workbench.errors import WorkbenchError
from workbench.recording import readback
from workbench.tools import browser, provenance, reproduce

LIGHTER = 0.45
"""How far toward white the colours of every run after the first are taken."""
NAMESPACE = uuid.UUID("6f1c2a1e-3a51-4d1b-9a0f-6b0f8e0c6a11")


@dataclass
class Run:
    """One compared recording: its stored provenance, its label and entity prefix."""

    stored: provenance.Stored
    label: str
    slug: str
    index: int

    @property
    def path(self) -> Path:
        return self.stored.path


# --- which runs, and what they are called ----------------------------------------------------------

def runs_of(files: list[Path], labels: list[str] | None) -> list[Run]:
    """The recordings, checked to be of one experiment, with their labels: given, else what
    tells their configs apart (``lam=0.99``), else the estimators that differ, else the file names."""
    if len(files) < 2:
        raise WorkbenchError("compare needs two or more recordings")
    stored = []
    for f in files:
        s = provenance.read(f)
        provenance.config_of(s)  # a recording of an experiment this workbench knows
        stored.append(s)
    exps = {s.experiment for s in stored}
    if len(exps) > 1:
        which = ", ".join(f"{s.path.name} ({s.experiment})" for s in stored)
        raise WorkbenchError(f"compare takes recordings of one experiment, not {which}")
    if labels is not None:
        if len(labels) != len(files):
            raise WorkbenchError(f"--labels names {len(labels)} runs for {len(files)} recordings")
        names = [str(x).strip() for x in labels]
        if any(not n for n in names):
            raise WorkbenchError("--labels: an empty label")
    else:
        names = _labels(stored)
    slugs = [re.sub(r"[^A-Za-z0-9_.-]+", "_", n).strip("_") or f"run{i}" for i, n in enumerate(names)]
    if len(set(names)) < len(names) or len(set(slugs)) < len(slugs):
        names = [f"{chr(65 + i)}: {n}" for i, n in enumerate(names)]
        slugs = [f"{chr(65 + i)}_{s}" for i, s in enumerate(slugs)]
    return [Run(s, n, g, i) for i, (s, n, g) in enumerate(zip(stored, names, slugs, strict=True))]


def _labels(stored: list[provenance.Stored]) -> list[str]:
    keys = sorted({k for s in stored for k in s.config} - {"estimators"})
    differ = [k for k in keys if len({json.dumps(s.config.get(k), sort_keys=True) for s in stored}) > 1]
    if differ:
        return [",".join(f"{k}={_show(s.config.get(k))}" for k in differ) for s in stored]
    sets = [tuple(s.config.get("estimators") or ()) for s in stored]
    if len(set(sets)) == len(sets):
        common = set.intersection(*map(set, sets))
        return ["+".join(e.split("=")[0] for e in est if e not in common) or "defaults" for est in sets]
    return [s.path.stem for s in stored]


def _show(value) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "x".join(map(str, value))
    return str(value)


# --- the runs' data, under their prefixes --------------------------------------------------------

def _lighter(packed: int, amount: float) -> int:
    r, g, b, a = (packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255, packed & 255
    r, g, b = (round(c + amount * (255 - c)) for c in (r, g, b))
    return (r << 24) | (g << 16) | (b << 8) | a


def _edit(batch: pa.RecordBatch, column: str, fn) -> pa.RecordBatch:
    """The batch with one list column's values mapped by ``fn`` (value -> value), types and metadata kept."""
    i = batch.schema.get_field_index(column)
    field = batch.schema.field(i)
    values = [None if row is None else [fn(v) for v in row] for row in batch.column(i).to_pylist()]
    return batch.set_column(i, field, pa.array(values, type=field.type))


def data_chunks(run: Run) -> Iterator:
    """The run's recording chunks under ``/<slug>``, series renamed ``"<label>: <name>"`` and,
    after the first run, every colour lighter; its properties left out (the comparison has its own)."""
    from rerun.chunk import RrdReader

    for chunk in RrdReader(str(run.path)).store().stream():
        entity = str(chunk.entity_path)
        if entity.startswith("/__"):
            continue
        target = f"/{run.slug}{entity}" if entity != "/" else f"/{run.slug}"
        names = chunk.to_record_batch().schema.names
        edits = [n for n in names if n.endswith(":names") or (run.index and n.endswith(":colors"))]
        if not edits:
            yield chunk.with_entity_path(target)
            continue
        batch = chunk.to_record_batch()
        for n in edits:
            if n.endswith(":names"):
                batch = _edit(batch, n, lambda v: f"{run.label}: {v}")
            else:
                batch = _edit(batch, n, lambda v: _lighter(int(v), LIGHTER))
        yield from _rebuilt(chunk, batch, target)


def _rebuilt(chunk, batch: pa.RecordBatch, entity: str) -> list:
    """``chunk`` again from its edited ``batch``, at ``entity``, on the same timelines (or static)."""
    from rerun.chunk import Chunk

    index = None if chunk.is_static else list(chunk.timeline_names)
    return [c.with_entity_path(entity) for c in Chunk.from_record_batch(batch, index=index)]


# --- the layouts ---------------------------------------------------------------------------------

def _query(q: str, slug: str) -> str:
    """A view's content query with its absolute paths moved under ``/<slug>`` (``$origin`` stays)."""
    sign, _, path = q.rpartition(" ")
    if path.startswith("/"):
        path = f"/{slug}{path}" if path != "/" else f"/{slug}"
    return f"{sign} {path}".strip()


def embedded_layout(run: Run) -> tuple[str, list, str | None]:
    """The run's own default blueprint, re-rooted under ``/<slug>``: its views' and containers'
    ids renamed (a recording compared with itself must not clash), origins and absolute queries
    prefixed. Returns its root container's id, the chunks, and its time panel's timeline."""
    _, chunks = browser.blueprint_chunks(run.path)
    tree = browser.layout(run.path)

    def rename(ident: str) -> str:
        kind, _, old = ident.partition("/")
        return f"{kind}/{uuid.uuid5(NAMESPACE, run.slug + old)}"

    out, timeline = [], None
    for chunk in chunks:
        entity = str(chunk.entity_path).lstrip("/")
        parts = entity.split("/")
        batch = chunk.to_record_batch()
        if parts[0] == "time_panel" and "TimePanelBlueprint:timeline" in batch.schema.names:
            timeline = (batch.column("TimePanelBlueprint:timeline").to_pylist()[-1] or [None])[0]
        if parts[0] not in ("view", "container"):
            continue
        target = "/" + "/".join([rename("/".join(parts[:2])), *parts[2:]])
        for name in batch.schema.names:
            if name == "ViewBlueprint:space_origin":
                batch = _edit(batch, name, lambda o: f"/{run.slug}{o}" if o != "/" else f"/{run.slug}")
            elif name == "ViewContents:query":
                batch = _edit(batch, name, lambda q: _query(q, run.slug))
            elif name in ("ContainerBlueprint:contents", "ContainerBlueprint:active_tab"):
                batch = _edit(batch, name, rename)
        out += _rebuilt(chunk, batch, target)
    return rename(tree.id), out, timeline


class Layout:
    """A default blueprint made of the runs' own layouts (as chunks) and new views: what
    ``set_sinks(default_blueprint=...)`` takes (it asks for ``to_blueprint`` and ``_log_to_stream``)."""

    def __init__(self, embedded: list[tuple[str, str, list]], overlaid: list, differences: list, results,
                 timeline: str | None) -> None:
        self.embedded, self.overlaid, self.differences = embedded, overlaid, differences
        self.results, self.timeline = results, timeline

    def to_blueprint(self) -> Layout:
        return self

    def _log_to_stream(self, stream) -> None:
        import rerun.blueprint as rrb
        from rerun.blueprint.archetypes import ContainerBlueprint, ViewportBlueprint

        def ident(part) -> str:
            return f"{'container' if isinstance(part, rrb.Container) else 'view'}/{part.id}"

        side = []
        for label, root, chunks in self.embedded:
            stream.send_chunks(chunks)
            stream.log(root, ContainerBlueprint.from_fields(display_name=label))
            side.append((label, root))
        side_id = f"container/{uuid.uuid4()}"
        stream.log(side_id, ContainerBlueprint(container_kind="horizontal", display_name="side by side",
                                               contents=[root for _, root in side]))
        tabs = [side_id]
        for name, parts in (("overlaid", self.overlaid), ("differences", self.differences)):
            if parts:
                box = rrb.Grid(*parts, name=name)
                box._log_to_stream(stream)
                tabs.append(ident(box))
        self.results._log_to_stream(stream)
        tabs.append(ident(self.results))
        root = uuid.uuid4()
        stream.log(f"container/{root}", ContainerBlueprint(container_kind="tabs", display_name="comparison",
                                                           contents=tabs))
        stream.log("viewport", ViewportBlueprint(root_container=root.bytes))
        for panel in (rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
                      rrb.TimePanel(state="collapsed", timeline=self.timeline)):
            panel._log_to_stream(stream)


def overlaid_views(runs: list[Run]) -> list:
    """One view per plot and map of the first run's layout, with every run's content in it; the
    legend (every run's names) only in the first plot: the colours are the same in the others."""
    import rerun.blueprint as rrb

    first = browser.layout(runs[0].path)
    others = [{(v.kind, v.origin): v for v in browser.layout(r.path).views()} for r in runs[1:]]
    out = []
    for view in first.views():
        if view.kind not in ("TimeSeries", "3D") or not all((view.kind, view.origin) in o for o in others):
            continue
        contents = []
        for r in runs:
            queries = (view.properties.get("ViewContents", {}).get("query") or ["$origin/**"])
            contents += [_query(q.replace("$origin", view.origin.rstrip("/") or ""), r.slug) for q in queries]
        if view.kind == "TimeSeries":
            rng = (view.properties.get("TimeAxis", {}).get("view_range") or [None])[0]
            axis = None
            if rng:
                axis = rrb.TimeAxis(view_range=rrb.TimeRange(
                    start=rrb.TimeRangeBoundary.absolute(seconds=rng["start"] / 1e9),
                    end=rrb.TimeRangeBoundary.absolute(seconds=rng["end"] / 1e9)))
            first_plot = not any(isinstance(v, rrb.TimeSeriesView) for v in out)
            out.append(rrb.TimeSeriesView(origin="/", contents=contents, name=view.name, axis_x=axis,
                                          plot_legend=rrb.PlotLegend(visible=first_plot)))
        else:
            eye = view.properties.get("EyeControls3D", {})
            kw = {}
            if eye.get("position"):
                kw["eye_controls"] = rrb.EyeControls3D(position=eye["position"][0], look_target=eye["look_target"][0],
                                                       eye_up=eye["eye_up"][0])
            bg = view.properties.get("Background", {}).get("color")
            if bg:
                p = int(bg[0])
                kw["background"] = ((p >> 24) & 255, (p >> 16) & 255, (p >> 8) & 255)
            out.append(rrb.Spatial3DView(origin="/", contents=contents, name=view.name, **kw))
    return out


# --- the differences -----------------------------------------------------------------------------

def differences(runs: list[Run], compared: tuple[str, ...], pairs: list[tuple[str, str]]
                ) -> dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Per compared plot: ``"<label k> - <label 0>: <estimator>"`` -> (run 0's times, run k's curve
    minus run 0's, run k's linearly interpolated onto run 0's times inside its span), for every
    estimator both runs have, and every ``(name in run 0, name in run k)`` pair given."""
    series = [readback.all_series(r.path, compared) for r in runs]
    out: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
    for origin in compared:
        by_run = [{e.rsplit("/", 1)[1]: tv for e, tv in s.items() if e.rsplit("/", 1)[0] == origin} for s in series]
        curves = {}
        for k in range(1, len(runs)):
            matched = [(n, n) for n in by_run[0] if n in by_run[k] and not n.startswith(("band", "bound"))]
            matched += [(a, b) for a, b in pairs if a in by_run[0] and b in by_run[k]]
            for a, b in matched:
                (t0, v0), (tk, vk) = by_run[0][a], by_run[k][b]
                inside = (t0 >= tk[0]) & (t0 <= tk[-1])
                d = np.full_like(v0, np.nan)
                d[inside] = np.interp(t0[inside], tk, vk) - v0[inside]
                name = a if a == b else f"{b} - {a}"
                curves[f"{runs[k].label} - {runs[0].label}: {name}"] = (t0, d)
        if curves:
            out[origin] = curves
    return out


# --- the results -----------------------------------------------------------------------------------

def _numbers(tree) -> dict[str, float]:
    """The finite figures of a metrics tree by path (lists, such as bands, left out)."""
    return {k: v for k, v in reproduce.flatten(tree, provenance.IGNORED, lists=False).items() if math.isfinite(v)}


def results_text(runs: list[Run], pairs: list[tuple[str, str]], limit: int = 60) -> str:
    """Each run's command and table, then the figures (per estimator) that differ from run 0's."""
    from workbench.core.registry import get

    exp = get(runs[0].stored.experiment)
    lines = [f"**Comparison of {len(runs)} {exp.name} recordings** (each later run against `{runs[0].label}`)", ""]
    for r in runs:
        lines += [f"**{r.label}** ({r.path.name}): `{r.stored.command or '?'}`", "",
                  exp.table(r.stored.metrics or {}) if r.stored.metrics else "(no metrics stored)", ""]
    base = _numbers((runs[0].stored.metrics or {}).get("estimators", {}))
    for r in runs[1:]:
        other = _numbers((r.stored.metrics or {}).get("estimators", {}))
        keys = [(k, k) for k in base if k in other]
        for a, b in pairs:
            keys += [(k, b + k[len(a):]) for k in base if k.startswith(a + ".") and b + k[len(a):] in other]
        rows = [(ka if ka == kb else f"{kb} - {ka}", base[ka], other[kb]) for ka, kb in keys
                if reproduce.relative(float(base[ka]), float(other[kb])) > reproduce.FLOAT_TOLERANCE]
        lines += [f"**{r.label} - {runs[0].label}**: {len(rows)} of {len(keys)} figures differ", ""]
        if rows:
            lines += [f"| figure | {runs[0].label} | {r.label} | difference |", "|---|---|---|---|"]
            lines += [f"| {k} | {a:.4g} | {b:.4g} | {b - a:+.4g} |" for k, a, b in rows[:limit]]
            if len(rows) > limit:
                lines.append(f"| ... {len(rows) - limit} more | | | |")
            lines.append("")
    lines += ["**How to read this comparison**", "",
              "- side by side: each run as it opens alone (its own layout and tabs).",
              f"- overlaid: every run's curves in one plot, named `<label>: <estimator>`; `{runs[0].label}` in the "
              "estimators' colours, the later runs in lighter shades of them.",
              f"- differences: each later run's curve minus `{runs[0].label}`'s, for the estimators both have"
              + (" and the pairs asked for" if pairs else "") + "; zero means the same."]
    return "\n".join(lines)


def write(files: list[Path], out: Path, labels: list[str] | None = None, pairs: list[tuple[str, str]] | None = None,
          force: bool = False) -> list[Run]:
    """The comparison recording, written to ``out`` (atomically; not over a file without ``force``)."""
    import rerun as rr
    import rerun.blueprint as rrb

    from workbench.core.registry import get
    from workbench.recording import draw, stream
    from workbench.recording import layout as views
    from workbench.version import __version__

    runs = runs_of(files, labels)
    out = stream.check_output(out, force)
    if any(out.resolve() == r.path.resolve() for r in runs):
        raise WorkbenchError(f"--out {out} is one of the recordings compared")
    pairs = list(pairs or [])
    exp = get(runs[0].stored.experiment)
    diffs = differences(runs, exp.compared, pairs)
    embedded, timeline = [], None
    for r in runs:
        root, chunks, tl = embedded_layout(r)
        embedded.append((r.label, root, chunks))
        timeline = timeline or tl
    names = {v.origin: v.name for v in browser.layout(runs[0].path).views()}
    versus = " / ".join(f"{r.label} - {runs[0].label}" for r in runs[1:])
    diff_views = []
    for origin, curves in diffs.items():
        t = next(iter(curves.values()))[0]
        shown = views.Curves(t, {n: d for n, (_, d) in curves.items()})
        diff_views.append(views.plot(f"/differences{origin}", f"{names.get(origin, origin)}: {versus}",
                                     (float(t[0]), float(t[-1])), shown))
    results = rrb.TextDocumentView(origin="/comparison", name="results")
    layout = Layout(embedded, overlaid_views(runs), diff_views, results, timeline)
    rec = rr.RecordingStream(f"workbench_compare_{exp.name}")
    tmp = out.with_name(f".{out.name}.tmp")
    ok = False
    try:
        rec.set_sinks(rr.FileSink(str(tmp)), default_blueprint=layout)
        rec.send_recording_name(f"workbench compare {exp.name}: " + " vs ".join(r.label for r in runs))
        rec.send_property("workbench_compare", rr.AnyValues(
            experiment=exp.name, version=__version__, command=stream.command_line(),
            inputs=json.dumps([{"path": str(r.path), "label": r.label, "prefix": f"/{r.slug}",
                                "command": r.stored.command, "git_commit": r.stored.git_commit} for r in runs])))
        for r in runs:
            rec.send_chunks(list(data_chunks(r)))
        colours = {}
        for r in runs:
            table = (r.stored.metrics or {}).get("estimator_table", {})
            colours.update({n: tuple(e["color"]) for n, e in table.items()})
        for origin, curves in diffs.items():
            for name, (t, d) in curves.items():
                est = name.rsplit(": ", 1)[1].split(" - ")[0]
                key = re.sub(r"[^A-Za-z0-9_.-]+", "_", name)
                draw.scalars(rec, f"/differences{origin}/{key}", "time", t, d, name, colours.get(est, (120, 120, 120)))
        rec.log("/comparison", rr.TextDocument(results_text(runs, pairs), media_type=rr.MediaType.MARKDOWN),
                static=True)
        rec.flush()
        rec.disconnect()
        ok = True
    finally:
        if ok:
            tmp.replace(out)
        elif tmp.exists():
            tmp.unlink()
    return runs
