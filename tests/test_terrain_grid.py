"""The paper's grid: the statistics on a hand-made case, and the sweep preset through the launcher."""

import csv

import numpy as np
from launcher import cli

from workbench.experiments.terrain import grid


def test_aggregate_hand_case():
    rows = [{"size": "a", "max_linear": 100.0, "max_angular": 0.001, "functionals": 10, "run": r,
             "navigation_dx": 0.0, "navigation_dy": 0.0, "centre_dx": dx, "centre_dy": 0.0,
             "refined_dx": 3.0, "refined_dy": 4.0} for r, dx in enumerate((-10.0, 30.0))]
    (e,) = grid.aggregate(rows, ("size",))
    assert e["samples"] == 2
    assert np.isclose(e["centre_mean_x"], 0.2) and np.isclose(e["centre_std_x"], 0.1)  # |dx| = 0.1, 0.3
    assert np.isclose(e["refined_mean_r"], 0.05) and np.isclose(e["refined_std_r"], 0.0)


def test_paper_grid_preset_writes_table_csv_and_plots(tmp_path):
    """``workbench sweep terrain --preset paper-grid`` at one size and one run: the 27 error cells
    as tidy rows and, from them, the paper's Fig. 3 report."""
    out = tmp_path / "grid"
    cmd = ["sweep", "terrain", "--preset", "paper-grid", "--grid", "size=100x100",
           "--runs", "1", "--set", "node_step=2", "--set", "mode=ii-only", "--out", str(out)]
    r = cli(*cmd)
    assert r.returncode == 0, r.stderr
    with open(out / "grid.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 27                          # 3 x 3 maxima x 3 sample sizes, one run
    assert {float(x["max_linear"]) for x in rows} == {50.0, 100.0, 200.0}
    refined = np.array([np.hypot(float(x["refined_dx"]), float(x["refined_dy"])) / float(x["max_linear"])
                        for x in rows])
    nav = np.array([np.hypot(float(x["navigation_dx"]), float(x["navigation_dy"])) / float(x["max_linear"])
                    for x in rows])
    assert refined.mean() < 0.6 * nav.mean()      # the paper's claim, pooled over the grid
    for name in ("grid.md", "fig3_100x100_centre.png", "fig3_100x100_refined.png", "spread_vs_N_100x100.png",
                 "summary.md", "dr_fraction_vs_max_linear.png"):
        assert (out / name).stat().st_size > 1000, name
    assert "mode `ii-only`" in (out / "grid.md").read_text()
    again = cli(*cmd)
    assert again.returncode == 2 and "--resume" in again.stderr
