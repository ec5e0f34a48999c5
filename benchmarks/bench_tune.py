"""What a tuning study costs beyond its runs (issue 26: under 5 % of a 200-trial study).

A study of ``--trials`` trials (sea's paper scenario, the EKF's likelihood over three noises,
``--runs`` runs a trial) on the local pool, timed from outside: its wall time against the runs'
own seconds (each task's, summed) shared over the workers. The difference is the tuner: Optuna's
asks and tells (the sampler's model over every finished trial), the journal, the Parquet writes,
the objective, the probe run, the report and the workers idle at each batch's end. The tuner's own
seconds in the main process (``tuner_seconds``) are printed too.

Run: ``python benchmarks/bench_tune.py [--trials 200] [--runs 5]``. The load average is printed:
on a shared machine compare the ratio of one run.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from workbench.core.registry import get
from workbench.tuning import space, study


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    exp = get("sea")
    params = space.parse(exp, ["sigma-acc=0.01:1:log", "sigma-alpha=0.3:3:log", "sigma-beta=0.5:5:log"], {}, None)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = study.tune("sea", params, "likelihood", "ekf", args.trials, args.runs, 0, None, Path(tmp) / "study",
                         jobs=args.jobs)
        wall = time.perf_counter() - t0
    runs_share = res.run_seconds / args.jobs
    over = wall - runs_share
    print(f"load average {os.getloadavg()[0]:.2f}; {args.trials} trials x {args.runs} runs on {res.executor}")
    print(f"wall {wall:.1f} s; the runs' own {res.run_seconds:.1f} s over {args.jobs} workers = {runs_share:.1f} s")
    print(f"beyond the runs: {over:.1f} s = {100 * over / wall:.1f} % of the study (target < 5 %); "
          f"the tuner's own seconds in the main process {res.tuner_seconds:.1f} s "
          f"= {100 * res.tuner_seconds / wall:.1f} %")
    print(f"best: {res.best}")


if __name__ == "__main__":
    main()
