"""Speed of the sea image stage (issue 5): detection at 960x540 must reach 30 frames/s or more;
(issue 15) render + detection at 1920x1080 30 frames/s or more on one core (OpenCV's threads: 1).

Renders the paper run's frames once (timed: the rendering), then times the detector and
tracker on them alone (render excluded) and the two together (render included), at each size.
CPU time is printed beside the wall time, with the load average: the machine is shared.

Run: ``python benchmarks/bench_sea_images.py [--frames 300] [--sizes 960x540,1920x1080]``
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from workbench.experiments.sea import run
from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.imaging import camera as cm
from workbench.experiments.sea.imaging import detect, stage
from workbench.experiments.sea.imaging.render import Renderer


def bench(size: tuple[int, int], frames: int) -> dict:
    cfg = SeaConfig(from_images=True, image_size=size).validate()
    data = run.make_data(cfg, 0)
    cam = stage.camera_for(data, cfg)
    rng = np.random.default_rng(0)
    renderer = Renderer(cam, data.height, rng)
    tilt, roll = stage.attitude(cfg, data.t, rng)
    steps = np.linspace(0, data.steps - 1, frames).astype(int)
    t0, c0 = time.perf_counter(), time.process_time()
    rendered = []
    for k in steps:
        target = (data.alpha[k], data.beta[k], float(np.hypot(data.range[k], data.height)))
        rendered.append(renderer.frame(tilt[k], roll[k], data.observer[k], data.course[k] + cam.pan, data.t[k],
                                       target, rng, cfg.pixel_noise))
    render_wall, render_cpu = time.perf_counter() - t0, time.process_time() - c0
    tracker = detect.Tracker(cam)
    t0, c0 = time.perf_counter(), time.process_time()
    errs = []
    for k, frame in zip(steps, rendered, strict=True):
        det = tracker.step(frame)
        if det.ok:
            u, v = cm.project(cam, data.alpha[k], data.beta[k], tilt[k], roll[k])
            errs.append((det.point[0] - u, det.point[1] - v))
    detect_wall, detect_cpu = time.perf_counter() - t0, time.process_time() - c0
    e = np.array(errs)
    return {"size": size, "frames": frames, "detected": len(errs),
            "detect_fps": frames / detect_wall, "detect_fps_cpu": frames / detect_cpu,
            "render_ms": 1e3 * render_wall / frames, "render_ms_cpu": 1e3 * render_cpu / frames,
            "total_fps": frames / (render_wall + detect_wall),
            "rmse_px": np.sqrt(np.mean(e**2, axis=0)) if len(e) else (np.nan, np.nan)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--sizes", default="960x540,1920x1080")
    p.add_argument("--threads", type=int, default=1, help="OpenCV's threads (1: one core, as the target says)")
    a = p.parse_args()
    import cv2

    cv2.setNumThreads(a.threads)
    print(f"OpenCV threads: {a.threads}")
    for text in a.sizes.split(","):
        load = os.getloadavg()[0]
        r = bench(cm.parse_size(text), a.frames)
        w, h = r["size"]
        target = "  (target >= 30 frames/s)" if (w, h) == (960, 540) else ""
        whole = "  (target >= 30 frames/s on one core)" if (w, h) == (1920, 1080) else ""
        print(f"{w}x{h}, {r['frames']} frames of the paper run, load {load:.1f} before:")
        print(f"  detection alone (render excluded): {r['detect_fps']:.0f} frames/s wall, "
              f"{r['detect_fps_cpu']:.0f} frames/s CPU{target}")
        print(f"  rendering: {r['render_ms']:.1f} ms/frame wall, {r['render_ms_cpu']:.1f} ms CPU")
        print(f"  render + detection (render included): {r['total_fps']:.0f} frames/s wall{whole}")
        print(f"  detected {r['detected']} of {r['frames']}; waterline rmse u {r['rmse_px'][0]:.3f} px, "
              f"v {r['rmse_px'][1]:.3f} px")


if __name__ == "__main__":
    main()
