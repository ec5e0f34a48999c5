"""The results tables' markdown, one helper for every experiment: a number as a table writes it,
a table from a header and rows, and the metrics' table (a row per estimator, a column per
metric, from the metrics JSON's one shape, :mod:`.metric`): a plugin's metric gets its column
without a line written for it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from workbench.metrics import diagnosis


def number(x: float | None, fmt: str = ".2f") -> str:
    """``x`` in ``fmt``; ``-`` where there is none (None, NaN)."""
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return f"{x:{fmt}}"


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    """Markdown lines of a table (also readable as plain text)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def metric_columns(stats: Mapping, builtin: Sequence[Any], columns: Sequence[str]) -> list[tuple[str, str, str]]:
    """The metrics' table columns: ``(metric, title, format)`` for ``columns`` (the experiment's
    choice of its ``builtin`` metrics) and every plugin metric the metrics JSON describes."""
    known = {m.name: m for m in builtin}
    described = stats.get("metric_table", {})
    out = [(n, known[n].title, known[n].fmt) for n in columns if n in known]
    for name, d in described.items():
        if d.get("source", "built-in") != "built-in" and name not in columns:
            out.append((name, name + (f" {d['unit']}" if d.get("unit") else ""), ".3g"))
    return out


def metric_table(stats: Mapping, builtin: Sequence[Any], columns: Sequence[str], spread: bool = False) -> list[str]:
    """A row per estimator, a column per metric (:func:`metric_columns`); ``spread``: each figure
    with its spread over runs (``+- <metric>_std``) where there is one and more than one run."""
    cols = metric_columns(stats, builtin, columns)
    runs = stats.get("runs", 1)
    rows = []
    diagnosed = any(e.get("diagnosis") for e in stats["estimators"].values())
    for name, e in stats["estimators"].items():
        cells = [name]
        for key, _, fmt in cols:
            cell = number(e.get(key), fmt)
            std = e.get(f"{key}_std")
            if spread and runs > 1 and std is not None and cell != "-":
                cell += f" +- {std:.2f}"
            cells.append(cell)
        rows.append(cells + ([diagnosis.line(e.get("diagnosis")) or "-"] if diagnosed else []))
    return table(["estimator", *(title for _, title, _ in cols), *(["diagnosis (no truth)"] if diagnosed else [])],
                 rows)


def bounds_table(stats: Mapping, quantities: Sequence[tuple[str, str, str, str]]) -> list[str]:
    """Markdown lines: each estimator's bound kind, its bounds and efficiencies (+- their Monte
    Carlo standard errors) for ``quantities`` ((quantity, unit, bound metric, efficiency metric),
    ...); a note naming any estimator below its bound by more than three standard errors (it
    cannot be, on these data)."""
    rows = [(n, e) for n, e in stats["estimators"].items() if any(b in e for _, _, b, _ in quantities)]
    if not rows:
        return []
    head = ["estimator", "held to"]
    for q, u, _, _ in quantities:
        head += [f"{q} bound {u}", "efficiency"]
    out = ["**Cramér-Rao bounds**: efficiency = RMSE / bound (1: as good as any estimator can be on these data; "
           "+- its Monte Carlo standard error); a causal estimator is held to the filtering bound, a smoother to "
           "the smoothing bound", ""]
    body, below = [], []
    for name, e in rows:
        cells = [name, e.get("bound_kind") or _held_to(stats, name)]
        for q, _, b, f in quantities:
            cells += [f"{e[b]:.3g}" if e.get(b) is not None else "", _efficiency(e, f)]
            if _below(e, f):
                below.append(f"{name} ({q})")
        body.append(cells)
    out += table(head, body)
    if below:
        out += ["", "**Below the bound**, beyond the Monte Carlo error: " + ", ".join(below)
                + ". No estimator can be on these data: it knows more than them (the truth?) or the bound's "
                  "model is not the data's; check it."]
    return out + [""]


def _held_to(stats: Mapping, name: str) -> str:
    """The bound an estimator is held to by its table row (an experiment may say it otherwise)."""
    row = stats.get("estimator_table", {}).get(name)
    if row is None:
        return ""
    if row.get("lag_seconds") is not None:
        return f"fixed-lag {row['lag_seconds']:g} s"
    return "filtering" if row.get("causal") else "smoothing"


def _below(e: Mapping, key: str) -> bool:
    """An efficiency under 1 by more than three of its standard errors (none without them: one
    run's error is one draw, as likely small as large)."""
    eff, se = e.get(key), e.get(f"{key}_se")
    return eff is not None and se is not None and np.isfinite(eff) and eff + 3 * se < 1.0


def _efficiency(e: Mapping, key: str) -> str:
    eff, se = e.get(key), e.get(f"{key}_se")
    if e.get(f"{key}_note"):
        return "none: bound near zero"
    if eff is None or not np.isfinite(eff):
        return ""
    return f"{eff:.2f}" + (f" +- {se:.2f}" if se is not None else "") + (" (below!)" if _below(e, key) else "")


def default_table(stats: Mapping, metrics: Sequence[Any], columns: tuple[str, ...] = (),
                  bounds: tuple[tuple[str, str, str, str], ...] = ()) -> str:
    """The metrics' table (``columns``, or every metric but the bounds and efficiencies) and the
    bounds' (``bounds``: quantity, unit, bound metric, efficiency metric)."""
    shown = columns or tuple(m.name for m in metrics if m.efficiency is None and not m.name.endswith("_bound"))
    lines = [f"**{stats['experiment']} / {stats['scenario']}** ({stats.get('label', '')}), {stats['runs']} run(s), "
             f"seed {stats['seed']}", ""]
    lines += metric_table(stats, metrics, shown, spread=True)
    bands = [f"{m.name}: 95 % band {lo:.2f}-{hi:.2f}" for m in metrics
             if m.dimension and (band := stats.get("metric_table", {}).get(m.name, {}).get("band"))
             for lo, hi in [band]]
    if bands:
        lines += ["", "; ".join(bands)]
    return "\n".join(lines + [""] + verdicts(stats) + bounds_table(stats, bounds))


def verdicts(stats: Mapping) -> list[str]:
    """Each estimator's consistency, without the truth (its innovations' NIS and whiteness, its
    disagreement with the smoother) and with it (its NEES): each test's figure against its band or
    limit, and the verdict (``consistent_without_truth``, ``consistent_with_truth``)."""
    described = stats.get("metric_table", {})
    lines = []
    for name, e in stats["estimators"].items():
        parts = []
        for free, key, what in ((True, "consistent_without_truth", "without truth"),
                                (False, "consistent_with_truth", "with truth")):
            if e.get(key) is None:
                continue
            tests = [_test(m, e) for m, d in described.items()
                     if d.get("truth_free", False) == free and e.get(f"{m}_consistent") is not None]
            if free and (e.get("diagnosis") or {}).get("consistent") is not None:
                tests.append(f"the diagnosis: {diagnosis.line(e['diagnosis'])}")   # it joins the verdict
            parts.append(f"{what} {'consistent' if e[key] else '**not consistent**'} ({'; '.join(tests)})")
        found = e.get("diagnosis")
        if found:
            parts.insert(0, f"diagnosis **{diagnosis.line(found)}**: {found['reason']}")
        if parts:
            lines.append(f"- {name}: " + "; ".join(parts))
    if not lines:
        return []
    wrong = [n for n, e in stats["estimators"].items()
             if (e.get("diagnosis") or {}).get("verdict") in ("too narrow", "too wide", "outliers")]
    if wrong and not stats.get("tuned_noise"):
        lines.append(f"- the noise assumed does not fit the data for {', '.join(wrong)}: `--tune-noise` estimates it "
                     "from the data (the EKF's likelihood, cross-validated, with intervals; README, Self-tuned runs)")
    return ["**Consistency**: the diagnosis without truth (every measurement handed counted, the ones left out "
            "too: docs/diagnosis.md), then each test at 95 %: without truth, the filters' innovations (NIS, "
            "whiteness) and each causal estimator against the smoother; with truth, the NEES", "", *lines, ""]


def _test(metric: str, e: Mapping) -> str:
    value, band = e[metric], e.get(f"{metric}_band")
    if band is not None:
        where = "in" if band[0] <= value <= band[1] else ("above" if value > band[1] else "below")
        return f"{metric} {value:.3g} {where} {band[0]:.3g}-{band[1]:.3g}"
    return f"{metric} {value:.3g}" + (" within its limit" if e[f"{metric}_consistent"] else " over its limit")
