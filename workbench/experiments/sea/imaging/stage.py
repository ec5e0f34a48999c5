"""The image stage: render each step's frame from the truth, detect, and hand the angles on.

``measure`` renders one frame per step (:mod:`.render`) through the true camera (the true
observer position and course, the mount's pan, the platform's seeded tilt and roll), runs
the detector and tracker (:mod:`.detect`) on it, and returns an :class:`ImageStage`; ``with_angles``
turns a dataset into the same dataset with the image-derived angles, so that every
estimator runs on them unchanged ("the same data through every estimator").

Readings and choices:

* The camera's pan (its axis from the course) is a mount setting: by default the middle of
  the run's true azimuths (rounded to 0.5 deg), so the object stays in the 70 deg field; an
  object outside the frame is not seen.
* The track-loss window hides the object (nothing drawn); the impulse (Fig. 5) is a
  disturbance outside the camera, so its draws are added to the image-derived angles as to
  the simulated ones.
* Errors are *truth minus measurement* (as for the estimators), in radians and in pixels
  (the waterline point against the true target point's projection).
* ``bad_frames`` replaces seeded steps by bad frames (a wrong size, a wrong type, all sky,
  an empty array), in turn: the detector reports why and the estimators coast there.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from workbench.experiments.sea.config import SeaConfig
from workbench.experiments.sea.imaging import camera as cam_model
from workbench.experiments.sea.imaging.camera import Camera
from workbench.experiments.sea.imaging.detect import DetectorConfig, Tracker
from workbench.experiments.sea.imaging.render import Renderer, colour
from workbench.experiments.sea.scenario import SeaData

BAD_KINDS = ("wrong size", "wrong type", "all sky", "empty")
RECORD_WIDTH = 960
"""Frames wider than this are recorded downscaled to it (the overlays are scaled with them)."""


@dataclass
class ImageStage:
    """One run's image stage; per step arrays of length T (NaN / False where nothing)."""

    camera: Camera
    alpha: np.ndarray           # image-derived azimuth, rad
    beta: np.ndarray            # image-derived depression, rad
    detected: np.ndarray        # bool
    visible: np.ndarray         # bool: the object was drawn inside the frame
    pixel: np.ndarray           # (T, 2) detected waterline point
    true_pixel: np.ndarray      # (T, 2) the true target point projected
    horizon: np.ndarray         # (T, 2) detected (v at u = cx, slope)
    true_horizon: np.ndarray    # (T, 2)
    tilt: np.ndarray            # true, rad
    roll: np.ndarray
    tilt_est: np.ndarray
    roll_est: np.ndarray
    box: np.ndarray             # (T, 4) x0, y0, x1, y1
    gate: np.ndarray            # (T, 4)
    reasons: list[str]          # "" where detected
    bad: dict[int, str]         # step -> kind of the bad frame put there
    seconds_render: float
    seconds_detect: float
    frames: list[bytes] = field(default_factory=list)   # JPEG, the recorded steps
    frame_steps: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    frame_scale: float = 1.0    # recorded frame pixels per camera pixel

    def errors(self, data: SeaData) -> np.ndarray:
        """``(T, 4)``: truth minus measurement of alpha, beta (rad), u, v (px); NaN where not detected."""
        e = np.full((len(self.alpha), 4), np.nan)
        ok = self.detected
        e[ok, 0] = data.alpha[ok] - self.alpha[ok]
        e[ok, 1] = data.beta[ok] - self.beta[ok]
        e[ok, 2:] = self.true_pixel[ok] - self.pixel[ok]
        return e


def camera_for(data: SeaData, cfg: SeaConfig) -> Camera:
    w, h = cfg.image_size
    if cfg.pan_deg is not None:
        pan = np.deg2rad(cfg.pan_deg)
    else:
        a = np.rad2deg(data.alpha[np.isfinite(data.alpha)])
        pan = np.deg2rad(np.round((a.min() + a.max()) / 2 * 2) / 2)
    return Camera(w, h, cfg.fov_deg, float(pan))


def attitude(cfg: SeaConfig, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The platform's tilt and roll (rad): a seeded offset and two slow swells of the given amplitude."""
    out = []
    for amp in (cfg.tilt_deg, cfg.roll_deg):
        p1, p2 = rng.uniform(4.0, 9.0), rng.uniform(1.5, 3.0)
        f1, f2, off = rng.uniform(0, 2 * np.pi), rng.uniform(0, 2 * np.pi), rng.uniform(-0.3, 0.3)
        x = off + 0.5 * np.sin(2 * np.pi * t / p1 + f1) + 0.2 * np.sin(2 * np.pi * t / p2 + f2)
        out.append(np.deg2rad(amp) * x)
    return out[0], out[1]


def bad_frame(kind: str, good: np.ndarray, renderer: Renderer, observer, yaw: float, t: float) -> np.ndarray:
    """A frame the detector must refuse: the wrong size or type, all sky (the platform pitched up), empty."""
    if kind == "wrong size":
        return good[::2, ::2].copy()
    if kind == "wrong type":
        return good.astype(np.float32)
    if kind == "all sky":
        return renderer.frame(np.deg2rad(-40.0), 0.0, observer, yaw, t, None)
    return np.zeros((0, 0), np.uint8)


def measure(data: SeaData, cfg: SeaConfig, run: int, keep_frames: bool = False,
            dcfg: DetectorConfig | None = None) -> ImageStage:
    """Render and detect every step of the run (seeded by ``(seed, run)``, apart from the data's draws)."""
    rng = np.random.default_rng([cfg.seed, run, 7])
    T = data.steps
    cam = camera_for(data, cfg)
    renderer = Renderer(cam, data.height, rng)
    tilt, roll = attitude(cfg, data.t, rng)
    bad_steps = np.sort(rng.choice(T, size=cfg.bad_frames, replace=False)) if cfg.bad_frames else []
    bad = {int(k): BAD_KINDS[i % len(BAD_KINDS)] for i, k in enumerate(bad_steps)}
    tracker = Tracker(cam, dcfg)
    stride = cfg.frame_stride or (1 if cam.width <= RECORD_WIDTH else 2)
    scale = min(1.0, RECORD_WIDTH / cam.width)
    rec_size = (int(round(cam.width * scale)), int(round(cam.height * scale)))

    nan2 = np.full((T, 2), np.nan)
    st = ImageStage(
        camera=cam, alpha=np.full(T, np.nan), beta=np.full(T, np.nan), detected=np.zeros(T, bool),
        visible=np.zeros(T, bool), pixel=nan2.copy(), true_pixel=nan2.copy(), horizon=nan2.copy(),
        true_horizon=nan2.copy(), tilt=tilt, roll=roll, tilt_est=np.full(T, np.nan),
        roll_est=np.full(T, np.nan), box=np.full((T, 4), np.nan), gate=np.full((T, 4), np.nan),
        reasons=[""] * T, bad=bad, seconds_render=0.0, seconds_detect=0.0, frame_scale=scale)
    for k in range(T):
        yaw = data.course[k] + cam.pan
        u, v = cam_model.project(cam, data.alpha[k], data.beta[k], tilt[k], roll[k])
        st.true_pixel[k] = u, v
        st.true_horizon[k] = cam_model.horizon_line(cam, tilt[k], roll[k])
        dist = float(np.hypot(data.range[k], data.height))
        target = (data.alpha[k], data.beta[k], dist) if data.seen[k] else None
        margin = 3.0
        st.visible[k] = bool(target is not None and margin <= u <= cam.width - 1 - margin
                             and margin <= v <= cam.height - 1 - margin)
        t0 = time.perf_counter()
        frame = renderer.frame(tilt[k], roll[k], data.observer[k], yaw, data.t[k], target, rng, cfg.pixel_noise)
        if k in bad:
            frame = bad_frame(bad[k], frame, renderer, data.observer[k], yaw, data.t[k])
        t1 = time.perf_counter()
        det = tracker.step(frame)
        st.seconds_render += t1 - t0
        st.seconds_detect += time.perf_counter() - t1
        if det.horizon is not None:
            st.horizon[k] = det.horizon.v_centre, det.horizon.slope
            st.tilt_est[k], st.roll_est[k] = det.tilt, det.roll
        if det.gate is not None:
            st.gate[k] = det.gate
        if det.ok:
            st.detected[k] = True
            st.alpha[k], st.beta[k] = det.alpha, det.beta
            st.pixel[k] = det.point
            st.box[k] = det.box
        else:
            st.reasons[k] = det.reason
        if keep_frames and k % stride == 0:
            st.frames.append(_jpeg(frame, rec_size))
            st.frame_steps = np.append(st.frame_steps, k)
    if data.impulse is not None:
        st.alpha = st.alpha + data.impulse[:, 0]
        st.beta = st.beta + data.impulse[:, 1]
    return st


def _jpeg(frame, size: tuple[int, int], quality: int = 80) -> bytes:
    """A displayable JPEG of any frame; a bad one (wrong type, empty) becomes a black frame."""
    if not isinstance(frame, np.ndarray) or frame.dtype != np.uint8 or frame.ndim != 2 or frame.size == 0:
        frame = np.zeros((size[1], size[0]), np.uint8)
    if (frame.shape[1], frame.shape[0]) != size:
        frame = cv2.resize(frame, size, interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", colour(frame), [cv2.IMWRITE_JPEG_QUALITY, quality])
    return buf.tobytes()


def with_angles(data: SeaData, alpha: np.ndarray, beta: np.ndarray, seen: np.ndarray, label: str = "") -> SeaData:
    """The same dataset with the measured angles (and the seen mask) replaced; NaN where unseen."""
    seen = np.asarray(seen, bool) & np.isfinite(alpha) & np.isfinite(beta)
    return replace(data, alpha_meas=np.where(seen, alpha, np.nan), beta_meas=np.where(seen, beta, np.nan),
                   seen=seen, label=label or data.label)


def from_stage(data: SeaData, stage: ImageStage) -> SeaData:
    """The dataset with the image stage's angles."""
    return with_angles(data, stage.alpha, stage.beta, stage.detected, f"{data.label}, from images")
