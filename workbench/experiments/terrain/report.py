"""The terrain results table: image II's orientation errors per estimator (:mod:`.metrics`), the
reduction over the navigation system, the halftone model's ground error, the paper's normalised
statistics, the Cramér-Rao bounds."""

from __future__ import annotations

from workbench.experiments.terrain.metrics import BOUNDS, METRICS, TABLE
from workbench.metrics import tables as markdown
from workbench.metrics.tables import number as _f

PAPER_CLAIMS = ("paper's claims (Fig. 3 and text): after processing, mean linear errors at most 40-60 % of the "
                "maximum error (at least a 2x reduction); their spread 6-16 % (100x100) and 4-13 % (200x200) of it, "
                "radial 3-10 % and 2-8 %")


def table(stats: dict) -> str:
    """Markdown (also readable as plain text)."""
    hit = stats.get("winner_in_true_cell")
    hit_pos = stats.get("winner_in_true_position_cell")
    lines = [f"**terrain / {stats['scenario']}** ({stats.get('label', '')}), error mode `{stats['mode']}`, "
             f"{stats['distribution']} errors up to {stats['max_linear']:g} m and {stats['max_angular']:g} rad, "
             f"{stats['runs']} run(s), seed {stats['seed']}; {stats['hypotheses']} hypotheses over "
             f"{stats['nodes']} nodes" + (f"; winner in the true cell in {100 * hit:.0f} % of runs (in the true "
                                          f"position cell in {100 * hit_pos:.0f} %)" if hit is not None else ""), ""]
    lines += markdown.metric_table(stats, METRICS, TABLE)
    for name, e in stats["estimators"].items():
        bits = [f"position error {_f(e.get('reduction'))} of the navigation system's, attitude "
                f"{_f(e.get('attitude_reduction'))}, ground {_f(e.get('ground_reduction'))}; spread over runs of "
                f"dR / max {_f(e.get('dr_fraction_std'), '.3f')}, of dX / max {_f(e.get('dx_fraction_std'), '.3f')}"]
        if e.get("anees") is not None:
            lo, hi = e["anees_band"]
            bits.append(f"image II's position ANEES {e['anees']:.2f} (3 dof; 95 % band {lo:.2f}-{hi:.2f})")
        if e.get("kappa") is not None:
            bits.append(f"the node sum's variance inflation kappa {e['kappa']:.2f} (the residuals' correlation and "
                        f"spread against R): {stats['nodes']} nodes count as {e['effective_nodes']:.0f} independent "
                        "ones")
        lines.append(f"- {name}: " + "; ".join(bits))
    if stats.get("data_repairs"):
        lines += ["", "Reading the data: " + ", ".join(f"{k.replace('_', ' ')} {v}"
                                                       for k, v in stats["data_repairs"].items())]
    lines += [""] + markdown.verdicts(stats) + markdown.bounds_table(stats, BOUNDS)
    lines += ["Errors are image II's (truth - estimate): position as a 3D norm, attitude as the norm of the "
              "three angles, means over runs; ground rmse is the halftone model's horizontal error over every pixel "
              "of image II (RMS over runs); dR = sqrt(dX^2 + dY^2).", "", PAPER_CLAIMS]
    return "\n".join(lines)
