"""Speed of the sea experiment (targets from issue 2): ``workbench sea --runs 100`` with every
estimator under 60 s on the 2-core machine, and one recorded run under 5 s.

Run: ``python benchmarks/bench_sea.py`` (prints the wall times and per-estimator seconds).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(args: list[str], workdir: Path) -> tuple[float, dict]:
    metrics = workdir / "m.json"
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "workbench", "sea", *args, "--out", str(workdir / "b.rrd"),
                    "--metrics", str(metrics), "--force"], check=True, capture_output=True)
    return time.perf_counter() - t0, json.loads(metrics.read_text())


def main() -> None:
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        one, m1 = timed(["--runs", "1"], work)
        hundred, m100 = timed(["--runs", "100"], work)
    print(f"one recorded run (all estimators, process start included): {one:.1f} s  (target < 5 s)")
    print(f"100 Monte Carlo runs, every estimator:                      {hundred:.1f} s  (target < 60 s)")
    print("seconds per run, per estimator:")
    for name, e in m100["estimators"].items():
        print(f"  {name:11s} {e['seconds']:.3f}")


if __name__ == "__main__":
    main()
