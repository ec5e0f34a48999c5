"""What ``--tune-noise`` prints: its report (:func:`workbench.core.selftune.tune_noise`) as lines."""

from __future__ import annotations

import math

from workbench.core.selftune import SPAN


def _band(lo: float, hi: float) -> str:
    return "no interval" if not (math.isfinite(lo) and math.isfinite(hi)) else f"95 % {lo:.3g}-{hi:.3g}"


def lines(report: dict) -> list[str]:
    """The report as the command prints it."""
    said = []
    for k, v in report["tuned"].items():
        lo, hi = report.get("interval", {}).get(k, (math.nan, math.nan))
        kept = not report.get("held_out", {}).get("generalises", True)
        mark = (", holds the start: kept" if k in report.get("not_rejected", ())
                else "" if report.get("identified", {}).get(k, True) or kept
                else ", not identified by these data: kept")
        said.append(f"{k.replace('_', '-')} {report['start'][k]:.4g} -> {v:.4g} ({_band(lo, hi)}{mark})")
    out = [f"tuned noise (the likelihood of {report['filter']}'s innovations on run 0, {report['evaluations']} "
           f"evaluations, {report['seconds']:.1f} s{'' if report['converged'] else ', not converged'}): "
           + "; ".join(said) + f"; NLL {report['nll_start']:.1f} -> {report['nll_tuned']:.1f}"]
    held = report.get("held_out")
    if held and held["measurements"]:
        first = report["first_part"]
        verdict = ("the tuned noise generalises" if held["nll_tuned"] < held["nll_start"]
                   else "NOT better: the tuned noise does not generalise, so nothing is told")
        out.append(f"cross-validated: tuned on the first {first['measurements']} measurements, the other "
                   f"{held['measurements']}'s predictive NLL {held['nll_start']:.1f} at the start -> "
                   f"{held['nll_tuned']:.1f} tuned ({verdict})")
    sm = report.get("smoother")
    if sm and sm.get("values"):
        said = "; ".join(f"{k.replace('_', '-')} {v:.4g} ({_band(*sm['interval'][k])})"
                         for k, v in sm["values"].items())
        state = "" if sm["settled"] else ", stopped: the iteration ran away" if sm.get("diverged") else ", not settled"
        out.append(f"{sm['smoother']}'s own evidence (variance components of its residuals, {sm['runs']} runs"
                   f"{state}): {said}"
                   + (f"; DISAGREES with the filter's on {', '.join(k.replace('_', '-') for k in sm['disagree'])}"
                      if sm["disagree"] else "; agrees with the filter's within their intervals"
                      if sm.get("compared") else "; the filter's values have no interval to compare with"))
    elif sm:
        out.append(f"{sm['smoother']}'s own evidence: none ({sm['failed']})")
    if report.get("contradicted"):
        out.append(f"nothing told: the smoother's evidence and the filter's differ by more than a factor {SPAN:g} on "
                   + ", ".join(k.replace("_", "-") for k in report["contradicted"])
                   + " (one of them is wrong, and the data cannot say which)")
    if report.get("not_told"):
        out.append("not told (kept at the start): " + ", ".join(k.replace("_", "-") for k in report["not_told"])
                   + ": the filter's and the smoother's evidence disagree beyond their intervals")
    if report.get("not_rejected"):
        out.append("not told (kept at the start): " + ", ".join(k.replace("_", "-") for k in report["not_rejected"])
                   + ": every identified value's 95 % interval holds its start, so the data do not reject it")
    out += [f"not tuned: {k.replace('_', '-')}: {why}" for k, why in report["left"].items()]
    return out
