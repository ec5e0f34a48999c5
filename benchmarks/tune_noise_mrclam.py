"""``--tune-noise`` on the real MRCLAM robots without their truth, then scored with it (issue 35).

For each robot of ``mrclam6`` (1-5): a copy of the dataset folder without that robot's
``Groundtruth`` file (symbolic links to the rest) is what the tuning reads, so no truth can reach
it. The tuning's report gives the filter's values with their 95 % intervals, the held-out part's
predictive NLL at the start and tuned values, and the batch smoother's own values (variance
components) with where they disagree. Then, on the folder with the truth, every estimator's
position RMSE at the data's noise, at the filter's values and at the smoother's, and the tuning's
seconds (the 2-minute goal for a 25-minute robot).

Run: ``python benchmarks/tune_noise_mrclam.py [--data ../shared/data/mrclam6] [--robots 1,2,3,4,5]``.
The load average is printed: on a shared machine the seconds swing with it.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

import workbench
from workbench.core import selftune, tune_report
from workbench.core.registry import get

ESTIMATORS = ["ekf", "isam2", "gtsam-batch"]


def rmse(cfg_changes: dict, data: Path, robot: int) -> dict[str, float]:
    res = workbench.run("omni", scenario="mrclam", data=data, robot=robot, estimators=ESTIMATORS, **cfg_changes)
    return {e: float(res.metrics["estimators"][e]["position_rmse"]) for e in ESTIMATORS}


def main() -> None:
    ap = argparse.ArgumentParser()
    root = Path(__file__).resolve().parents[1]
    ap.add_argument("--data", type=Path, default=root / ".." / "shared" / "data" / "mrclam6")
    ap.add_argument("--robots", default="1,2,3,4,5")
    ap.add_argument("--out", type=Path, default=None, help="write the rows as JSON here")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    exp = get("omni")
    rows = []
    for robot in (int(r) for r in args.robots.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            blind = Path(tmp) / "mrclam6"
            blind.mkdir()
            for f in args.data.resolve().iterdir():
                if f.name != f"Robot{robot}_Groundtruth.dat":
                    (blind / f.name).symlink_to(f)
            cfg = exp.validate(exp.configure(scenario="mrclam", data=blind, robot=robot))
            _, rep = selftune.tune_noise(exp, cfg)
        print(f"robot {robot}:")
        for line in tune_report.lines(rep):
            print("  " + line)
        filt = {f"assume_{k}": v for k, v in rep["told"].items()}   # what --tune-noise tells the estimators
        sm = rep.get("smoother") or {}
        smooth = {**filt, **{f"assume_{k}": v for k, v in sm.get("values", {}).items()}}
        scores = {"data's": rmse({}, args.data, robot), "filter's": rmse(filt, args.data, robot)}
        # what was told before a start the data do not reject and the values not identified were kept
        # (each value but the disagreeing ones, where anything was), for a before-and-after in one run
        before = {f"assume_{k}": v for k, v in rep["tuned"].items() if k not in rep["not_told"]}
        if rep["held_out"]["generalises"] and not rep["contradicted"] and before != filt:
            scores["filter's as told before 2026-12-07"] = rmse(before, args.data, robot)
        if sm.get("values"):
            scores["smoother's"] = rmse(smooth, args.data, robot)
        for which, s in scores.items():
            print(f"  position RMSE at the {which} noise: " + ", ".join(f"{e} {v:.2f} m" for e, v in s.items()))
        rows.append({"robot": robot, "report": rep, "rmse": scores})
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1, default=float))
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
