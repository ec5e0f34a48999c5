"""From a sea frame to the object's angles: horizon, sea band, object, waterline, tracking.

Per frame (:class:`Tracker.step`):

1. **Check** the frame: a 2D uint8 (or 3-channel, converted to grey) array of the camera's
   size; anything else is "no detection" with the reason, never an exception.
2. **Horizon**: a coarse search (where there is no previous line) on a 1/k downsampled frame
   takes, per column, the strongest bright-to-dark step and fits a line robustly; then ~160
   columns (3-pixel averages) are refined to sub-pixel by the area of the step: with the sky
   and sea levels extrapolated linearly from either side of a small window, the edge lies
   at ``v_top - 1/2 + sum_k c_k``, ``c_k`` the sky's share of pixel k (exact for an area-
   sampled step). A line is fitted with residuals beyond 3 robust sigmas dropped, twice. No
   step above a minimum contrast (an all-sky or blank frame) is "no horizon". The horizon
   gives the platform's tilt and roll (:func:`camera.attitude_from_horizon`).
3. **Sea mask and object**: the band below the horizon down to ``max_depression`` is sheared
   so that the horizon is a row (the sea mask, rectified); each row's median is the sea's
   level there, and the darkness ``median - I`` above a threshold (5 robust sigmas of the
   band, at least ``min_contrast``) gives connected components. While tracking, only a gate
   around the predicted position counts and the nearest strong component wins; without a
   track, the darkest (largest summed darkness) anywhere in the band.
4. **Waterline to sub-pixel**, on the original pixels: the horizontal position is the
   darkness centroid (the silhouette is symmetric about its vertical axis); per column of the
   middle 60 % of the blob, the lower edge is the centroid of the darkness' fall across it
   (exact for an area-sampled step of any contrast); a line through those edges parallel to
   the horizon meets the vertical axis through the centroid at the waterline point.
5. **Angles**: the point is back-projected through the camera turned by the horizon's tilt
   and roll (the yaw, course plus the mount's pan, is known).
6. **Tracking**: a constant-velocity track in angle space predicts the next position; the
   gate grows while the track coasts through frames without a detection (a track loss, a bad
   frame) and the track is dropped after ``max_coast`` frames (then the band is searched).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from workbench.experiments.sea.imaging import camera as cam_model
from workbench.experiments.sea.imaging.camera import Camera


@dataclass
class Horizon:
    v_centre: float      # v of the line at u = cx
    slope: float         # dv/du
    rms: float           # residual RMS of the columns used, px
    used: int            # columns used

    def v_at(self, u, cx: float):
        return self.v_centre + self.slope * (np.asarray(u, float) - cx)


@dataclass
class Detection:
    """One frame's outcome; ``ok`` False carries the reason."""

    ok: bool = False
    reason: str = ""
    horizon: Horizon | None = None
    tilt: float = np.nan
    roll: float = np.nan
    point: tuple[float, float] = (np.nan, np.nan)       # waterline, px
    box: tuple[float, float, float, float] | None = None  # x0, y0, x1, y1 of the blob, px
    gate: tuple[float, float, float, float] | None = None
    alpha: float = np.nan
    beta: float = np.nan


@dataclass
class DetectorConfig:
    max_depression_deg: float = 5.0   # the search band's depth below the horizon
    min_contrast: float = 12.0        # grey levels: weakest horizon step / object darkness
    gate_px: float = 12.0             # gate half-size at 1920 px width (scaled with the width)
    gate_growth_px: float = 1.5       # per coasted frame, at 1920 px
    max_coast: int = 100              # frames without a detection before the track is dropped
    columns: int = 160                # horizon columns refined to sub-pixel


@dataclass
class Track:
    angles: np.ndarray                # alpha, beta, rad
    rate: np.ndarray = field(default_factory=lambda: np.zeros(2))  # per frame
    misses: int = 0
    size: tuple[float, float] = (4.0, 2.0)  # blob width, height, px


def as_gray(frame, cam: Camera) -> tuple[np.ndarray | None, str]:
    """The frame as a grey uint8 image of the camera's size, or None and why not."""
    if not isinstance(frame, np.ndarray):
        return None, f"bad frame: not an image ({type(frame).__name__})"
    if frame.size == 0:
        return None, "bad frame: empty"
    if frame.dtype != np.uint8:
        return None, f"bad frame: type {frame.dtype} (expected uint8)"
    if frame.ndim == 3 and frame.shape[2] == 3:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    if frame.ndim != 2:
        return None, f"bad frame: shape {frame.shape} (expected HxW or HxWx3)"
    if frame.shape != (cam.height, cam.width):
        return None, f"bad frame: size {frame.shape[1]}x{frame.shape[0]} (expected {cam.width}x{cam.height})"
    return frame, ""


def coarse_horizon(gray: np.ndarray, cam: Camera, dcfg: DetectorConfig) -> tuple[Horizon | None, str]:
    """The strongest bright-to-dark row step per column of a downsampled frame, fitted robustly."""
    H, W = gray.shape
    k = max(1, W // 240)
    small = cv2.resize(gray, (W // k, H // k), interpolation=cv2.INTER_AREA).astype(np.float32)
    step = small[:-1] - small[1:]               # positive where it gets darker downwards
    rows = np.argmax(step, axis=0)
    strength = step[rows, np.arange(step.shape[1])]
    good = strength >= dcfg.min_contrast * 0.5
    if good.sum() < 0.5 * len(good):
        return None, f"no horizon: no edge (strongest step {float(np.median(strength)):.1f} grey levels)"
    u = (np.arange(step.shape[1]) + 0.5) * k - 0.5
    v = (rows + 1.0) * k - 0.5
    line = _robust_line(u[good], v[good], cam.cx, floor=k)
    if line is None:
        return None, "no horizon: the edge is not a line"
    return line, ""


def _robust_line(u: np.ndarray, v: np.ndarray, cx: float, floor: float = 0.1,
                 weights: np.ndarray | None = None) -> Horizon | None:
    """``v = a + b (u - cx)`` by least squares, residuals past 3 robust sigmas dropped (twice)."""
    keep = np.isfinite(v)
    for _ in range(3):
        if keep.sum() < 5:
            return None
        A = np.stack([np.ones(keep.sum()), u[keep] - cx], axis=1)
        w = np.ones(keep.sum()) if weights is None else weights[keep]
        coef, *_ = np.linalg.lstsq(A * w[:, None], v[keep] * w, rcond=None)
        res = v - (coef[0] + coef[1] * (u - cx))
        sigma = max(1.4826 * np.median(np.abs(res[keep])), floor / 3.0)
        new = np.isfinite(res) & (np.abs(res) <= 3.0 * sigma)
        if np.array_equal(new, keep):
            break
        keep = new
    return Horizon(float(coef[0]), float(coef[1]), float(np.sqrt(np.mean(res[keep] ** 2))), int(keep.sum()))


def refine_horizon(gray: np.ndarray, cam: Camera, prior: Horizon, dcfg: DetectorConfig,
                   half: int) -> Horizon | None:
    """Sub-pixel horizon near ``prior``: the area of the sky-to-sea step in each sampled column."""
    H, W = gray.shape
    n = min(dcfg.columns, W // 3)
    cols = np.round(np.linspace(2, W - 3, n)).astype(int)
    centre = np.round(prior.v_at(cols, cam.cx)).astype(int)
    ok = (centre - half >= 0) & (centre + half + 1 < H)
    cols, centre = cols[ok], centre[ok]
    if len(cols) < 10:
        return None
    offs = np.arange(-half, half + 1)
    rows = centre[:, None] + offs[None, :]
    P = (gray[rows, cols[:, None] - 1].astype(np.float32) + gray[rows, cols[:, None]]
         + gray[rows, cols[:, None] + 1]) / 3.0                       # (n, 2 half + 1)
    # sky and sea levels: lines through the three outermost rows of each side, extrapolated
    x = offs.astype(np.float32)
    sky = _side_line(P[:, :3], x[:3], x)
    sea = _side_line(P[:, -3:], x[-3:], x)
    contrast = sky - sea
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.clip((P - sea) / contrast, -0.5, 1.5)
    c[:, :3] = 1.0
    c[:, -3:] = 0.0
    edge = centre - half - 0.5 + c.sum(axis=1)
    good = np.nanmin(contrast, axis=1) >= dcfg.min_contrast
    if good.sum() < 10:
        return None
    return _robust_line(cols[good].astype(float), edge[good], cam.cx, floor=0.1)


def _side_line(P: np.ndarray, x: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Per row of P, the least-squares line through ``(x, P)`` evaluated at ``at``: ``(n, len(at))``."""
    xm = x.mean()
    slope = ((P - P.mean(axis=1, keepdims=True)) * (x - xm)).sum(axis=1) / ((x - xm) ** 2).sum()
    slope = np.full_like(slope, np.median(slope))   # the same background slope in every column
    return P.mean(axis=1, keepdims=True) + slope[:, None] * (at[None, :] - xm)


def find_horizon(gray: np.ndarray, cam: Camera, dcfg: DetectorConfig,
                 prior: Horizon | None = None) -> tuple[Horizon | None, str]:
    scale = cam.width / 1920.0
    if prior is None:
        prior, why = coarse_horizon(gray, cam, dcfg)
        if prior is None:
            return None, why
        first = max(4, cam.width // 240 + 3)
    else:
        first = max(4, int(round(8 * scale)) + 3)
    line = refine_horizon(gray, cam, prior, dcfg, first)
    if line is None:
        return None, "no horizon: too few columns with a sky-to-sea step"
    fine = refine_horizon(gray, cam, line, dcfg, 5)
    if fine is None:
        return None, "no horizon: too few columns with a sky-to-sea step"
    return fine, ""


@dataclass
class Blob:
    point: tuple[float, float]
    box: tuple[float, float, float, float]
    size: tuple[float, float]
    mass: float


def find_object(gray: np.ndarray, cam: Camera, hz: Horizon, dcfg: DetectorConfig,
                gate: tuple[float, float, float, float] | None = None,
                predicted: tuple[float, float] | None = None) -> tuple[Blob | None, str]:
    """The object in the sea band below the horizon (inside ``gate`` when tracking)."""
    H, W = gray.shape
    top = -3                                          # rows relative to the horizon
    depth = int(np.ceil(cam.f * np.tan(np.deg2rad(dcfg.max_depression_deg))))
    x0, x1 = 0, W
    if gate is not None:
        x0, x1 = max(int(np.floor(gate[0])), 0), min(int(np.ceil(gate[2])) + 1, W)
        if x1 - x0 < 3:
            return None, "object not found: gate outside the frame"
    # the sea band, sheared so that the horizon is the row ``-top``
    M = np.array([[1.0, 0.0, 0.0], [hz.slope, 1.0, hz.v_centre - hz.slope * cam.cx + top]], np.float32)
    band = cv2.warpAffine(gray, M, (W, depth - top), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_REPLICATE).astype(np.float32)
    level = np.median(band, axis=1)
    dark = level[:, None] - band
    # per row: waves near the camera are rougher than the haze near the horizon
    sigma = 1.4826 * np.median(np.abs(dark), axis=1)
    row_thresh = np.maximum(dcfg.min_contrast, 5.0 * sigma)
    thresh = float(np.median(row_thresh[-top + 1:]))
    sub = dark[:, x0:x1]
    if gate is not None:
        gy0 = int(np.floor(gate[1] - hz.v_at(gate[0], cam.cx))) - top
        gy1 = int(np.ceil(gate[3] - hz.v_at(gate[0], cam.cx))) - top + 2
        sub = sub.copy()
        sub[: max(gy0, 0)] = 0
        sub[max(gy1, 0):] = 0
    mask = (sub > row_thresh[:, None]).astype(np.uint8)
    mask[: -top] = 0                                  # nothing above the horizon
    n, labels, stats, cent = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None, "object not found" + (" in the gate" if gate is not None else " in the sea band")
    masses = np.bincount(labels.ravel(), weights=np.clip(sub, 0, None).ravel(), minlength=n)[1:]
    area = stats[1:, cv2.CC_STAT_AREA]
    score = masses * (area >= 2)
    if predicted is not None and gate is not None:
        cu = cent[1:, 0] + x0
        cv = cent[1:, 1] + top + hz.v_at(cu, cam.cx)
        gw, gh = (gate[2] - gate[0]) / 2, (gate[3] - gate[1]) / 2
        score = score / (1.0 + ((cu - predicted[0]) / gw) ** 2 + ((cv - predicted[1]) / gh) ** 2)
    best = int(np.argmax(score))
    if score[best] <= 0:
        return None, "object not found: only specks"
    bx, by, bw, bh = stats[best + 1, :4]
    thresh = float(row_thresh[min(by + bh - 1, len(row_thresh) - 1)])
    return _waterline(gray, cam, hz, level, top, thresh, bx + x0, by, bw, bh, float(masses[best]))


def _waterline(gray, cam, hz, level, top, thresh, bx, by, bw, bh, mass) -> tuple[Blob | None, str]:
    """Sub-pixel waterline point of the blob found at ``(bx, by, bw, bh)`` of the sheared band."""
    H, W = gray.shape
    u0, u1 = max(bx - 2, 0), min(bx + bw + 2, W)
    vh = hz.v_at(np.arange(u0, u1), cam.cx)
    v0 = int(np.floor(vh.min() + by + top)) - 2
    v1 = int(np.ceil(vh.max() + by + bh + top)) + 4
    if v0 < 0 or v1 > H:
        return None, "object not found: at the frame's edge"
    patch = gray[v0:v1, u0:u1].astype(np.float32)
    uu = np.arange(u0, u1, dtype=float)[None, :]
    vv = np.arange(v0, v1, dtype=float)[:, None]
    rel = vv - hz.v_at(uu, cam.cx) - top               # row in the band's level profile
    bg = np.interp(rel, np.arange(len(level)), level)
    d = bg - patch
    w = np.where(d > 0.25 * thresh, d, 0.0)
    if w.sum() <= 0:
        return None, "object not found: no contrast"
    xc = float((w * uu).sum() / w.sum())
    yc = float((w * vv).sum() / w.sum())
    # lower edge per column, middle 60 % of the blob
    half = max(0.3 * bw, 0.6)
    cols = np.flatnonzero(np.abs(uu[0] - xc) <= half)
    if cols.size == 0:
        cols = np.array([int(np.argmin(np.abs(uu[0] - xc)))])
    edges, wts, us = [], [], []
    n = d.shape[0]
    for j in cols:
        prof = d[:, j]
        peak = prof.max()
        if peak < thresh:
            continue
        below = np.flatnonzero(prof > 0.5 * peak)
        rb = below[-1]
        k = np.arange(max(rb - 2, 0), min(rb + 3, n - 1))
        g = np.clip(prof[k] - prof[k + 1], 0.0, None)
        if g.sum() <= 0:
            continue
        edges.append(float((g * (k + 0.5)).sum() / g.sum()) + v0)
        wts.append(float(g.sum()))
        us.append(float(uu[0, j]))
    if not edges:
        return None, "object not found: no lower edge"
    edges, wts, us = np.array(edges), np.array(wts), np.array(us)
    v_wl = float(np.sum(wts * (edges - hz.slope * (us - xc))) / wts.sum())  # the waterline at u = xc
    roll = -np.arctan(hz.slope)
    # the vertical axis through the centroid meets the waterline
    u_p = xc - (yc - v_wl) * np.sin(roll) * np.cos(roll)
    v_p = v_wl + hz.slope * (u_p - xc)
    box = (float(u0 + 2), float(v0 + 2), float(u1 - 2), float(v1 - 4))
    return Blob((u_p, v_p), box, (float(bw), float(bh)), mass), ""


class Tracker:
    """Frame-by-frame detection with a constant-velocity angle track (see the module docstring)."""

    def __init__(self, cam: Camera, dcfg: DetectorConfig | None = None):
        self.cam = cam
        self.cfg = dcfg or DetectorConfig()
        self.track: Track | None = None
        self.horizon: Horizon | None = None

    def step(self, frame) -> Detection:
        cam, dcfg = self.cam, self.cfg
        det = Detection()
        if self.track is not None:
            self.track.angles = self.track.angles + self.track.rate  # predict to this frame
        gray, why = as_gray(frame, cam)
        if gray is None:
            return self._miss(det, why)
        hz, why = find_horizon(gray, cam, dcfg, self.horizon)
        if hz is None and self.horizon is not None:       # the prior may be stale: search afresh
            hz, why = find_horizon(gray, cam, dcfg, None)
        self.horizon = hz
        if hz is None:
            return self._miss(det, why)
        det.horizon = hz
        det.tilt, det.roll = cam_model.attitude_from_horizon(cam, hz.v_centre, hz.slope)
        gate = predicted = None
        if self.track is not None:
            scale = cam.width / 1920.0
            pu, pv = cam_model.project(cam, *self.track.angles, det.tilt, det.roll)
            if np.isfinite(pu) and np.isfinite(pv):
                grow = dcfg.gate_growth_px * scale * self.track.misses
                gw = max(dcfg.gate_px * scale, 1.5 * self.track.size[0]) + grow
                gh = max(dcfg.gate_px * scale, 1.5 * self.track.size[1]) + grow
                gate = (pu - gw, pv - gh, pu + gw, pv + gh)
                predicted = (float(pu), float(pv))
                det.gate = gate
        blob, why = find_object(gray, cam, hz, dcfg, gate, predicted)
        if blob is None:
            return self._miss(det, why)
        alpha, beta = cam_model.back_project(cam, *blob.point, det.tilt, det.roll)
        if not beta > 0:
            return self._miss(det, "object at or above the horizon")
        det.ok, det.point, det.box = True, blob.point, blob.box
        det.alpha, det.beta = float(alpha), float(beta)
        z = np.array([det.alpha, det.beta])
        if self.track is None:
            self.track = Track(z, size=blob.size)
        else:
            t = self.track
            steps = t.misses + 1
            resid = z - t.angles
            t.rate = t.rate + 0.3 * resid / steps
            t.angles = z
            t.misses = 0
            t.size = blob.size
        return det

    def _miss(self, det: Detection, reason: str) -> Detection:
        det.ok, det.reason = False, reason
        if self.track is not None:
            self.track.misses += 1
            if self.track.misses > self.cfg.max_coast:
                self.track = None
        return det
