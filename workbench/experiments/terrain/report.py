"""The terrain results table: image II's orientation errors per estimator, the reduction over
the navigation system, the halftone model's ground error, the paper's normalised statistics."""

from __future__ import annotations

from workbench.estimation import bounds

PAPER_CLAIMS = ("paper's claims (Fig. 3 and text): after processing, mean linear errors at most 40-60 % of the "
                "maximum error (at least a 2x reduction); their spread 6-16 % (100x100) and 4-13 % (200x200) of it, "
                "radial 3-10 % and 2-8 %")


def _f(x: float | None, fmt: str = ".2f") -> str:
    return "-" if x is None else f"{x:{fmt}}"


def table(stats: dict) -> str:
    """Markdown (also readable as plain text)."""
    head = ("| estimator | position error m | / navigation | attitude error mrad | ground rmse m | "
            "mean dR / max | sd dR / max | mean dX / max | sd dX / max | s/run |")
    hit = stats.get("winner_in_true_cell")
    hit_pos = stats.get("winner_in_true_position_cell")
    lines = [f"**terrain / {stats['scene']}** ({stats.get('label', '')}), error mode `{stats['mode']}`, "
             f"{stats['distribution']} errors up to {stats['max_linear']:g} m and {stats['max_angular']:g} rad, "
             f"{stats['runs']} run(s), seed {stats['seed']}; {stats['hypotheses']} hypotheses over "
             f"{stats['nodes']} nodes" + (f"; winner in the true cell in {100 * hit:.0f} % of runs (in the true "
                                          f"position cell in {100 * hit_pos:.0f} %)" if hit is not None else ""),
             "", head, "|" + "---|" * 10]
    for name, e in stats["estimators"].items():
        p = e["paper"]
        lines.append(
            f"| {name} | {e['position_error']:.2f} | {_f(e['reduction'])} | {1000 * e['attitude_error']:.3f} "
            f"| {e['ground_rmse']:.2f} | {p['mean_r']:.3f} | {p['std_r']:.3f} | {p['mean_x']:.3f} | {p['std_x']:.3f} "
            f"| {e['seconds']:.2f} |")
    for name, e in stats["estimators"].items():
        if e.get("anees") is not None:
            lo, hi = e["nees_band"]
            lines.append(f"- {name}: image II's position ANEES {e['anees']:.2f} (3 dof; 95 % band {lo:.2f}-{hi:.2f})")
    for name, e in stats["estimators"].items():
        if e.get("kappa") is not None:
            lines.append(f"- {name}: the node sum's variance inflation kappa {e['kappa']:.2f} (the residuals' "
                         f"correlation and spread against R): {stats['nodes']} nodes count as "
                         f"{e['effective_nodes']:.0f} independent ones")
    lines += [""] + bounds.table(stats, (("position", "m"), ("attitude", "mrad")))
    lines += ["Errors are image II's (truth - estimate): position as a 3D norm, attitude as the norm of the "
              "three angles, means over runs; ground rmse is the halftone model's horizontal error over every pixel "
              "of image II (RMS over runs); dR = sqrt(dX^2 + dY^2).", "", PAPER_CLAIMS]
    return "\n".join(lines)
