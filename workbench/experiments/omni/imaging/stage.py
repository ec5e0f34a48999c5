"""The hemispherical camera's round image, rendered and read back with OpenCV.

Rendering (``spec/omni.md``, Images): the camera looks up at a hemispherical mirror, so the
image is a disc whose polar angle is the azimuth in the vehicle frame and whose radius grows
with the elevation of the viewed ray; the centre (the camera's own reflection) is blind. A
vertical line of height ``line_height`` seen from ``camera_height`` at distance ``d`` is a
radial segment from the radius of elevation ``atan(-camera_height / d)`` to that of
``atan((line_height - camera_height) / d)``, as wide as the line's ``line_width`` subtends.
Lines are painted far to near, so nearer ones occlude those behind. The background is a
texture fixed to the world (it turns with the vehicle), plus pixel noise.

Image convention: pixel ``(u, v) = centre + r (cos a, -sin a)`` for the azimuth ``a`` in the
vehicle frame (anticlockwise, 0 straight ahead), so the image reads like a top-down map.

Extraction: ``cv2.warpPolar`` unwraps the disc so that every radial line becomes a row; the
rows are high-passed along the angle (a line is darker than the background beside it), a
row's score is its summed darkness over the mirror's ring, and the score's local maxima
above a threshold, refined by a parabola through three rows, are the bearings.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import cv2
import numpy as np

from workbench.errors import require
from workbench.estimation.angles import wrap
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData


@dataclass(frozen=True)
class MirrorCamera:
    """The round image's geometry: size, blind centre, elevation range of the mirror."""

    size: int = 480
    blind: float = 0.12
    outer: float = 0.48
    elevation_low: float = math.radians(-60.0)
    elevation_high: float = math.radians(60.0)
    camera_height: float = 1.0
    line_height: float = 3.0
    line_width: float = 0.25
    noise: float = 4.0

    @property
    def centre(self) -> float:
        return (self.size - 1) / 2.0

    @property
    def r_blind(self) -> float:
        return self.blind * self.size

    @property
    def r_outer(self) -> float:
        return self.outer * self.size

    def radius(self, elevation: np.ndarray) -> np.ndarray:
        """Image radius of a ray's elevation (linear in elevation across the mirror)."""
        f = (np.clip(elevation, self.elevation_low, self.elevation_high) - self.elevation_low) / (
            self.elevation_high - self.elevation_low)
        return self.r_blind + f * (self.r_outer - self.r_blind)


class Renderer:
    """Renders round images. The world texture is tabulated once over (world azimuth,
    radius) and each frame gathers from it with the heading's offset; the pixel noise is
    drawn once into a bank and each frame takes a random slice of it."""

    TEXTURE_COLUMNS = 4096

    def __init__(self, cam: MirrorCamera, rng: np.random.Generator):
        require(cam.size >= 64, f"round image size must be at least 64 px (got {cam.size})")
        self.cam = cam
        ax = np.arange(cam.size) - cam.centre
        u, v = np.meshgrid(ax, ax)
        angle = np.arctan2(-v, u)
        r = np.hypot(u, v)
        self.ring = (r >= cam.r_blind) & (r <= cam.r_outer)
        m = self.TEXTURE_COLUMNS
        self.col = np.round(angle / (2 * np.pi) * m).astype(np.int64) % m
        self.row = np.minimum(np.round(r).astype(np.int64), int(np.ceil(cam.r_outer)) + 1)
        a = np.arange(m)[None, :] * 2 * np.pi / m
        rr = np.arange(self.row.max() + 1)[:, None] / cam.size
        self.texture = (150.0 + 25.0 * np.sin(5 * a) * np.cos(9 * rr) + 15.0 * np.sin(17 * a + 4 * rr)
                        + 10.0 * np.cos(41 * a)).astype(np.float32)
        self.bank = (cam.noise * rng.standard_normal(3 * cam.size * cam.size)).astype(np.float32)
        self.rng = rng

    def background(self, heading: float) -> np.ndarray:
        """The world-fixed texture (it turns with the vehicle) on the mirror's ring."""
        shift = int(round(heading / (2 * np.pi) * self.TEXTURE_COLUMNS))
        img = self.texture[self.row, (self.col + shift) % self.TEXTURE_COLUMNS]
        img[~self.ring] = 8.0
        return img

    def render(self, pose: np.ndarray, landmarks: np.ndarray, max_range: float, fov: float) -> np.ndarray:
        """The uint8 round image seen from ``pose`` (x, y, phi)."""
        cam = self.cam
        canvas = self.background(float(pose[2]))
        d = landmarks - pose[:2]
        dist = np.hypot(d[:, 0], d[:, 1])
        bearing = np.arctan2(d[:, 1], d[:, 0]) - pose[2]
        bearing = np.arctan2(np.sin(bearing), np.cos(bearing))
        seen = (dist <= max_range) & (dist > 0.3) & (np.abs(bearing) <= fov / 2)
        shift = 4
        scale = 1 << shift
        for i in np.flatnonzero(seen)[np.argsort(-dist[seen])]:  # far to near: near ones occlude
            half = math.atan2(cam.line_width / 2, dist[i])
            r0 = float(cam.radius(math.atan2(-cam.camera_height, dist[i])))
            r1 = float(cam.radius(math.atan2(cam.line_height - cam.camera_height, dist[i])))
            corners = [(cam.centre + r * math.cos(a), cam.centre - r * math.sin(a))
                       for r, a in ((r0, bearing[i] - half), (r1, bearing[i] - half), (r1, bearing[i] + half),
                                    (r0, bearing[i] + half))]
            pts = np.round(np.array(corners) * scale).astype(np.int32)
            cv2.fillConvexPoly(canvas, pts, 45.0, lineType=cv2.LINE_AA, shift=shift)
        n = cam.size * cam.size
        start = int(self.rng.integers(0, len(self.bank) - n))
        canvas += self.bank[start:start + n].reshape(cam.size, cam.size)
        return np.clip(canvas, 0, 255).astype(np.uint8)


@dataclass(frozen=True)
class Extractor:
    """Bearings of the radial lines in a round image (see the module docstring)."""

    cam: MirrorCamera
    rows: int = 1440
    highpass: int = 21
    threshold: float = 12.0
    min_separation: int = 6

    def polar(self, img: np.ndarray) -> np.ndarray:
        cam = self.cam
        cols = int(round(cam.r_outer))
        return cv2.warpPolar(img, (cols, self.rows), (cam.centre, cam.centre), cam.r_outer,
                             cv2.WARP_POLAR_LINEAR + cv2.INTER_LINEAR)

    def check(self, img: np.ndarray) -> str | None:
        """Why a frame cannot be read (``None`` if it can)."""
        if not isinstance(img, np.ndarray) or img.size == 0:
            return "empty frame"
        if img.dtype != np.uint8:
            return f"frame type {img.dtype}, not uint8"
        if img.ndim != 2 or img.shape != (self.cam.size, self.cam.size):
            return f"frame shape {img.shape}, not ({self.cam.size}, {self.cam.size})"
        return None

    def extract(self, img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bearings (rad, vehicle frame, wrapped) and their darkness scores; empty on a bad frame."""
        if self.check(img) is not None:
            return np.zeros(0), np.zeros(0)
        cam = self.cam
        p = self.polar(img).astype(np.float32)
        lo, hi = int(math.ceil(cam.r_blind + 2)), int(math.floor(cam.r_outer - 2))
        band = p[:, lo:hi]
        k = self.highpass
        padded = np.concatenate([band[-k:], band, band[:k]], axis=0)
        smooth = cv2.blur(padded, (1, k))[k:-k]
        dark = np.clip(smooth - band, 0.0, None)
        # darkness above the pixel noise, averaged over the ring's width
        score = np.clip(dark - 2.0 * cam.noise, 0.0, None).sum(axis=1) / band.shape[1] * 4.0
        kernel = np.array([1.0, 2.0, 3.0, 2.0, 1.0]) / 9.0  # one peak across a wide (near) line
        score = np.convolve(np.concatenate([score[-2:], score, score[:2]]), kernel, "same")[2:-2]
        left, right = np.roll(score, 1), np.roll(score, -1)
        peaks = np.flatnonzero((score > self.threshold) & (score >= left) & (score > right))
        if len(peaks) == 0:
            return np.zeros(0), np.zeros(0)
        # non-maximum suppression within min_separation rows (on the circle)
        peaks = peaks[np.argsort(-score[peaks])]
        kept: list[int] = []
        for i in peaks:
            if all(min(abs(i - j), self.rows - abs(i - j)) >= self.min_separation for j in kept):
                kept.append(int(i))
        kept_arr = np.array(sorted(kept))
        y0, y1, y2 = score[kept_arr - 1], score[kept_arr], score[(kept_arr + 1) % self.rows]
        denom = y0 - 2 * y1 + y2
        delta = np.where(np.abs(denom) > 1e-9, 0.5 * (y0 - y2) / denom, 0.0)
        # warpPolar's angle runs clockwise on screen (image y down): a = -angle
        angle = -2.0 * math.pi * (kept_arr + np.clip(delta, -0.5, 0.5)) / self.rows
        return np.arctan2(np.sin(angle), np.cos(angle)), y1


@dataclass
class ImageStage:
    """The image front end's output for one run.

    ``data`` holds the associated image bearings (``meas_lm`` are track ids; ``landmarks`` the
    majority true landmark of each track, NaN where a track has none, for scoring only);
    ``stats`` the stage's figures; ``frames`` a decimated sample ``(step, image, bearings)``
    for the recording.
    """

    data: OmniData
    stats: dict
    frames: list


BAD_FRAMES = ("empty", "wrong size", "wrong type", "blank")


def bad_frame(kind: str, cam: MirrorCamera) -> np.ndarray:
    """A frame the extractor must refuse or find nothing in (``BAD_FRAMES``)."""
    if kind == "empty":
        return np.zeros((0, 0), np.uint8)
    if kind == "wrong size":
        return np.full((cam.size // 2, cam.size), 128, np.uint8)
    if kind == "wrong type":
        return np.full((cam.size, cam.size), 0.5, np.float32)
    return np.full((cam.size, cam.size), 128, np.uint8)


def run_stage(data: OmniData, cam: MirrorCamera, cfg: OmniConfig, rng: np.random.Generator,
              keep_every: int = 0, bad_frames: int = 0) -> ImageStage:
    """Render a round image at every bearing epoch from the true pose, extract its bearings,
    associate them through the filter (:func:`associate.associate`: only confirmed tracks
    are kept; ``tracks_merged`` / ``tracks_rejected`` count the tentative tracks merged into a
    landmark or left out), and score the stage against the simulation.

    ``bad_frames`` frames (spread evenly, kinds in turn from ``BAD_FRAMES``) are replaced by
    bad ones: they give no bearings (the estimators coast on odometry) and are listed in
    ``stats["bad_frames"]`` with the reason, for the recording."""
    from workbench.experiments.omni.imaging.associate import associate, majority

    renderer, extractor = Renderer(cam, rng), Extractor(cam)
    steps, bearings, true_ids, frames, refused = [], [], [], [], []
    visible = matched = 0
    errors = []
    epochs = data.epochs()
    bad_at = {int(i): BAD_FRAMES[k % len(BAD_FRAMES)]
              for k, i in enumerate(np.linspace(0, len(epochs) - 1, bad_frames + 2)[1:-1].round())}
    t0 = time.perf_counter()
    for e, (step, idx) in enumerate(epochs):
        pose = data.truth[step]
        if e in bad_at:
            img = bad_frame(bad_at[e], cam)
            refused.append((int(step), extractor.check(img) or "no lines found"))
        else:
            img = renderer.render(pose, data.landmarks, data.max_range, data.fov)
        found, _ = extractor.extract(img)
        lm = data.meas_lm[idx]  # what the simulation says is in view (for scoring only)
        d = data.landmarks[lm] - pose[:2]
        truth_b = wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[2])
        ids = np.full(len(found), -1)
        if len(found) and len(lm):
            diff = np.abs(wrap(found[:, None] - truth_b[None, :]))
            near = diff.argmin(axis=1)
            close = diff[np.arange(len(found)), near] < math.radians(1.0)
            ids[close] = lm[near[close]]
            errors.extend(wrap(found[close] - truth_b[near[close]]))
            matched += len(set(ids[close].tolist()))
        visible += len(lm)
        steps += [step] * len(found)
        bearings += found.tolist()
        true_ids += ids.tolist()
        if keep_every and e % keep_every == 0 and e not in bad_at:
            frames.append((step, img, found))
    seconds = time.perf_counter() - t0
    steps_a, bear_a, true_a = np.array(steps, int), np.array(bearings, float), np.array(true_ids, int)
    raw = replace(data, meas_step=steps_a, meas_lm=np.zeros(len(steps_a), int), meas_bearing=bear_a)
    assoc = associate(raw, cfg)
    owner = majority(assoc.track, true_a, assoc.n_tracks)
    real = true_a >= 0
    correct = real & (assoc.track >= 0) & (owner[np.maximum(assoc.track, 0)] == true_a)
    keep = assoc.track >= 0
    lms = np.full((assoc.n_tracks, 2), np.nan)
    lms[owner >= 0] = data.landmarks[owner[owner >= 0]]
    associated = replace(data, meas_step=steps_a[keep], meas_lm=assoc.track[keep], meas_bearing=bear_a[keep],
                         meas_sigma=None, landmarks=lms, landmark_ids=np.arange(assoc.n_tracks))
    err = np.degrees(np.array(errors)) if errors else np.zeros(0)
    stats = {
        "frames": len(data.epochs()), "image_size": cam.size,
        "bearing_rmse": float(np.sqrt(np.mean(err**2))) if len(err) else None,
        "bearing_bias": float(np.mean(err)) if len(err) else None,
        "detection_rate": matched / visible if visible else None,
        "false_detections": int(np.sum(~real)),
        "association_rate": float(np.mean(correct[real])) if real.any() else None,
        "tracks": assoc.n_tracks, "landmarks": int(len(np.unique(owner[owner >= 0]))),
        "tracks_merged": assoc.merged, "tracks_rejected": assoc.rejected,
        "seconds": seconds, "bad_frames": refused,
    }
    return ImageStage(associated, stats, frames)
