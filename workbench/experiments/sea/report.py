"""The results table: Table 2's columns per estimator (mean +- spread over runs), the
paper's rows beside ours, and the scenario's extra figures."""

from __future__ import annotations

import numpy as np

from workbench.experiments.sea.metrics import BOUNDS, METRICS, TABLE
from workbench.experiments.sea.paper import TABLE2
from workbench.metrics import tables as markdown


def table(stats: dict) -> str:
    """Markdown (also readable as plain text)."""
    runs = stats["runs"]
    cols = markdown.metric_columns(stats, METRICS, TABLE)
    lines = [f"**sea / {stats['scenario']}** ({stats.get('label', '')}), {runs} run(s), "
             f"seed {stats['seed']}; mean +- std over runs", ""]
    rows = []
    im = stats.get("images")
    if im is not None:
        angles = {f"{g}_{q}": (im[g][q], im[f"{g}_std"][q]) for g in ("rmse", "bias") for q in ("alpha", "beta")}
        rows.append(["image stage (angles)", *(_pm(*angles[k], runs) if k in angles else "" for k, _, _ in cols)])
        cfg = stats["config"]
        noise = {"rmse_alpha": f"{cfg['sigma_alpha_arcmin']:g}", "rmse_beta": f"{cfg['sigma_beta_arcmin']:g}",
                 "bias_alpha": "0", "bias_beta": "0"}
        rows.append(["simulated angles (noise)", *(noise.get(k, "") for k, _, _ in cols)])
    tag = " (images)" if im is not None else ""
    for name, e in stats["estimators"].items():
        rows.append([f"{name}{tag}", *(_cell(e, k, fmt, runs) for k, _, fmt in cols)])
    for name, e in stats.get("simulated", {}).get("estimators", {}).items():
        rows.append([f"{name} (simulated)", *(_cell(e, k, fmt, runs) if k != "seconds" else "" for k, _, fmt in cols)])
    if stats["scenario"] in ("paper", "track-loss", "impulse"):
        for name, row in TABLE2.items():
            rows.append([f"paper: {name}", *(f"{row[k.split('_')[0]][k.split('_')[1]]:g}"
                                             if k.split("_")[0] in ("rmse", "bias") else "" for k, _, _ in cols)])
    lines += markdown.table(["estimator", *(title for _, title, _ in cols)], rows)
    extra = []
    for name, e in stats["estimators"].items():
        bits = [f"position rmse {e['position_rmse']:.2f} m" if e.get("position_rmse") is not None
                else "no truth: no errors"]
        if (e.get("coverage") or 1.0) < 1.0:
            bits.append(f"estimates {100 * e['coverage']:.0f} % of steps")
        if e.get("anees") is not None:
            lo, hi = e["anees_band"]
            bits.append(f"ANEES {e['anees']:.2f} (95 % band {lo:.2f}-{hi:.2f})")
        if "recovery" in e:
            r = e["recovery"]
            state = "" if r["settled"] else ", not settled by the end"
            bits.append(f"impulse transient {r['seconds']:.1f} s above {r['level_arcmin']:.2f}'{state}")
        if "forecast" in e:
            bits.append(_forecast(e["forecast"]))
        if "rmse_during_loss" in e:
            r = e["rmse_during_loss"]
            bits.append(f"during the loss rmse x {r['x']:.1f} m, y {r['y']:.1f} m")
        extra.append(f"- {name}: " + "; ".join(bits))
    if im is not None:
        w, h = im["size"]
        fps = im["frames_per_second"]
        reasons = ", ".join(f"{k} {v}" for k, v in im["no_detection"].items()) or "none"
        extra.append(
            f"- image stage ({w}x{h}, {im['arcmin_per_px']:.2f}' per px, pan {im['pan_deg']:g} deg): "
            f"detected {100 * im['detection_rate']:.1f} % of {im['visible_frames']} frames in view, "
            f"{im['false_detections']} false; waterline rmse u {im['rmse_px']['u']:.3f} px, "
            f"v {im['rmse_px']['v']:.3f} px (bias {im['bias_px']['u']:.3f}, {im['bias_px']['v']:.3f}); "
            f"horizon rmse {_num(im['horizon']['rmse_px'])} px; detection {fps['detect']:.0f} frames/s "
            f"({fps['render_and_detect']:.0f} with rendering); no detection: {reasons}")
    if stats.get("data_repairs"):
        extra += ["", "Reading the data: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                       for k, v in stats["data_repairs"].items())]
    body = "\n".join(lines + [""] + markdown.verdicts(stats) + markdown.bounds_table(stats, BOUNDS) + extra)
    if "ships" in stats:
        return ships_table(stats) + "\n\nEvery ship's runs pooled:\n\n" + body
    return body


def _cell(e: dict, key: str, fmt: str, runs: int) -> str:
    """A figure of Table 2 with its spread over runs (``+- <key>_std``) where there is one."""
    if e.get(key) is None:
        return "-"
    if key == "seconds":
        return f"{e[key]:{fmt}}"
    std = e.get(f"{key}_std")
    return _pm(e[key], std, runs) if std is not None else f"{e[key]:{fmt}}"  # (a metric pooled over runs: no spread)


def ships_table(stats: dict) -> str:
    """``--mmsi all``: a row per ship (each estimator's position RMSE, m, the mean over the ship's
    runs), the median and the worst ship, and the ships skipped with the reason."""
    ships, over, skipped = stats["ships"], stats["over_ships"], stats["ships_skipped"]
    names = list(over)
    per = next(iter(ships.values()))["runs"] if ships else 0
    lines = [f"**sea / ais, every ship**: {len(ships)} ship(s) run ({per} run(s) each, seed {stats['seed']}), "
             f"{len(skipped)} skipped; position RMSE, m", "",
             "| MMSI | segment | " + " | ".join(names) + " |", "|" + "---|" * (len(names) + 2)]
    for mmsi, s in ships.items():
        segment = s["label"].split(", ", 1)[1] if ", " in s["label"] else s["label"]
        lines.append(f"| {mmsi} | {segment} | "
                     + " | ".join(_m(s["estimators"][n]["position_rmse"]) for n in names) + " |")
    lines.append("| **median over ships** | | " + " | ".join(
        _m(over[n]["position_rmse"]["median"]) for n in names) + " |")
    lines.append("| **worst ship** | | " + " | ".join(
        f"{_m(over[n]['position_rmse']['worst'])} ({over[n]['position_rmse']['worst_mmsi']})" for n in names) + " |")
    if skipped:
        lines += ["", f"Skipped ({len(skipped)}): " + "; ".join(f"{m} ({why})" for m, why in skipped.items())]
    return "\n".join(lines)


def _num(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def _m(x: float | None) -> str:
    """Metres for the ships' table: 3 significant digits under 10, one decimal above."""
    if x is None or not np.isfinite(x):
        return "n/a"
    return f"{x:.3g}" if abs(x) < 10 else f"{x:.1f}"


def _forecast(f: dict) -> str:
    """Median and 90th percentile of the l-step forecast errors, and the unusable count."""
    head = f"{f['steps']}-step ({f['seconds_ahead']:g} s) forecast:"
    parts = []
    if "alpha" in f:
        a, b = f["alpha"], f["beta"]
        parts.append(f"angle error median {a['median_abs']:.2f}' / {b['median_abs']:.2f}' "
                     f"(alpha / beta; 90 % under {a['p90_abs']:.1f}' / {b['p90_abs']:.1f}')")
    p = f["position"]
    if p["median"] is not None:
        text = f"position error median {p['median']:.1f} m (90 % under {p['p90']:.1f} m"
        if not f["unusable"] and None not in p["rmse"].values():
            text += f"; rmse x {p['rmse']['x']:.1f} m, y {p['rmse']['y']:.1f} m"
        parts.append(text + ")")
    if "alpha" in f:
        parts.append(f"{f['unusable']} of {f['count']} unusable (beta <= 0)")
    return head + " " + ", ".join(parts)


def _pm(mean: float, std: float, runs: int) -> str:
    fmt = ".3g" if abs(mean) < 0.1 else ".2f"
    return f"{mean:{fmt}}" + (f" +- {std:.2f}" if runs > 1 else "")
