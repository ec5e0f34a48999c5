"""The graph estimators' maps on synthetic drives with misread ids (issue 36): 17 logs, each map
against its bound.

The logs: 5, 10 and 20 % of the bearings given another landmark's id, seeds 3-6 each, and 10 %
seeds 0-2, 5 % seed 1, 20 % seed 0 (``omni.faults``, 3,000 poses). Each row gives every estimator's
position RMSE over the whole run, its aligned map RMSE against its bound, the run's seconds and the
diagnosis; the last line counts the maps within 2x their bound.

Run: ``python benchmarks/misread_maps.py [--estimators isam2,gtsam-batch] [--poses 3000]``.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
import warnings
from pathlib import Path

from workbench import api
from workbench.experiments.omni import faults
from workbench.sweeps.grid import settings

CASES = [(r, s) for r in (0.05, 0.10, 0.20) for s in (3, 4, 5, 6)] + [(0.10, 0), (0.10, 1), (0.10, 2), (0.05, 1),
                                                                        (0.20, 0)]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--estimators", default="isam2,gtsam-batch")
    ap.add_argument("--poses", type=int, default=3000)
    ap.add_argument("--set", action="append", default=[],
                    help="KEY=VALUE for every run (repeatable, as a sweep's), e.g. huber=1.345")
    args = ap.parse_args()
    fixed = settings(api.get("omni"), args.set)
    warnings.simplefilter("ignore")
    print(f"load average {os.getloadavg()[0]:.2f}; set {fixed}")
    print("| misread, seed | estimator | position m | map m (bound) | s | diagnosis |\n|---|---|---|---|---|---|")
    within: dict[str, int] = {}
    for rate, seed in CASES:
        with tempfile.TemporaryDirectory() as tmp:
            faults.write(Path(tmp), faults.Faults(poses=args.poses, seed=seed, misread=rate))
            t0 = time.perf_counter()
            res = api.run("omni", "log", data=tmp, estimators=args.estimators, **fixed)
            seconds = time.perf_counter() - t0
        for name, e in res.metrics["estimators"].items():
            if name == "odometry":
                continue
            err, bound = e.get("aligned_map_rmse", math.nan), e.get("map_bound", math.nan)
            within[name] = within.get(name, 0) + bool(err <= 2.0 * bound)
            verdict = (e.get("diagnosis") or {}).get("verdict")
            print(f"| {rate:.0%}, {seed} | {name} | {e.get('position_rmse_whole_run', math.nan):.3f} | "
                  f"{err:.3f} ({bound:.2f}) | {seconds:.1f} | {verdict} |", flush=True)
    print("within 2x the bound: " + ", ".join(f"{k} {v} of {len(CASES)}" for k, v in within.items()))


if __name__ == "__main__":
    main()
