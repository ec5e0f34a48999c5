"""Speed of recurrent-search estimation (targets from issue 4): a 200x200 search over
5^3 x 3^3 = 3375 hypotheses in under 5 s on the 2-core machine, and peak memory under 4 GB at
400x500. The search is timed alone (scene, rendering and node selection excluded), on one and
on two threads, in both error modes, after one warm-up call that loads (or, the first time,
compiles) the Numba kernel, whose time is printed apart; the arithmetic is counted per node and hypothesis
(linearisation, H'H as a full n x n product, H'r, r'r) and reported as a rate and as a fraction
of 2e10 flop/s. Peak memory is the whole process's maximum resident set at 400x500.

Run: ``python benchmarks/bench_terrain.py`` (about a minute; the machine is shared, so CPU time
and the load average are printed beside the wall times).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from workbench.experiments.terrain import navigation  # noqa: E402
from workbench.experiments.terrain import scenario as scene  # noqa: E402
from workbench.experiments.terrain.algorithms import search  # noqa: E402
from workbench.experiments.terrain.config import TerrainConfig  # noqa: E402

# flops per node and hypothesis of the linearisation, estimated by counting the operations in
# ``fused._block`` (projection ~25, the bilinear read of 3 channels ~24, the chain rule ~60;
# the common mode adds the rays, two Newton steps with a DEM read and image I's chain rule)
LINEARISE_FLOPS = {"ii-only": 110, "common": 250}
BOUND = 2e10


def problem(mode: str, size: str) -> tuple[search.Problem, search.Hypotheses]:
    cfg = TerrainConfig(mode=mode, size=size).validate()
    rng = np.random.default_rng(0)
    sc = scene.synthetic_scene(cfg, rng)
    state = navigation.draw_state(cfg, rng)
    pos, ang = navigation.measured(sc.position, sc.angles, navigation.error_map(mode, sc.interval) @ state)
    return (search.make_problem(cfg, sc.k, sc.dem, pos, ang, sc.images, sc.interval),
            search.hypotheses(cfg, rng))


def warm_up(p: search.Problem, hyp: search.Hypotheses) -> float:
    """Load or compile the kernel (one chunk of two hypotheses); returns seconds."""
    t0 = time.perf_counter()
    search.run(p, search.Hypotheses(hyp.centres[:2], hyp.prior, hyp.kind))
    return time.perf_counter() - t0


def timed(p: search.Problem, hyp: search.Hypotheses, threads: int) -> tuple[float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    search.run(p, hyp, threads=threads)
    return time.perf_counter() - t0, time.process_time() - c0


def memory_child() -> None:
    p, hyp = problem("common", "400x500")
    search.run(p, hyp, threads=2)
    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def main() -> None:
    if sys.argv[1:] == ["--memory-child"]:
        memory_child()
        return
    print(f"load average at start: {os.getloadavg()[0]:.2f} (2 cores)")
    for mode in ("ii-only", "common"):
        p, hyp = problem(mode, "200x200")
        n_h, nodes, n = len(hyp.centres), len(p.nodes), p.n
        flops = n_h * nodes * (LINEARISE_FLOPS[mode] + 2 * n * n + 2 * n + 2)
        print(f"{mode:8s} kernel load/compile: {warm_up(p, hyp):.2f} s (once per machine; cached on disk)")
        for threads in (1, 2):
            wall, cpu = timed(p, hyp, threads)
            print(f"{mode:8s} 200x200, {n_h} hypotheses x {nodes} nodes (n = {n}), {threads} thread(s): "
                  f"{wall:.2f} s wall, {cpu:.2f} s CPU (target < 5 s); ~{flops:.2e} flops -> "
                  f"{flops / wall:.2e} flop/s = {flops / wall / BOUND:.0%} of 2e10 flop/s")
    out = subprocess.run([sys.executable, __file__, "--memory-child"], capture_output=True, text=True, check=True)
    peak_gb = int(out.stdout.strip().splitlines()[-1]) / 1024 ** 2
    print(f"peak memory, common mode at 400x500 (3375 hypotheses, 2 threads): {peak_gb:.2f} GB (target < 4 GB)")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
