"""One truth-free diagnosis per estimator, with its figures and a reason, that gating cannot fool.

Each run's estimate gives its **evidence** (:func:`evidence`): a filter's innovations of every
measurement it was handed (:class:`~workbench.estimation.consistency.Innovations`, the ones its
gate left out with the innovation they were judged on), a least-squares smoother's residuals at
its answer by group (:class:`~workbench.estimation.consistency.Residuals`), the whiteness of the
innovations and a causal estimator's disagreement with the run's smoother. The runs' evidence is
pooled and read (:func:`diagnose`), in this order:

1. **not enough data to say**: fewer than :data:`MIN_ROWS` measurements with a figure; **undecided**,
   whatever the figures, where the estimate says its data did not choose between two answers far
   apart (``undecided``: the batch's, :mod:`workbench.experiments.omni.algorithms.graph.undecided`);
2. **outliers / heavy tails**: a heavy tail the likelihood ratio keeps (p < :data:`ALPHA`), holding
   at least :data:`TAIL_FIRST` and at most :data:`OUTLIER_MAX` of the measurements (a larger one is
   the noise being wrong), with the share beyond the gate against the Gaussian's and the core's
   factors beside it (outliers bend a smoother: its odometry then looks too narrow too); a tail
   of :data:`TAIL_SHARE` to :data:`TAIL_FIRST` is the verdict after 3-5 below;
3. **noise assumed too narrow**, by what factor (sigma) and which group: the maximum
   likelihood of the noise's variance factor over every measurement handed, those the gate left
   out too (:mod:`~workbench.estimation.noisefit`); for a filter the state's (motion noise) and the
   measurement noise's apart where the innovations' shares tell them apart; for a smoother each
   group's variance component (Förstner 1979) from its residuals and redundancy. A factor counts
   where its 95 % interval leaves out 1 and it is beyond :data:`TOLERANCE`;
4. **wrong basin**: a causal estimator the run's smoother contradicts far beyond both their
   covariances (the median of ``d' (P_f + P_s)^-1 d``, no larger than chi-square with the state's
   dimension for a consistent pair, over its 99.9 % point: most of the run beyond 4 sigma;
   Bar-Shalom, Li, Kirubarajan, sec. 5.4), where the noise is not too narrow (that explains it);
5. **noise assumed too wide**, as 3;
6. **left out**: more measurements left out (gated, failed) than the estimator's own gate expects
   (a binomial test at :data:`ALPHA`) that nothing above explains;
7. **correlated innovations**: the whiteness test fails (a model error a scale does not mend);
8. **consistent**.

With ``--bootstrap B`` (:mod:`.bootstrap`), the covariance is checked too: the estimator's NEES on
datasets simulated from the run's own answer, in its band or not (``covers``). A noise that fits
with a NEES over its band is **overconfident** (under it, **conservative**); beside any other
verdict, the line says whether the covariance still covers the error (:func:`.bootstrap.into_diagnosis`).

The verdict is the first that holds; its figures are all given (``estimators.<name>.diagnosis``
of the metrics JSON). Readings taken: the innovations are treated as independent in the
intervals (they are not where the model is wrong), so a factor needs a size as well as a
significance to count; a left-out measurement with no innovation is censored at the gate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats as sstats

from workbench.estimation import noisefit
from workbench.estimation.consistency import MISS_SIGMAS, Innovations, Residuals
from workbench.estimation.metrics import chi2_quantile
from workbench.metrics import bootstrap
from workbench.metrics.truthfree import WHITE_MAX

MIN_ROWS = 30
"""Fewer measurements with a figure than this: not enough data to say."""
TOLERANCE = 1.25
"""A noise factor (on the sigma) within ``1/TOLERANCE .. TOLERANCE`` is not reported as wrong: a
quarter on the sigma is about the smallest change a tuning acts on, and the intervals, which
treat the innovations as independent, are narrower than the truth beneath it."""
TAIL_FIRST = 0.03
"""A tail holding at least this share (three times what a 99 % gate drops) is the verdict before the
noise's factors: outliers bend a smoother, and its odometry then looks too narrow too. A smaller
one is named after them, in the reason."""
OUTLIER_MAX = 0.25
"""A tail holding more than this share is not read as outliers (a minority the model does not
explain) but as the noise itself being wrong: the core's factor then decides."""
TAIL_SHARE = 0.01
"""A heavy tail is reported where it holds at least this share of the measurements (and more
than the gate expects to leave out): a smaller one is a few misreads, which a 99 % gate is for."""
UNIDENTIFIED = 10.0
"""A group's factor whose 95 % interval spans more than this ratio is reported as not identified by
the data (the innovations' shares hardly vary, or the group has no redundancy)."""
ALPHA = 1e-3
"""The significance of the tail's likelihood-ratio test and of the left-out share's binomial test."""
BASIN = 0.999
"""A causal estimator is in another basin than the smoother where its median disagreement is over
this point of its chi-square."""
VERDICTS = ("consistent", "overconfident", "conservative", "too narrow", "too wide", "outliers", "wrong basin",
            "left out", "correlated", "not enough data", "undecided")


@dataclass
class Evidence:
    """One estimator's truth-free evidence (one run's, or the runs' pooled): ``q`` the normalised
    squared innovation or residual of every measurement handed (NaN: none), ``dof`` its dimension,
    ``kept`` whether the estimator used it, ``share`` each innovation's share that is the state's
    uncertainty (filters), ``censor`` the gate's chi-square point where a left-out one has no
    figure, ``gate`` the gate's probability, ``groups`` a smoother's ``group -> (sum r2, redundancy,
    rows)``, ``whiteness`` the runs' whiteness figures, ``disagreement`` a causal estimator's
    against the smoother with its ``dimension``."""

    kind: str
    q: np.ndarray
    dof: np.ndarray
    kept: np.ndarray
    share: np.ndarray | None = None
    censor: np.ndarray | None = None
    gate: float | None = None
    groups: dict[str, tuple[float, float, int]] = field(default_factory=dict)
    whiteness: list[float] = field(default_factory=list)
    disagreement: np.ndarray | None = None
    dimension: int = 0
    unmapped: list[float] = field(default_factory=list)  # [measurements of what the map does not hold, all]
    iterated: list[dict[str, float]] = field(default_factory=list)  # each run's iterated variance components
    remarks: list[str] = field(default_factory=list)  # what the estimator says went wrong (each run's, once)
    undecided: list[dict] = field(default_factory=list)  # each run's choice its data did not make ("said": in words)


def _censor(kept: np.ndarray, q: np.ndarray, dof: np.ndarray, gate: float | None) -> np.ndarray:
    out = np.full(len(q), np.inf)
    if gate:
        lost = ~kept & ~np.isfinite(q)
        out[lost] = [chi2_quantile(gate, int(m)) for m in dof[lost]] if lost.any() else []
    return out


def from_innovations(innov: Innovations) -> Evidence:
    """A filter's evidence: the NIS of every measurement it was handed (gated ones too, where the
    filter kept their innovation)."""
    q = innov.nis_all()
    dof = np.full(len(q), innov.dimension)
    kept = innov.used
    return Evidence("innovations", q, dof, kept, innov.state_share(), _censor(kept, q, dof, innov.gate), innov.gate)


def from_residuals(res: Residuals) -> Evidence:
    """A smoother's evidence: its measurements' residuals (the ``measurement`` group's), each used
    one studentised by its group's redundancy share (its expectation at a consistent answer is
    then its dimension), each one left out as it is (a prediction's residual, at least as wide);
    and every group's variance component."""
    q = res.r2.copy()
    groups = {}
    for g in dict.fromkeys(res.group.tolist()):
        mine = res.group == g
        used = mine & res.used & np.isfinite(res.r2)
        red = res.redundancy.get(g, 0.0)
        n = float(res.dof[used].sum())
        if n > 0 and red > 0:
            q[used] = res.r2[used] / (red / n)
        groups[g] = (float(res.r2[used].sum()), red, int(used.sum()))
    rows = res.group == res.measurement
    return Evidence("residuals", q[rows], res.dof[rows], res.used[rows], None,
                    _censor(res.used[rows], res.r2[rows], res.dof[rows], res.gate), res.gate, groups)


def evidence(estimate: Any, metrics: Mapping[str, Any] | None = None, dimension: int = 0,
             residual: str | None = None) -> Evidence | None:
    """One run's evidence of an estimate: its ``residuals`` (a smoother) or ``innovations`` (a
    filter), else the experiment's ``residual`` metric where it has its dof (normalised squared
    residuals of an estimate with a covariance), with the run's whiteness and its gap to the
    smoother (``metrics``: the estimator's metric -> :class:`~.metric.Values`; ``smoother_gap``,
    chi-square with ``dimension``); None where there is none."""
    metrics = metrics or {}
    res = getattr(estimate, "residuals", None)
    innov = getattr(estimate, "innovations", None)
    r = metrics.get(residual) if residual else None
    if isinstance(res, Residuals) and len(res.r2):
        ev = from_residuals(res)
    elif isinstance(innov, Innovations) and len(innov.t):
        ev = from_innovations(innov)
    elif r is not None and r.dof:
        q = np.asarray(r.values, float)
        ev = Evidence("residuals", q, np.full(len(q), r.dof), np.isfinite(q))
    else:
        return None
    ev.remarks = [str(r) for r in getattr(estimate, "remarks", None) or ()]
    ev.undecided = [u] if (u := getattr(estimate, "undecided", None)) else []
    if isinstance(res, Residuals) and (bad := res.contradicted()):
        # (a landmark's own bearings rejecting its place: :mod:`workbench.experiments.omni.placed`)
        ev.remarks.append(f"{len(bad)} of {len(res.missed())} landmarks rejected by their own measurements: most of "
                          f"each one's over {MISS_SIGMAS:g} sigma off its place (misread ids, or a wrong basin)")
    w = metrics.get("innovation_whiteness")
    if w is not None and np.isfinite(w.values).any():
        ev.whiteness = [float(np.nanmean(w.values))]
    u = metrics.get("unmapped")
    if u is not None and len(u.values):
        ev.unmapped = [float(np.sum(u.values)), float(len(u.values))]
    d = metrics.get("smoother_gap")
    if d is not None and dimension:
        ev.disagreement, ev.dimension = np.asarray(d.values, float), dimension
    return ev


def collect(metrics: list, estimates: Mapping[str, Any], samples: Mapping[str, Mapping[str, Any]]
            ) -> dict[str, Evidence]:
    """One run's evidence of every estimate (:func:`evidence`): ``metrics`` the run's metric rows
    (the ``disagreement`` one's dimension is the smoother gap's; one marked ``evidence`` is the
    residual read where an estimate has no innovations or residuals), ``samples`` their values."""
    dimension = next((m.dimension or 0 for m in metrics if m.name == "disagreement"), 0)
    residual = next((m.name for m in metrics if m.evidence), None)
    out = {}
    for name, est in estimates.items():
        ev = evidence(est, samples.get(name), dimension, residual)
        if ev is not None:
            out[name] = ev
    return out


def pool(items: list[Evidence]) -> Evidence | None:
    """The runs' evidence of one estimator as one."""
    items = [e for e in items if e is not None]
    if not items:
        return None

    def cat(name):
        parts = [getattr(e, name) for e in items]
        return None if any(p is None for p in parts) else np.concatenate(parts)

    groups: dict[str, tuple[float, float, int]] = {}
    for e in items:
        for g, (s, r, n) in e.groups.items():
            a = groups.get(g, (0.0, 0.0, 0))
            groups[g] = (a[0] + s, a[1] + r, a[2] + n)
    dis = [e.disagreement for e in items if e.disagreement is not None]
    unmapped = [sum(e.unmapped[i] for e in items if e.unmapped) for i in (0, 1)] if any(e.unmapped for e in items) \
        else []
    return Evidence(items[0].kind, cat("q"), cat("dof"), cat("kept"), cat("share"), cat("censor"), items[0].gate,
                    groups, [w for e in items for w in e.whiteness], np.concatenate(dis) if dis else None,
                    items[0].dimension, unmapped, [d for e in items for d in e.iterated],
                    list(dict.fromkeys(r for e in items for r in e.remarks)), [u for e in items for u in e.undecided])


def _outside(value: float | None, interval: tuple[float, float] | None) -> int:
    """+1 where a sigma factor is too narrow (over the tolerance, its interval above 1), -1 too
    wide, 0 neither."""
    if value is None or not np.isfinite(value):
        return 0
    lo, hi = interval if interval is not None else (value, value)
    if value > TOLERANCE and lo > 1.0:
        return 1
    if value < 1.0 / TOLERANCE and hi < 1.0:
        return -1
    return 0


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %" if x < 0.1 else f"{100 * x:.0f} %"


def diagnose(ev: Evidence | None, names: Mapping[str, str] | None = None) -> dict | None:
    """:func:`_diagnose`, with what the estimator says went wrong (``remarks``: iSAM2 given up)
    leading the reason and the line, and such an estimator never called consistent: its answer
    from there on is not the method's."""
    found = _diagnose(ev, names)
    if found is not None and ev.remarks:
        found["remarks"] = list(ev.remarks)
        found["reason"] = "; ".join(ev.remarks) + "; " + found["reason"]
        found["consistent"] = False
    if found is not None and ev.undecided:  # two answers fit alike, far apart: the data chose neither
        found.update(verdict="undecided", undecided=ev.undecided[0], consistent=None,
                     reason=f"{len(ev.undecided)} run(s): {ev.undecided[0]['said']}; " + found["reason"])
    return found


def _diagnose(ev: Evidence | None, names: Mapping[str, str] | None = None) -> dict | None:
    """The diagnosis of one estimator from its pooled evidence (the module's text): ``verdict``
    (one of :data:`VERDICTS`), ``consistent`` (whether the estimator is, whatever the data hold:
    "consistent", or "outliers" that its gate took out with its noise right otherwise), ``factor``
    (the sigma factor where the noise is wrong: over 1 too narrow), ``group``, ``reason`` (one
    line) and the figures. ``names``: what the groups are called in words (``{"state":
    "odometry"}``)."""
    if ev is None:
        return None
    names = {"state": "motion", "measurement": "measurement", **(names or {})}
    handed = len(ev.q)
    seen = np.isfinite(ev.q)
    cens = ~seen & np.isfinite(ev.censor) if ev.censor is not None else np.zeros(handed, bool)
    rows = int(seen.sum() + cens.sum())
    left = float(np.mean(~ev.kept)) if handed else 0.0
    expected = (1.0 - ev.gate) if ev.gate else 0.0
    out: dict[str, Any] = {"handed": handed, "left_out": left, "left_out_expected": expected, "rows": rows}
    if rows < MIN_ROWS:
        return {"verdict": "not enough data", "factor": None, "group": None,
                "reason": f"{rows} measurements with a figure (at least {MIN_ROWS} to say)", **out}
    n_left = int(round(left * handed))
    p_left = float(sstats.binom.sf(n_left - 1, handed, max(expected, 1e-3))) if n_left else 1.0
    out["left_out_p"] = p_left
    censor = np.where(cens, ev.censor, np.inf) if ev.censor is not None else None
    plain, heavy, p_tail = noisefit.tail_test(ev.q, ev.dof, ev.share, censor)
    # a tail is a minority the core does not explain: one fitted to more than OUTLIER_MAX is the
    # mixture taking up a noise that is wrong throughout (the Gaussian's factor then says how wrong)
    tailed = (heavy is not None and p_tail < ALPHA and max(TAIL_SHARE, expected) <= heavy.eps <= OUTLIER_MAX)
    best = heavy if tailed else plain
    if best is None:
        return {"verdict": "not enough data", "factor": None, "group": None, "reason": "no figure to fit", **out}
    out.update(noisefit.goodness_of_fit(ev.q, ev.dof, plain.k))
    out["scale"] = math.sqrt(best.k)
    out["tail_share"] = best.eps if tailed else 0.0
    out["tail_width"] = math.sqrt(best.c) if tailed else None
    out["tail_p"] = p_tail
    groups: dict[str, dict] = {}
    if best.a is not None:  # a filter: the state's share and the measurement noise's apart
        for key, v in (("state", best.a), ("measurement", best.b)):
            iv = best.intervals.get("a" if key == "state" else "b")
            groups[names.get(key, key)] = {"factor": math.sqrt(v),
                                           "interval": None if iv is None else [math.sqrt(iv[0]), math.sqrt(iv[1])]}
    groups.update(components(ev, names))  # a smoother: each group's variance component
    if not groups:  # one scale: a smoother's measurements, or innovations whose noise parts are not given
        iv = best.intervals.get("k")
        one = names["measurement"] if ev.kind == "residuals" else "all"
        groups[one] = {"factor": math.sqrt(best.k),
                       "interval": None if iv is None else [math.sqrt(iv[0]), math.sqrt(iv[1])]}
    out["groups"] = groups

    for g, v in groups.items():  # a smoother's components iterated by solving again (the bootstrap's): the size
        got = [d[g] for d in ev.iterated if d.get(g) is not None]
        if got:
            v["iterated"] = float(np.exp(np.mean(np.log(got))))
    for v in groups.values():
        iv = v["interval"]
        v["identified"] = identified(iv)
        if iv is not None and not v["identified"]:
            v["interval"] = None
    said = (f"{_pct(left)} of {handed} measurements left out, "
            + (f"{_pct(expected)} expected at its gate" if ev.gate else "no gate") + "; "
            + "; ".join((f"{g} x{v['factor']:.2f}" + (f" [{v['interval'][0]:.2f}-{v['interval'][1]:.2f}]"
                                                      if v["interval"] else "")
                         + (f" (x{v['iterated']:.2f} iterated)" if "iterated" in v else "")) if v["identified"] else
                        f"{g} not identified" for g, v in groups.items()))
    direction = {g: _outside(v["factor"], tuple(v["interval"])) if v["identified"] else 0 for g, v in groups.items()}
    if "gof_p" in out:
        said += (f"; the distribution against chi-square: p {out['gof_p']:.2g}, scaled by the fit's factor "
                 f"p {out['gof_scaled_p']:.2g} (Cramér-von Mises)")
    if ev.unmapped and ev.unmapped[1]:
        out["unmapped"] = ev.unmapped[0] / ev.unmapped[1]
        said += f"; {_pct(out['unmapped'])} of all the measurements of what its map does not hold (not counted)"
    if tailed:
        said += f"; a tail of {_pct(best.eps)} {math.sqrt(best.c):.0f}x wider"
    basin = None
    if ev.disagreement is not None and ev.dimension and np.isfinite(ev.disagreement).any():
        med = float(np.nanmedian(ev.disagreement))
        out["smoother_gap_median"] = med
        limit = chi2_quantile(BASIN, ev.dimension)
        if med > limit:
            basin = (f"the smoother contradicts it beyond both their covariances (median gap {med:.3g} against "
                     f"{limit:.3g}, the {100 * BASIN:g} % point of chi-square with {ev.dimension})")
            said = basin + "; " + said
    narrow = [g for g, d in direction.items() if d > 0]
    wide = [g for g, d in direction.items() if d < 0]
    # what the noise factors say beside a tail: each group's factor where it is out of tolerance, else None
    # (every group keyed: a replay compares the same keys)
    out["core"] = {g: groups[g]["factor"] if g in narrow + wide else None for g in groups}
    def outliers() -> dict:
        # the estimator is consistent where its gate took the tail out and its noise is right otherwise
        handled = not (narrow or wide) and left >= 0.5 * best.eps and basin is None
        return {"verdict": "outliers", "factor": None, "group": None, "consistent": handled,
                "reason": f"outliers or heavy tails: {_pct(left)} left out, {_pct(best.eps)} in a tail "
                          f"{math.sqrt(best.c):.0f}x wider than the noise"
                          + (" (its gate took them out: consistent on the rest)" if handled else "") + "; " + said,
                **out}

    if tailed and best.eps >= TAIL_FIRST:
        return outliers()
    if narrow:
        f = max(groups[g].get("iterated", groups[g]["factor"]) for g in narrow)
        return {"verdict": "too narrow", "factor": f, "group": ", ".join(narrow),
                "reason": f"noise assumed too narrow by about {f:.2g}x ({', '.join(narrow)}): " + said, **out}
    if basin is not None:
        return {"verdict": "wrong basin", "factor": None, "group": None, "reason": said, **out}
    if wide:
        f = min(groups[g].get("iterated", groups[g]["factor"]) for g in wide)
        return {"verdict": "too wide", "factor": f, "group": ", ".join(wide),
                "reason": f"noise assumed too wide by about {1 / f:.2g}x ({', '.join(wide)}): " + said, **out}
    if tailed:
        return outliers()
    excess = p_left < ALPHA and left > expected
    if excess:
        return {"verdict": "left out", "factor": None, "group": None,
                "reason": "more left out than its model expects: " + said, **out}
    if ev.whiteness and float(np.mean(ev.whiteness)) > WHITE_MAX:
        w = float(np.mean(ev.whiteness))
        return {"verdict": "correlated", "factor": None, "group": None,
                "reason": f"innovations not white ({w:.2f} of the lags outside their band, at most {WHITE_MAX}): "
                          "a model error no noise scale mends; " + said, **out}
    return {"verdict": "consistent", "factor": None, "group": None, "consistent": True, "reason": said, **out}


def components(ev: Evidence, names: Mapping[str, str]) -> dict[str, dict]:
    """A smoother's residual groups' variance components (Förstner 1979; one step, at the weights it
    was solved with): group (as ``names`` call it) -> ``factor`` (sigma), its 95 % ``interval``, ``rows``."""
    out = {}
    for g, (s, red, n) in ev.groups.items():
        vc = noisefit.variance_components(np.array([s]), red)
        if vc is not None:
            out[names.get(g, g)] = {"factor": math.sqrt(vc[0]), "interval": [math.sqrt(vc[1][0]), math.sqrt(vc[1][1])],
                                    "rows": n}
    return out


def identified(interval: Any) -> bool:
    """Whether a factor's 95 % interval says the data identify it (finite, positive, narrower than
    :data:`UNIDENTIFIED`)."""
    iv = interval
    return bool(iv is not None and np.isfinite(iv).all() and iv[0] > 0 and iv[1] / iv[0] < UNIDENTIFIED)


def attach(stats: dict, evidence: list[Mapping[str, Evidence]], names: Mapping[str, str] | None = None) -> None:
    """Each estimator's diagnosis from the runs' ``evidence`` (each run's estimator -> its
    :class:`Evidence`), pooled, into its entry of the metrics JSON (``diagnosis``);
    ``consistent_without_truth`` then also asks the diagnosis to be "consistent" (what the
    estimator left out counts), and ``left_out`` / ``left_out_expected`` are set from it."""
    for name, entry in stats["estimators"].items():
        found = diagnose(pool([run[name] for run in evidence if name in run]), names)
        if found is None:
            continue
        entry["diagnosis"] = found
        bootstrap.into_diagnosis(found, entry)
        entry["left_out"] = found["left_out"]
        entry["left_out_expected"] = found["left_out_expected"]
        found.setdefault("consistent", False if found["verdict"] != "not enough data" else None)
        if found["consistent"] is not None:
            entry["consistent_without_truth"] = bool(entry.get("consistent_without_truth", True)
                                                     and found["consistent"])


def line(d: Mapping | None) -> str:
    """A diagnosis in a few words (a table's cell, a recording's title)."""
    if not d:
        return ""
    text = ", ".join([*(r.split(":")[0] for r in d.get("remarks") or ()), _words(d)])
    if d.get("covers") is not None and d["verdict"] not in ("overconfident", "conservative"):
        text += f", bootstrap NEES {d['bootstrap_nees']:.1f} " + ("in band" if d["covers"] else "out of band")
    elif d.get("covers") is not None:
        text += f" (bootstrap NEES {d['bootstrap_nees']:.1f})"
    return text


def _words(d: Mapping) -> str:
    v = d["verdict"]
    if v in ("too narrow", "too wide") and d.get("factor"):
        f = d["factor"] if v == "too narrow" else 1.0 / d["factor"]
        return f"{v} x{f:.1f} ({d['group']})"
    if v == "outliers":
        core = ", ".join(f"{g} x{f:.1f}" for g, f in (d.get("core") or {}).items() if f is not None)
        return f"outliers {_pct(d.get('tail_share') or d['left_out'])}" + (f" ({core})" if core else "")
    if v == "left out":
        return f"left out {_pct(d['left_out'])}"
    return v
