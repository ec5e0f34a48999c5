"""A sweep's report, rebuilt from its Parquet files alone (``workbench sweep-report DIR``):
``summary.csv`` and ``summary.md`` (per cell, estimator and metric: the mean over runs, its
spread, a 95 % interval of the mean), a PNG per headline metric and swept setting (the mean
over the other settings' cells and the runs, one line per estimator, with its interval), and
``sweep.rrd``: the same curves in Rerun, a tab per swept setting on one timeline (the value's index).

The 95 % interval is Student's t on the runs: ``mean +- t(0.975, n-1) sd / sqrt(n)``.
"""

from __future__ import annotations

import io
import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from workbench.errors import WorkbenchError
from workbench.recording import stream

FALLBACK = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
            (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def read(folder: Path) -> pa.Table:
    """Every task's rows in a sweep folder, one table."""
    files = sorted((Path(folder) / "tasks").glob("*.parquet"))
    if not files:
        raise WorkbenchError(f"no sweep results in {folder} (expected {folder}/tasks/*.parquet)")
    return pa.concat_tables([pq.read_table(f) for f in files], promote_options="default")


def definition(folder: Path) -> dict:
    """What the sweep was (its fixed settings, grid keys, estimators): as every task's Parquet
    file carries it, so the files alone are enough."""
    first = sorted((Path(folder) / "tasks").glob("*.parquet"))[0]
    meta = pq.read_schema(first).metadata or {}
    return json.loads(meta.get(b"workbench.sweep", b"{}"))


def params(table: pa.Table) -> list[str]:
    """The swept settings: the columns ``p.<setting>``, in the order they were swept."""
    return [c[2:] for c in table.column_names if c.startswith("p.")]


def t95(n: int) -> float:
    """Student's t quantile 0.975 with ``n - 1`` degrees of freedom (nan for one run)."""
    if n < 2:
        return float("nan")
    from scipy.stats import t

    return float(t.ppf(0.975, n - 1))


def summarise(table: pa.Table) -> list[dict]:
    """Per cell, estimator and metric: n, mean, std (ddof 1), the 95 % interval, failed runs."""
    keys = ["cell", *[f"p.{k}" for k in params(table)], "estimator", "metric", "unit"]
    ok = table.filter(pc.invert(table["failed"]))
    grouped = ok.group_by(keys).aggregate([("value", "mean"), ("value", "count"),
                                           ("value", "stddev", pc.VarianceOptions(ddof=1))])
    failed = defaultdict(int)
    for row in table.filter(table["failed"]).select(["cell", "estimator"]).to_pylist():
        failed[(row["cell"], row["estimator"])] += 1
    out = []
    for row in grouped.to_pylist():
        n, mean, sd = row["value_count"], row["value_mean"], row["value_stddev"]
        half = t95(n) * sd / math.sqrt(n) if n > 1 and sd is not None else float("nan")
        entry = {"cell": row["cell"], **{k: row[f"p.{k}"] for k in params(table)}, "estimator": row["estimator"],
                 "metric": row["metric"], "unit": row["unit"], "n": n, "mean": mean,
                 "std": sd if sd is not None else float("nan"), "ci95_lo": mean - half, "ci95_hi": mean + half,
                 "failed_runs": failed.get((row["cell"], row["estimator"]), 0)}
        out.append(entry)
    out.sort(key=lambda e: (e["cell"], e["estimator"], e["metric"]))
    return out


def to_csv(rows: list[dict]) -> str:
    import csv
    import io

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _num(x: float) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.3g}" if abs(x) < 10 else f"{x:.1f}"


def _experiment(name: str):
    try:
        from workbench.core.registry import get

        return get(name)
    except WorkbenchError:  # a sweep of an experiment this installation does not have
        return None


def headline(experiment: str, metrics: list[str]) -> list[str]:
    """The experiment's headline metrics present in the table (all metrics if it names none)."""
    exp = _experiment(experiment)
    wanted = [m for m in exp.headline if m in metrics] if exp is not None else []
    return wanted or [m for m in metrics if m != "failed"]


def markdown(rows: list[dict], table: pa.Table, manifest: dict | None) -> str:
    """A table per headline metric: a row per cell, a column per estimator, ``mean +- half-interval``."""
    experiment = table["experiment"][0].as_py()
    exp = _experiment(experiment)
    keys = params(table)
    estimators = list(dict.fromkeys(table["estimator"].to_pylist()))
    metrics = list(dict.fromkeys(r["metric"] for r in rows))
    runs = len(set(table["run"].to_pylist()))
    version, commit = table["version"][0].as_py(), table["git_commit"][0].as_py()
    lines = [f"**sweep of {experiment}** ({table['scenario'][0].as_py()}): {len(set(table['cell'].to_pylist()))} "
             f"cell(s) x {runs} run(s), seed {table['seed'][0].as_py()}; workbench {version}, commit {commit[:12]}",
             "", "Each entry: the mean over runs +- the half-width of its 95 % interval (Student's t).", ""]
    if manifest and manifest.get("fixed"):
        lines += ["Fixed: " + ", ".join(f"{k} = {v}" for k, v in manifest["fixed"].items()), ""]
    by = {(r["cell"], r["estimator"], r["metric"]): r for r in rows}
    cells = sorted({(r["cell"], tuple(r[k] for k in keys)) for r in rows})
    for metric in headline(experiment, metrics):
        unit = next((r["unit"] for r in rows if r["metric"] == metric), "")
        lines += [f"### {metric}" + (f" ({unit})" if unit else ""), "",
                  "| " + " | ".join([*keys, *estimators]) + " |", "|" + "---|" * (len(keys) + len(estimators))]
        for cell, values in cells:
            cols = []
            for name in estimators:
                r = by.get((cell, name, metric))
                cols.append("-" if r is None else f"{_num(r['mean'])} +- {_num((r['ci95_hi'] - r['ci95_lo']) / 2)}"
                            + (f" ({r['failed_runs']} failed)" if r["failed_runs"] else ""))
            lines.append("| " + " | ".join([*map(str, values), *cols]) + " |")
        note = exp.paper_notes.get(metric) if exp is not None else None
        lines += ["", f"_{note}_"] if note else []
        lines.append("")
    others = [m for m in metrics if m not in headline(experiment, metrics) and m != "failed"]
    if others:
        lines += [f"Every metric ({', '.join(others)} too) is in summary.csv; the runs' rows in tasks/*.parquet."]
    return "\n".join(lines)


def marginals(table: pa.Table, key: str, metric: str) -> dict[str, tuple[list, np.ndarray, np.ndarray]]:
    """Per estimator, against the values of ``key``: the mean over every run of every cell with
    that value, and the half-width of its 95 % interval."""
    sub = table.filter(pc.and_(pc.equal(table["metric"], metric), pc.invert(table["failed"])))
    values = sorted(set(sub[f"p.{key}"].to_pylist()), key=lambda v: (isinstance(v, str), v))
    out = {}
    for name in dict.fromkeys(sub["estimator"].to_pylist()):
        mine = sub.filter(pc.equal(sub["estimator"], name))
        col, val = mine[f"p.{key}"].to_pylist(), np.asarray(mine["value"].to_pylist(), float)
        means, halves = [], []
        for v in values:
            x = val[[c == v for c in col]]
            x = x[np.isfinite(x)]
            means.append(float(x.mean()) if x.size else np.nan)
            halves.append(t95(x.size) * float(x.std(ddof=1)) / math.sqrt(x.size) if x.size > 1 else np.nan)
        out[name] = (values, np.array(means), np.array(halves))
    return out


def colors(experiment: str, names: list[str]) -> dict[str, tuple[int, int, int]]:
    """The estimators' colours from their experiment's table; a fixed cycle for the others."""
    exp = _experiment(experiment)
    table = exp.estimators if exp is not None else {}
    out, spare = {}, iter(FALLBACK * 4)
    for name in names:
        out[name] = table[name].color if name in table else next(spare)
    return out


def plots(table: pa.Table, folder: Path) -> list[Path]:
    """A PNG per headline metric and swept setting."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    experiment = table["experiment"][0].as_py()
    metrics = list(dict.fromkeys(table["metric"].to_pylist()))
    written = []
    rgb = colors(experiment, list(dict.fromkeys(table["estimator"].to_pylist())))
    units = dict(zip(table["metric"].to_pylist(), table["unit"].to_pylist(), strict=True))
    for key in params(table):
        for metric in headline(experiment, metrics):
            curves = marginals(table, key, metric)
            fig, ax = plt.subplots(figsize=(7.2, 4.4), dpi=100)
            for name, (values, mean, half) in curves.items():
                numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
                x = values if numeric else list(range(len(values)))
                ax.errorbar(x, mean, yerr=half, marker="o", capsize=3, label=name,
                            color=np.array(rgb[name]) / 255.0)
                if not numeric:
                    ax.set_xticks(x, [str(v) for v in values])
            ax.set_xlabel(key)
            ax.set_ylabel(f"{metric} ({units.get(metric, '')})" if units.get(metric) else metric)
            ax.set_title(f"{experiment}: {metric} against {key} (mean over runs, 95 % interval)", fontsize=10)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8, loc="best")
            fig.tight_layout()
            path = folder / f"{metric}_vs_{key}.png"
            buf = io.BytesIO()
            fig.savefig(buf, format="png")
            plt.close(fig)
            stream.write_bytes_atomic(path, buf.getvalue())
            written.append(path)
    return written


INDEX = "value"
"""The recording's one timeline: the index of a swept setting's value (a viewer shows one
timeline at a time, so every view's curves are on the same one; the views name the values)."""


def recording(table: pa.Table, folder: Path, summary_md: str) -> Path:
    """``sweep.rrd``: per swept setting a tab, per headline metric a view of each estimator's
    mean against the setting's values (their index on the timeline ``value``, the values in
    the view's name); the summary as a text document."""
    import rerun as rr
    import rerun.blueprint as rrb


    experiment = table["experiment"][0].as_py()
    metrics = headline(experiment, list(dict.fromkeys(table["metric"].to_pylist())))
    rgb = colors(experiment, list(dict.fromkeys(table["estimator"].to_pylist())))
    values = {key: sorted(set(table[f"p.{key}"].to_pylist()), key=lambda v: (isinstance(v, str), v))
              for key in params(table)}
    tabs = []
    for key, vals in values.items():
        shown = ", ".join(f"#{i} {v}" for i, v in enumerate(vals))
        tabs.append(rrb.Vertical(*[rrb.TimeSeriesView(origin=f"/sweep/{key}/{m}", name=f"{m} against {key} ({shown})")
                                   for m in metrics], name=f"against {key}"))
    tabs.append(rrb.TextDocumentView(origin="/summary", name="summary"))
    blueprint = rrb.Blueprint(rrb.Tabs(*tabs), collapse_panels=True)
    path = folder / "sweep.rrd"
    with stream.recording(path, f"{experiment}-sweep", {"sweep": str(folder)}, int(table["seed"][0].as_py()),
                          blueprint) as rec:
        for key, vals in values.items():
            for metric in metrics:
                for name, (_, mean, _) in marginals(table, key, metric).items():
                    entity = f"/sweep/{key}/{metric}/{name}"
                    rec.log(entity, rr.SeriesLines(colors=[rgb[name]], names=[name], widths=[2.0]), static=True)
                    rec.log(entity, rr.SeriesPoints(colors=[rgb[name]], marker_sizes=[4.0]), static=True)
                    ok = np.isfinite(mean)
                    if ok.any():
                        rec.send_columns(entity, indexes=[rr.TimeColumn(INDEX, sequence=np.flatnonzero(ok))],
                                         columns=rr.Scalars.columns(scalars=mean[ok]))
            rec.send_property(f"values_of_{key}", rr.AnyValues(values=[str(v) for v in vals]))
        rec.log("/summary", rr.TextDocument(summary_md, media_type=rr.MediaType.MARKDOWN), static=True)
    return path


def write(folder: Path) -> list[Path]:
    """Rebuild the whole report of a sweep folder from its Parquet files."""

    folder = Path(folder).expanduser()
    table = read(folder)
    rows = summarise(table)
    manifest = definition(folder)
    md = markdown(rows, table, manifest)
    stream.write_text_atomic(folder / "summary.csv", to_csv(rows))
    stream.write_text_atomic(folder / "summary.md", md)
    written = [folder / "summary.csv", folder / "summary.md"]
    written += plots(table, folder)
    written.append(recording(table, folder, md))
    exp = _experiment(table["experiment"][0].as_py())
    preset = {p.name: p for p in exp.presets}.get(manifest.get("preset")) if exp is not None else None
    if preset is not None and preset.report is not None:
        written += preset.report(table, folder, manifest)
    return written
