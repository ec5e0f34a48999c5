"""A tuning study's report, from its folder alone (the journal and the trials' Parquet files):
``best.toml`` (the best trial's values with the study's fixed settings: ``--config best.toml``
runs them), ``summary.md`` (the best trial, the objective's Monte Carlo error at it, the
parameters' importances, the leading trials), ``objective.png`` (the objective of every trial and
the best so far), ``param-<field>.png`` (the objective over each parameter) and ``study.rrd`` (the
same on a ``trial`` timeline, the summary beside)."""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from workbench.config import files as configfile
from workbench.core.registry import get
from workbench.recording import stream
from workbench.tuning import files
from workbench.tuning.objective import resolve


def _completed(study: Any) -> list:
    from optuna.trial import TrialState

    return sorted(study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,)), key=lambda t: t.number)


def best_values(manifest: dict, best: Any) -> dict[str, Any]:
    """What ``best.toml`` holds: the scenario, the study's fixed settings and the best values."""
    values = {"scenario": manifest["scenario"], **manifest["fixed"], **best.params}
    return {k: v for k, v in values.items() if v is not None}


def write(folder: Path) -> tuple[list[Path], dict]:
    """Write the report; the files written and the best trial (number, value, its error, params)."""
    folder = Path(folder)
    manifest, study, table = files.load(folder)
    done = _completed(study)
    if not done:
        md = f"# Tuning study: {manifest['experiment']}\n\nNo trial finished with a finite objective.\n"
        stream.write_text_atomic(folder / "summary.md", md)
        return [folder / "summary.md"], {}
    exp = get(manifest["experiment"])
    base = exp.configure(manifest["scenario"], seed=manifest["seed"], runs=manifest["runs"], **manifest["fixed"])
    objective = resolve(manifest["objective"], manifest["estimator"], exp.metrics(base))
    best = min(done, key=lambda t: (t.value, t.number))
    rows = table.filter(np.asarray(table["trial"].to_pylist()) == best.number) if table is not None else None
    _, se = objective.value(files.figures(rows, objective)) if rows is not None else (best.value, math.nan)
    fields = [p["field"] for p in manifest["space"]]
    importances = _importances(study, fields, len(done))
    written = []
    stream.write_text_atomic(folder / "best.toml", "# the best trial of the study in this folder: "
                             f"workbench {manifest['experiment']} --config best.toml\n"
                             + configfile.dumps_toml(best_values(manifest, best)))
    written.append(folder / "best.toml")
    md = markdown(manifest, objective, done, best, se, importances, base)
    stream.write_text_atomic(folder / "summary.md", md)
    written.append(folder / "summary.md")
    written += plots(folder, manifest, done)
    written.append(recording(folder, manifest, done, md))
    return written, {"trial": best.number, "value": best.value, "mc_error": se, "params": dict(best.params)}


def _importances(study: Any, fields: list[str], n: int) -> dict[str, float] | str:
    if len(fields) == 1:
        return {fields[0]: 1.0}
    if n < 4:
        return f"not computed: {n} finished trial(s), fewer than 4"
    import optuna

    try:
        return dict(optuna.importance.get_param_importances(study))
    except (RuntimeError, ValueError) as exc:  # e.g. a parameter never varied
        return f"not computed: {exc}"


def markdown(manifest: dict, objective: Any, done: list, best: Any, se: float,
             importances: dict[str, float] | str, base: Any) -> str:
    space = {p["field"]: p for p in manifest["space"]}
    lines = [f"# Tuning study: {manifest['experiment']} ({manifest['scenario']})", "",
             f"Objective: {manifest['objective']}, {objective.describe}; minimised over {len(done)} finished "
             f"trial(s) of {manifest['runs']} run(s) each (seed {manifest['seed']}; every trial the same runs).", "",
             f"**Best: trial {best.number}, objective {best.value:.6g}** (Monte Carlo standard error over its runs "
             + (f"{se:.3g}" if math.isfinite(se) else "n/a with one run")
             + "; trials share their runs, so their differences are far more precise than that).", "",
             "| setting | range | best | the config's (on a simulation: what made the data) |", "|---|---|---|---|"]
    for name, value in best.params.items():
        p = space[name]
        own = getattr(base, name.removeprefix("assume_"), None) if name.startswith("assume_") else None
        rng = f"{p['low']:g} .. {p['high']:g}{' (log)' if p['log'] else ''}"
        lines.append(f"| {p['key']} ({name}) | {rng} | {value:.6g} | {'' if own is None else f'{own:g}'} |")
    lines += ["", "Importances (fANOVA over the finished trials):", ""]
    if isinstance(importances, str):
        lines.append(importances)
    else:
        lines += [f"- {k}: {v:.2f}" for k, v in importances.items()]
    lines += ["", "Leading trials:", "", "| trial | objective | " + " | ".join(space) + " |",
              "|---|---|" + "---|" * len(space)]
    for t in sorted(done, key=lambda t: (t.value, t.number))[:10]:
        lines.append(f"| {t.number} | {t.value:.6g} | " + " | ".join(f"{t.params[k]:.4g}" for k in space) + " |")
    lines += ["", f"Apply: `workbench {manifest['experiment']} --config best.toml`; every trial's rows: "
              "trials/*.parquet."]
    return "\n".join(lines) + "\n"


def plots(folder: Path, manifest: dict, done: list) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([t.number for t in done])
    v = np.array([t.value for t in done])
    written = []
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(n, v, "o", ms=4, alpha=0.6, label="trial")
    ax.step(n, np.minimum.accumulate(v), where="post", lw=2, label="best so far")
    ax.set_xlabel("trial")
    ax.set_ylabel(f"objective ({manifest['objective']})")
    ax.legend()
    ax.grid(alpha=0.3)
    written.append(_save(fig, folder / "objective.png"))
    for p in manifest["space"]:
        x = np.array([t.params[p["field"]] for t in done])
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.scatter(x, v, c=n, cmap="viridis", s=18)
        k = int(np.argmin(v))
        ax.scatter([x[k]], [v[k]], marker="*", s=200, c="red", label=f"best {x[k]:.4g}")
        if p["log"]:
            ax.set_xscale("log")
        ax.set_xlabel(f"{p['key']} ({p['field']})")
        ax.set_ylabel(f"objective ({manifest['objective']})")
        ax.legend()
        ax.grid(alpha=0.3)
        written.append(_save(fig, folder / f"param-{p['field']}.png"))
    plt.close("all")
    return written


def _save(fig: Any, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    stream.write_bytes_atomic(path, buf.getvalue())
    return path


def recording(folder: Path, manifest: dict, done: list, summary_md: str) -> Path:
    """``study.rrd``: the objective and each parameter on a ``trial`` timeline, the summary beside."""
    import rerun as rr
    import rerun.blueprint as rrb

    n = np.array([t.number for t in done])
    v = np.array([t.value for t in done], float)
    views = [rrb.TimeSeriesView(origin="/objective", name=f"objective ({manifest['objective']})")]
    views += [rrb.TimeSeriesView(origin=f"/params/{p['field']}", name=p["key"]) for p in manifest["space"]]
    blueprint = rrb.Blueprint(rrb.Horizontal(rrb.Vertical(*views), rrb.TextDocumentView(origin="/summary",
                                                                                         name="summary")),
                              collapse_panels=True)
    path = folder / "study.rrd"
    with stream.recording(path, f"{manifest['experiment']}-tune", manifest, int(manifest["seed"]), blueprint) as rec:
        index = [rr.TimeColumn("trial", sequence=n)]
        rec.log("/objective/trial", rr.SeriesPoints(names=["trial"], marker_sizes=[3.0]), static=True)
        rec.send_columns("/objective/trial", indexes=index, columns=rr.Scalars.columns(scalars=v))
        rec.log("/objective/best", rr.SeriesLines(names=["best so far"], widths=[2.0]), static=True)
        rec.send_columns("/objective/best", indexes=index, columns=rr.Scalars.columns(scalars=np.minimum.accumulate(v)))
        for p in manifest["space"]:
            x = np.array([t.params[p["field"]] for t in done], float)
            rec.log(f"/params/{p['field']}", rr.SeriesPoints(names=[p["key"]], marker_sizes=[3.0]), static=True)
            rec.send_columns(f"/params/{p['field']}", indexes=index, columns=rr.Scalars.columns(scalars=x))
        rec.log("/summary", rr.TextDocument(summary_md, media_type=rr.MediaType.MARKDOWN), static=True)
    return path
