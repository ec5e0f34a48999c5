"""What the Cramér-Rao bounds add to a run (issue 13's target: under 20 %), each experiment on its
paper scenario with its default estimators: one run's data and estimators, its evaluation with
the bounds, and the bounds alone, timed in one process so the ratio holds on a shared machine.

Run: ``python benchmarks/bench_bounds.py`` (prints seconds and the bounds' share of a run).
"""

from __future__ import annotations

import os
import time

import numpy as np

import workbench
from workbench.core.registry import get


def _bounds(name: str, exp, cfg, result) -> float:
    """Seconds of the bounds alone, as the evaluation computes them for this run."""
    t0 = time.perf_counter()
    if name == "sea":
        from workbench.experiments.sea import bounds as sb

        d = result.data
        m = sb.Model(d.dt, d.height, d.sigma_acc, d.sigma_alpha, d.sigma_beta, d.sigma_observer, cfg.prior_speed)
        b = sb.Bounds(m, [sb.Truth(d.target, d.observer, d.seen, d.disturbed)])
        for delay in {0.0, float("inf"), *(e.delay for e in result.estimators.values())}:
            b.variances(delay)
    elif name == "omni":
        from workbench.experiments.omni import bounds as ob
        from workbench.experiments.omni.algorithms import graph

        kf = result.keyframes if result.keyframes is not None else graph.keyframes(result.data, cfg)
        ob.variances(result.data, kf, {0.0, float("inf")})
    else:
        from workbench.experiments.terrain import bounds as tb

        tb.state_bound(result.problem, result.state, cfg)
        tb.bundle_adjustment(cfg, result.scene, result.estimates["gtsam-ba"].extras)
    return time.perf_counter() - t0


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.2f}")
    for name in ("sea", "omni", "terrain"):
        exp = get(name)
        cfg = workbench.configure(name)
        chosen = exp.select(None)
        runs, shares = [], []
        for run in (1, 2):
            t0 = time.perf_counter()
            result = exp.run_once(cfg, run, chosen)
            exp.evaluate(result, cfg, run)
            whole = time.perf_counter() - t0
            alone = _bounds(name, exp, cfg, result)
            runs.append(whole)
            shares.append(alone / (whole - alone))
        print(f"{name:8s} a run with its evaluation {np.mean(runs):6.2f} s; the bounds in it "
              f"{100 * np.mean(shares):4.1f} % of the rest")


if __name__ == "__main__":
    main()
