"""The agreement benchmark's bookkeeping (``benchmarks/diagnosis_agreement.py``): each simulated
cell on its own seeds, and the NEES verdict pooled over the runs it names, checked against
hand-computed means and Bar-Shalom's chi-square band."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from workbench.estimation.metrics import chi2_band

HERE = Path(__file__).resolve().parents[1] / "benchmarks" / "diagnosis_agreement.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("diagnosis_agreement", HERE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_each_simulated_cell_draws_its_own_seeds(bench, tmp_path):
    """Cells that shared their seeds were nearly one draw of the NEES: every simulated cell and
    each of its truth-only twins now has a seed of its own, and the twins bring the NEES to 24
    runs (8 x 3 resamples, equal to the bootstrap's) and then to ``nees_runs`` where short of it."""
    cells = bench._cells(8, 20, tmp_path, resamples=3, logs=1, nees_runs=48)
    paper = [(c, kw) for e, c, kw in cells if kw.get("scenario") == "paper"]
    seeds = [kw["seed"] for _, kw in paper]
    # 5 omni cells, each with two twins; 5 sea cells, whose 20 x 3 already pass 48 runs, with one
    assert len(seeds) == len(set(seeds)) == 5 * 3 + 5 * 2
    for cell in {c for c, _ in paper}:
        omni = [kw for e, c, kw in cells if c == cell and e == "omni"]
        if omni:
            assert [kw["runs"] for kw in omni] == [8, 16, 24]
            assert [kw.get("truth_only", False) for kw in omni] == [False, True, "more"]


def test_the_nees_verdict_pools_the_runs_it_names(bench):
    """8 runs at ANEES 1.8, 16 equal-power twins at 2.2 and 24 more at 2.8: over the 24 the mean
    is 49.6 / 24 = 2.067, under the band's 2.101 (3 dof); over all 48, 116.8 / 48 = 2.433, inside
    2.347-3.732. The bootstrap's own verdict (one entry) is its ``covers``."""
    entries = [{"anees": 1.8, "diagnosis": {"verdict": "too wide", "covers": False}}]
    p = bench._pooled(entries, [8], [(2.2, 16, False), (2.8, 24, True)], 3, 3)
    assert p["anees_equal"] == pytest.approx(49.6 / 24) and p["nees_equal_runs"] == 24
    assert p["anees"] == pytest.approx(116.8 / 48) and p["nees_runs"] == 48
    assert p["anees_equal"] < chi2_band(3, 24)[0] and p["nees_equal"] is False
    assert chi2_band(3, 48)[0] < p["anees"] < chi2_band(3, 48)[1] and p["nees"] is True
    assert p["said"] is False
