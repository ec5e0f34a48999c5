"""The synthetic-fault table (issue 36): the smoothers and the EKF on a synthetic drive
(:mod:`workbench.experiments.omni.faults`: 3,000 poses, 150 trees, increments odometry with each
step's covariance) carrying each fault a real log has, one at a time; per fault and estimator
the pose error over the whole run (the smoothers' trajectory as held at the end) and the map's
after the best rigid alignment, each against its Cramér-Rao bound, the bearings left out, the
seconds, and what the diagnosis without truth says.

Faults: none; 10 % of the bearings given another tree's id; Student-t bearing noise (3 degrees
of freedom); 60 s blind every 200 s; the odometry's covariance stated 3x too narrow (as sigmas).

Run: ``python benchmarks/fault_table.py [--poses N] [--estimators LIST]`` (one run each).
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

from workbench import api
from workbench.experiments.omni import faults
from workbench.sweeps.grid import settings

FAULTS = {
    "none": {},
    "misread 10 %": {"misread": 0.10},
    "Student-t 3": {"student_t": 3.0},
    "blind 60 s": {"blind": 60.0, "blind_every": 200.0},
    "odometry 3x narrow": {"odometry_stated": 1.0 / 3.0},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=3000)
    ap.add_argument("--estimators", default="ekf,isam2,gtsam-batch")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", action="append", default=[],
                    help="KEY=VALUE for every run (repeatable, as a sweep's), e.g. huber=1.345")
    args = ap.parse_args()
    fixed = settings(api.get("omni"), args.set)
    print(f"load average {os.getloadavg()[0]:.2f}; {args.poses} poses, seed {args.seed}; set {fixed}")
    print("| fault | estimator | pose RMSE m (bound) | map aligned m (bound) | left out | s | diagnosis |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, fault in FAULTS.items():
            folder = Path(tmp) / name.replace(" ", "_").replace("%", "pc")
            faults.write(folder, faults.Faults(poses=args.poses, seed=args.seed, **fault))
            t0 = time.perf_counter()
            r = api.run("omni", "log", data=str(folder), estimators=args.estimators, **fixed)
            wall = time.perf_counter() - t0
            for est, e in r.metrics["estimators"].items():
                pos = e.get("position_rmse_whole_run", e.get("position_rmse", math.nan))
                bound = e.get("position_bound_whole_run", e.get("position_bound", math.nan))
                diag = e.get("diagnosis", {})
                verdict = diag.get("verdict", diag) if isinstance(diag, dict) else diag
                print(f"| {name} | {est} | {pos:.2f} ({bound:.2f}) | {e.get('aligned_map_rmse', math.nan):.2f} "
                      f"({e.get('map_bound', math.nan):.2f}) | {e.get('left_out', math.nan):.3f} | "
                      f"{e.get('seconds', math.nan):.1f} | {verdict} |")
            for est, why in r.failures.items():
                print(f"| {name} | {est} | failed: {why} | | | | |")
            print(f"<!-- {name}: {wall:.1f} s in all -->")


if __name__ == "__main__":
    main()
