"""The omni results table: errors after settling and over the whole run, the map, the
filter's own sigmas and its consistency, beside the paper's claims."""

from __future__ import annotations

from workbench.estimation import bounds

PAPER_CLAIMS = ("paper's claims (simulation): position error < 0.5 m, heading error < 1 deg; "
                "own standard deviations < 1 m and < 1 deg after settling; odometry drifts without bound")


def _f(x: float | None, fmt: str = ".2f") -> str:
    return "-" if x is None else f"{x:{fmt}}"


def table(stats: dict) -> str:
    """Markdown (also readable as plain text)."""
    lo, hi = stats["nees_band"]
    head = ("| estimator | pos rmse m | pos max m | head rmse deg | head max deg | map rmse m | "
            "sigma x/y max m | sigma head max deg | ANEES | landmarks | init s | s/run |")
    lines = [f"**omni / {stats['scenario']}** ({stats.get('label', '')}), {stats['runs']} run(s), "
             f"seed {stats['seed']}; errors after {stats['settle_seconds']:g} s, over all runs; "
             f"ANEES 95 % band {lo:.2f}-{hi:.2f}", "", head, "|" + "---|" * 12]
    for name, e in stats["estimators"].items():
        s = e["sigma"]
        sig_xy = None if s["x_max"] is None else max(s["x_max"], s["y_max"])
        lines.append(
            f"| {name} | {_f(e['rmse']['position'])} | {_f(e['max']['position'])} | {_f(e['rmse']['heading'])} "
            f"| {_f(e['max']['heading'])} | {_f(e['rmse']['map'])} | {_f(sig_xy)} | {_f(s['heading_max'])} "
            f"| {_f(e['anees'])} | {e['landmarks_initialised']:.1f} | {_f(e['init_seconds']['median'], '.1f')} "
            f"| {e['seconds']:.2f} |")
    lines += ["", "Whole run (including the first lap):"]
    for name, e in stats["estimators"].items():
        w, m = e["rmse_whole_run"], e["max_whole_run"]
        bits = [f"position rmse {_f(w['position'])} m, max {_f(m['position'])} m",
                f"heading rmse {_f(w['heading'])} deg, max {_f(m['heading'])} deg"]
        if e.get("rmse_aligned_whole_run"):
            a, r = e["rmse_aligned_whole_run"], e["alignment"]
            bits.append(f"after the best rigid alignment (evo -a) position rmse {_f(a['position'])} m, "
                        f"heading rmse {_f(a['heading'])} deg (the alignment: {_f(r['rotation_deg'])} deg, "
                        f"{_f(r['translation'])} m, rms over runs)")
        if e.get("rmse_smoothed_whole_run"):
            f = e["rmse_smoothed_whole_run"]
            bits.append(f"its whole trajectory as held at the end (smoothed) position rmse {_f(f['position'])} m, "
                        f"heading rmse {_f(f['heading'])} deg")
        if e.get("nees_inside_band") is not None:
            bits.append(f"mean NEES inside the band at {100 * e['nees_inside_band']:.0f} % of steps")
        if e["failures"]:
            bits.append(f"{e['failures']} rejected update(s)")
        if e.get("bearings_gated"):
            bits.append(f"{e['bearings_gated']} bearing(s) left out by the gate (misreads, outliers)")
        lines.append(f"- {name}: " + "; ".join(bits))
    if stats.get("data_repairs"):
        lines += ["", "Reading the log: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                      for k, v in stats["data_repairs"].items())]
    lines += [""] + bounds.table(stats, (("position", "m"), ("heading", "deg"), ("map", "m")))
    im = stats.get("images")
    if im:
        def pct(x: float | None) -> str:
            return "-" if x is None else f"{100 * x:.1f}"

        lines += ["", f"Image stage ({_f(im['image_size'], '.0f')} px round images, "
                  f"{_f(im['frames'], '.0f')} frames a run): bearing rmse {_f(im['bearing_rmse'], '.3f')} deg, "
                  f"bias {_f(im['bearing_bias'], '.3f')} deg; "
                  f"{pct(im['detection_rate'])} % of the lines in view detected, "
                  f"{_f(im['false_detections'], '.1f')} false detections a run; {pct(im['association_rate'])} % of "
                  f"detections associated with their own line ({_f(im['tracks'], '.1f')} tracks for "
                  f"{_f(im['landmarks'], '.1f')} lines; {_f(im.get('tracks_merged'), '.1f')} tentative tracks "
                  f"merged into a landmark, {_f(im.get('tracks_rejected'), '.1f')} rejected); "
                  f"{_f(im['seconds'], '.1f')} s a run"]
        if im.get("bearing_rmse") is None:
            lines.append("Nothing was detected in any frame: the estimators had no bearings.")
    if stats["scenario"] == "paper":
        lines += ["", PAPER_CLAIMS]
    return "\n".join(lines)
