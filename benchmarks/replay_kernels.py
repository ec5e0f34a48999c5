"""``workbench replay`` of recordings under every BLAS kernel and SIMD level this processor can
run (issue 33): the outcome line of each, so that what a colleague's processor would say of a
shared recording is seen on this one. Kernels: the processor's own choice, ``avx2`` (an AVX2
machine without AVX-512: Haswell kernels, numpy's AVX-512 loops off), ``sandybridge`` (AVX, no
FMA), ``prescott`` (SSE3), ``skylakex`` (AVX-512), each where this processor has the instructions.

Run: ``python benchmarks/replay_kernels.py [RECORDING ...]`` (default: every recording in
``tests/data``; ``--write`` first writes a fresh sea, omni and terrain recording under the ``avx2``
kernel and replays those too).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from launcher import kernels  # noqa: E402

FRESH = {"sea": ("--runs", "4", "--duration", "20"), "omni": ("--runs", "2", "--duration", "60"),
         "terrain": ("--runs", "2", "--size", "100x100", "--levels-linear", "3", "--levels-angular", "1")}


def replay(path: Path, env: dict[str, str]) -> tuple[int, str, float]:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "workbench", "replay", str(path)], capture_output=True, text=True,
                       env={**os.environ, **env})
    lines = [line for line in r.stdout.splitlines() if not line.startswith("replaying")]
    return r.returncode, (lines[0] if lines else r.stderr.strip().splitlines()[-1]), time.perf_counter() - t0


def main() -> int:
    args = [a for a in sys.argv[1:] if a != "--write"]
    paths = [Path(a) for a in args] or sorted((ROOT / "tests" / "data").rglob("*.rrd"))
    found = {"here": {}, **kernels()}
    with tempfile.TemporaryDirectory() as d:
        if "--write" in sys.argv:
            for name, extra in FRESH.items():
                out = Path(d) / f"{name}-avx2.rrd"
                subprocess.run([sys.executable, "-m", "workbench", name, *extra, "--out", str(out)], check=True,
                               capture_output=True, env={**os.environ, **found.get("avx2", {})})
                paths.append(out)
        print(f"load {os.getloadavg()[0]:.1f}; kernels: {', '.join(found)}")
        worst = 0
        for path in paths:
            print(f"{path.name}:")
            for name, env in found.items():
                code, line, seconds = replay(path, env)
                worst = max(worst, code)
                print(f"  {name:12s} exit {code}  {seconds:5.1f} s  {line}")
    return worst


if __name__ == "__main__":
    sys.exit(main())
