"""Speed of the sea experiment (targets from issue 2): ``workbench sea --runs 100`` with every
estimator under 60 s on the 2-core machine, and one recorded run under 5 s.

Run: ``python benchmarks/bench_sea.py`` (prints the wall times, the CPU time the processes
used and the per-estimator seconds). On a shared machine the wall time depends on what else
runs: the load average is printed beside each figure, and CPU time / cores is the wall time
an idle machine would take, give or take the serial parts (start-up, run 0, the recording).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(args: list[str], workdir: Path) -> tuple[float, float, dict]:
    """Wall seconds, CPU seconds (the command and its worker processes) and the metrics."""
    metrics = workdir / "m.json"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "workbench", "sea", *args, "--out", str(workdir / "b.rrd"),
                    "--metrics", str(metrics), "--force"], check=True, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, json.loads(metrics.read_text())


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        load1 = os.getloadavg()[0]
        one, one_cpu, _ = timed(["--runs", "1"], work)
        load100 = os.getloadavg()[0]
        hundred, hundred_cpu, m100 = timed(["--runs", "100"], work)
    print(f"one recorded run (all estimators, process start included): {one:.1f} s wall, "
          f"{one_cpu:.1f} s CPU, load {load1:.1f} before  (target < 5 s)")
    print(f"100 Monte Carlo runs, every estimator: {hundred:.1f} s wall, {hundred_cpu:.1f} s CPU, "
          f"load {load100:.1f} before  (target < 60 s)")
    print("seconds per run, per estimator:")
    for name, e in m100["estimators"].items():
        print(f"  {name:11s} {e['seconds']:.3f}")


if __name__ == "__main__":
    main()
