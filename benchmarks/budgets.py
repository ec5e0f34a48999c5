"""Every estimator on every long log within a budget (issue 36, item 5): each MRCLAM 6 robot with
the default estimators within 30 s on these 2 cores, and each estimator on the synthetic drive of
the public car log's shape (7,000 poses, :mod:`workbench.experiments.omni.faults`) within 60 s.
Each run as a user runs it (``api.run``: every figure, the map read every second for the
recording); per robot and estimator, its position RMSE and seconds (its own and the shared
products it used: the batch's include iSAM2's), the whole run's wall time, and the verdict.

Run: ``python benchmarks/budgets.py [--data ../shared/data]`` (MRCLAM skipped where absent).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

from workbench import api
from workbench.experiments.omni import faults

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"


def _run(label: str, budget: float, **kw) -> bool:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = api.run("omni", **kw)
    wall = time.perf_counter() - t0
    rows = r.metrics["estimators"]
    worst = max(e["seconds"] for e in rows.values())
    parts = ", ".join(f"{n} {e['position_rmse']:.3f} m {e['seconds']:.1f} s" for n, e in rows.items())
    ok = (wall if budget == 30.0 else worst) <= budget and not r.failures
    print(f"| {label} | {parts} | {wall:.1f} | {'met' if ok else 'MISSED'} |"
          + (f" failed: {r.failures}" if r.failures else ""))
    return ok


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DATA)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    print("| log | estimator RMSE and seconds | whole run s | budget |\n|---|---|---|---|")
    ok = True
    if (args.data / "mrclam6").is_dir():
        for robot in range(1, 6):
            ok &= _run(f"MRCLAM 6 robot {robot} (30 s)", 30.0, scenario="mrclam", robot=robot,
                       data=str(args.data / "mrclam6"))
    else:
        print(f"(no MRCLAM data at {args.data / 'mrclam6'}: skipped)")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "drive"
        faults.write(folder, faults.Faults(poses=7000, max_range=17.0))
        ok &= _run("synthetic drive, 7,000 poses (60 s each)", 60.0, scenario="log", data=str(folder),
                   estimators="odometry,ekf,isam2,gtsam-batch,fixed-lag")
    print("every budget met" if ok else "a budget missed")


if __name__ == "__main__":
    main()
