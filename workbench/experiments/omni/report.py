"""The omni results table: the metrics (:mod:`.metrics`) per estimator after settling, the whole
run, the Cramér-Rao bounds, the image stage's figures, beside the paper's claims."""

from __future__ import annotations

from workbench.experiments.omni import placed, survey
from workbench.experiments.omni.config import BATCH_STARTS
from workbench.experiments.omni.metrics import BOUNDS, METRICS, TABLE
from workbench.metrics import tables as markdown
from workbench.metrics.tables import number as _f

PAPER_CLAIMS = ("paper's claims (simulation): position error < 0.5 m, heading error < 1 deg; "
                "own standard deviations < 1 m and < 1 deg after settling; odometry drifts without bound")


def table(stats: dict) -> str:
    """Markdown (also readable as plain text)."""
    lo, hi = stats["metric_table"]["anees"]["band"]
    lines = [f"**omni / {stats['scenario']}** ({stats.get('label', '')}), {stats['runs']} run(s), "
             f"seed {stats['seed']}; errors after {stats['settle_seconds']:g} s, over all runs; "
             f"ANEES 95 % band {lo:.2f}-{hi:.2f}", ""]
    lines += markdown.metric_table(stats, METRICS, TABLE)
    lines += ["", "Whole run (including the first lap):"]
    for name, e in stats["estimators"].items():
        bits = [f"position rmse {_f(e.get('position_rmse_whole_run'))} m, max {_f(e.get('position_max_whole_run'))} m",
                f"heading rmse {_f(e.get('heading_rmse_whole_run'))} deg, max {_f(e.get('heading_max_whole_run'))} deg"]
        if e.get("position_rmse_whole_run") is None:  # a log without its truth
            bits = ["no truth of the robot: no pose errors"]
            if e.get("aligned_map_rmse") is not None:
                bits.append(f"the map {_f(e['aligned_map_rmse'])} m off the landmark survey after the best rigid "
                            "alignment")
        if e.get("aligned_position_rmse_whole_run") is not None:
            bits.append(f"after the best rigid alignment (evo -a) position rmse "
                        f"{_f(e['aligned_position_rmse_whole_run'])} m, heading rmse "
                        f"{_f(e.get('aligned_heading_rmse_whole_run'))} deg (the alignment: "
                        f"{_f(e.get('alignment_rotation'))} deg, {_f(e.get('alignment_translation'))} m, "
                        "rms over runs)")
        if e.get("smoothed_position_rmse_whole_run") is not None:
            bits.append(f"its whole trajectory as held at the end (smoothed) position rmse "
                        f"{_f(e['smoothed_position_rmse_whole_run'])} m, heading rmse "
                        f"{_f(e.get('smoothed_heading_rmse_whole_run'))} deg")
        if e.get("anees_inside_band") is not None:
            bits.append(f"mean NEES inside the band at {100 * e['anees_inside_band']:.0f} % of steps")
        if e.get("failures"):
            bits.append(f"{e['failures']:.0f} rejected update(s)")
        won = {w: e[f"started_{w}"] for w in BATCH_STARTS if e.get(f"started_{w}")}
        if won:
            bits.append("started from " + ", ".join(f"{w} in {n:.0f}" for w, n in won.items())
                        + f" of {stats['runs']} run(s) (of the starts tried, the lowest cost on the data)")
        if e.get("bearings_gated"):
            bits.append(f"{e['bearings_gated']:.0f} bearing(s) left out by the gate (misreads, outliers)")
        if e.get("survey") and (e.get("position_rmse_whole_run") is None or e["survey"]["far"]):
            bits.append(survey.describe(e["survey"]) + (" (run 0)" if stats["runs"] > 1 else ""))
        if placed.describe(e.get("unplaced")):
            bits.append(placed.describe(e["unplaced"]) + (" (run 0)" if stats["runs"] > 1 else ""))
        lines.append(f"- {name}: " + "; ".join(bits))
    if stats.get("data_repairs"):
        lines += ["", "Reading the log: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                      for k, v in stats["data_repairs"].items())]
    lines += [""] + markdown.verdicts(stats) + markdown.bounds_table(stats, BOUNDS)
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
