"""What the truth-free metrics cost (issue 25: at most 10 % of a run): for each experiment's paper
scenario, the seconds of a run (its dataset and every default estimator: ``run_once``) against
the seconds its metrics take, the truth-free ones apart (:mod:`workbench.metrics.truthfree`
and the disagreement with the smoother), on the same runs in one process.

Run: ``python benchmarks/bench_truthfree.py [--runs N]``. The load average is printed: on a
shared machine compare the ratios of one run.
"""

from __future__ import annotations

import argparse
import os
import time

from workbench.core.registry import get
from workbench.metrics import base as metric

SETTINGS = {"sea": {}, "omni": {"duration": 200.0}, "terrain": {"size": "100x100"}}


def measure(name: str, runs: int) -> dict:
    exp = get(name)
    cfg = exp.validate(exp.configure(**SETTINGS[name]))
    chosen = exp.select()
    metrics = exp.metrics(cfg)
    free = [m for m in metrics if m.truth_free]
    rest = [m for m in metrics if not m.truth_free]
    run_s = all_s = free_s = 0.0
    for k in range(runs):
        t0 = time.perf_counter()
        result = exp.run_once(cfg, k, chosen)
        run_s += time.perf_counter() - t0
        for group, acc in ((rest, "all"), (free, "free")):
            ctx = metric.MetricContext(cfg, k, estimates=result.estimates, estimators=result.estimators,
                                       products=result.products, cache=dict(result.cache), result=result)
            t0 = time.perf_counter()
            metric.evaluate(group, result.data, result.estimates, ctx)
            spent = time.perf_counter() - t0
            if acc == "all":
                all_s += spent
            else:
                free_s += spent
    return {"run": run_s / runs, "metrics": all_s / runs, "truth_free": free_s / runs}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}; {args.runs} run(s) each; seconds a run")
    print(f"{'experiment':10s} {'run':>8s} {'metrics':>8s} {'truth-free':>10s} {'share':>6s}")
    for name in SETTINGS:
        r = measure(name, args.runs)
        print(f"{name:10s} {r['run']:8.3f} {r['metrics']:8.3f} {r['truth_free']:10.4f} "
              f"{100 * r['truth_free'] / r['run']:5.2f}%")


if __name__ == "__main__":
    main()
