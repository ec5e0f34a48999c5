"""Speed of the omni image stage (issue 5): rendering and extraction of the round image,
timed separately, at 320 px (the default) and 540 px (the round image inside a 960x540 frame).
Target: the image stage at 30 frames/s or more at 960x540.

Run: ``python benchmarks/bench_omni_images.py``.
"""

from __future__ import annotations

import time

import numpy as np

from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.imaging.stage import Extractor, MirrorCamera, Renderer
from workbench.experiments.omni.scenario import simulate


def main() -> None:
    cfg = OmniConfig(duration=40.0)
    data = simulate(cfg, np.random.default_rng(0))
    steps = [s for s, _ in data.epochs()]
    for size in (320, 540):
        cam = MirrorCamera(size=size)
        renderer, extractor = Renderer(cam, np.random.default_rng(1)), Extractor(cam)
        t0, c0 = time.perf_counter(), time.process_time()
        frames = [renderer.render(data.truth[s], data.landmarks, data.max_range, data.fov) for s in steps]
        t1, c1 = time.perf_counter(), time.process_time()
        for img in frames:
            extractor.extract(img)
        t2, c2 = time.perf_counter(), time.process_time()
        n = len(frames)
        print(f"{size} px round image, {n} frames: render {n / (t1 - t0):.0f} frames/s (CPU {n / (c1 - c0):.0f}), "
              f"extract {n / (t2 - t1):.0f} frames/s (CPU {n / (c2 - c1):.0f}; target >= 30)")


if __name__ == "__main__":
    main()
