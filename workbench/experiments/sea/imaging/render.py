"""Synthetic sea frames from a scenario's true geometry (grey, uint8; colour only for display).

A frame is the flat sea of (2) seen through :mod:`.camera`: a sky whose brightness falls with
elevation, the horizon as an exact straight edge (anti-aliased by pixel area), a sea whose
brightness rises towards the horizon (haze) with two octaves of waves (a swell and a chop)
that drift with time and are fixed to the world, so they also move as the platform does.
Waves finer than the pixel footprint fade out instead of aliasing. The object is a small
boat silhouette drawn in the image at the scale ``f / depth`` of its true distance, upright
in the world, its waterline centre exactly at the projection of the true target point (the
point that (1)-(2) measure). Its area coverage comes from 8-16x supersampling, so edges are
sub-pixel true. Sensor noise is white, Gaussian, seeded: each frame a window, at a random
offset, of one field of normal draws made once per renderer.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from workbench.experiments.sea.imaging import camera as cam_model
from workbench.experiments.sea.imaging.camera import Camera

# the boat's silhouette in metres (lateral, up): a hull and a cabin, symmetric about x = 0,
# the waterline along y = 0 (only its centre is the measured point)
HULL = np.array([[-2.4, 0.0], [2.4, 0.0], [3.0, 0.9], [-3.0, 0.9]])
CABIN = np.array([[-1.1, 0.85], [1.1, 0.85], [0.9, 2.0], [-0.9, 2.0]])


@dataclass(frozen=True)
class Look:
    """Grey levels and wave sizes of the synthetic scene."""

    sky_horizon: float = 196.0
    sky_zenith: float = 150.0
    sea_horizon: float = 124.0
    sea_near: float = 72.0
    haze: float = 0.08          # rad: the sea brightens towards the horizon over this depression
    boat: float = 30.0
    swell: tuple[float, float] = (9.0, 18.0)   # amplitude (grey), wavelength (m)
    chop: tuple[float, float] = (7.0, 2.5)
    swell_drift: tuple[float, float] = (1.2, 0.4)   # m/s
    chop_drift: tuple[float, float] = (-0.5, 1.1)


TILE = 256
NOISE_PAD = 257
"""How much larger than a frame (each way, pixels) the sensor-noise field is: the offsets a frame's
window is drawn from."""


def wave_tile(rng: np.random.Generator) -> np.ndarray:
    """A tileable ``TILE x TILE`` wave height field, unit std, one dominant wavelength of 16 texels.

    Band-passed white noise, elongated across the wind (crests longer than the waves).
    """
    noise = rng.standard_normal((TILE, TILE))
    k = np.fft.fftfreq(TILE)
    kx, ky = np.meshgrid(k, k)
    kr = np.hypot(kx * 1.0, ky * 2.5)
    band = np.exp(-0.5 * ((kr - 1.0 / 16.0) / 0.02) ** 2)
    field = np.real(np.fft.ifft2(np.fft.fft2(noise) * band))
    return (field / field.std()).astype(np.float32)


class Renderer:
    """Frames of one camera; ``frame`` draws one step. Pre-computes the pixel rays once."""

    def __init__(self, cam: Camera, camera_height: float, rng: np.random.Generator, look: Look | None = None):
        self.cam = cam
        self.h = float(camera_height)
        self.look = look or Look()
        self.tile = wave_tile(rng)
        self._field_rng = np.random.default_rng(rng.integers(0, 2**63))
        self._field: np.ndarray | None = None
        # sky and sea are smooth: computed on a half-resolution grid, then upsampled; the horizon
        # edge and the boat are drawn at full resolution
        self.w2, self.h2 = (cam.width + 1) // 2, (cam.height + 1) // 2
        u = (2.0 * np.arange(self.w2, dtype=np.float32) + 0.5 - np.float32(cam.cx)) / np.float32(cam.f)
        v = (2.0 * np.arange(self.h2, dtype=np.float32) + 0.5 - np.float32(cam.cy)) / np.float32(cam.f)
        self.X, self.Y = np.meshgrid(u, v)
        self.U = np.arange(cam.width, dtype=np.float32)[None, :]
        self.V = np.arange(cam.height, dtype=np.float32)[:, None]

    def frame(self, tilt: float, roll: float, observer_xy, axis_yaw: float, t: float,
              target: tuple[float, float, float] | None, rng: np.random.Generator | None = None,
              noise: float = 0.0) -> np.ndarray:
        """One grey frame.

        ``axis_yaw`` is the optical axis' direction in the world (course + pan, from +x, CCW);
        ``target`` is ``(alpha, beta, slant distance)`` of the object, or None where it is not
        to be seen (the track-loss window).
        """
        cam, L = self.cam, self.look
        H, W = cam.height, cam.width
        R = cam_model.rotation(tilt, roll).astype(np.float32)
        vc, slope = cam_model.horizon_line(cam, tilt, roll)
        hv = vc + slope * (np.array([0.0, W - 1.0]) - cam.cx)
        r_sea = int(np.clip(np.floor(hv.min()) - 1, 0, H))     # rows above: all sky
        r_sky = int(np.clip(np.ceil(hv.max()) + 2, 0, H))      # rows below: all sea
        # half-resolution rows that cover each layer, with a margin for the upsampling
        s0, s1 = max(r_sea // 2 - 2, 0), min(r_sky // 2 + 3, self.h2)
        img = np.empty((H, W), np.float32)
        if r_sky > 0:  # sky: brightness falls with elevation (sin e = -d_y / |d|)
            X, Y, r = self.X[:s1], self.Y[:s1], R.astype(float)
            dx = cv2.addWeighted(X, r[0, 0], Y, r[0, 1], r[0, 2])
            dy = cv2.addWeighted(X, r[1, 0], Y, r[1, 1], r[1, 2])
            dz = cv2.addWeighted(X, r[2, 0], Y, r[2, 1], r[2, 2])
            sin_e = cv2.divide(dy, cv2.magnitude(cv2.magnitude(dx, dy), dz), scale=-1.0)
            np.clip(sin_e, 0.0, 1.0, out=sin_e)
            sky = cv2.addWeighted(sin_e, L.sky_zenith - L.sky_horizon, sin_e, 0.0, L.sky_horizon)
            img[:r_sky] = self._up(sky, 0)[:r_sky]
        if r_sea < H:
            sea = self._up(self._sea(R, s0, observer_xy, axis_yaw, t), s0)
            off = 2 * s0
            if r_sky > r_sea:  # the horizon rows: blend by the sea's share of each pixel
                s = self.V[r_sea:r_sky] - np.float32(vc) - np.float32(slope) * (self.U - np.float32(cam.cx))
                cover = np.clip(s + 0.5, 0.0, 1.0)
                band = img[r_sea:r_sky]
                img[r_sea:r_sky] = band + (sea[r_sea - off: r_sky - off] - band) * cover
            img[r_sky:] = sea[r_sky - off: H - off]
        if target is not None:
            self._boat(img, tilt, roll, target)
        if noise > 0 and rng is not None:
            # white Gaussian sensor noise: a window of the renderer's noise field at an offset
            # drawn from ``rng`` (a fresh draw of 2 million normals per frame took half the
            # frame's time at 1920x1080; any one frame's noise is white, N(0, noise^2), and two
            # frames share a pixel's draw only where their offsets coincide, 1 in 66,000)
            oy, ox = (int(x) for x in rng.integers(0, NOISE_PAD, size=2))
            img += np.float32(noise) * self._noise()[oy:oy + H, ox:ox + W]
        np.add(img, 0.5, out=img)
        np.clip(img, 0, 255, out=img)
        return img.astype(np.uint8)

    def _noise(self) -> np.ndarray:
        """The renderer's field of N(0, 1) draws, ``NOISE_PAD`` larger than a frame each way,
        drawn once from its own seeded generator."""
        if self._field is None:
            H, W = self.cam.height, self.cam.width
            self._field = self._field_rng.standard_normal((H + NOISE_PAD, W + NOISE_PAD), dtype=np.float32)
        return self._field

    def _up(self, layer: np.ndarray, r0: int) -> np.ndarray:
        """Half-resolution rows ``r0..`` to full resolution (rows ``2 r0..``), full width."""
        return cv2.resize(layer, (2 * self.w2, 2 * layer.shape[0]), interpolation=cv2.INTER_LINEAR)[:, : self.cam.width]

    def _sea(self, R: np.ndarray, r0: int, observer_xy, yaw: float, t: float) -> np.ndarray:
        """The sea at half resolution from row ``r0``: haze by depression angle, two octaves of
        waves fixed to the world, faded where finer than the pixel footprint. Written with
        OpenCV's fused float32 primitives (``addWeighted``, ``magnitude``, ``phase`` (atan2 to
        2e-4 rad), ``exp``): one pass per line instead of numpy's temporaries."""
        L, cam = self.look, self.cam
        X, Y = self.X[r0:], self.Y[r0:]
        r = R.astype(float)
        dx = cv2.addWeighted(X, r[0, 0], Y, r[0, 1], r[0, 2])
        dy = cv2.addWeighted(X, r[1, 0], Y, r[1, 1], r[1, 2])
        dz = cv2.addWeighted(X, r[2, 0], Y, r[2, 1], r[2, 2])
        np.maximum(dy, np.float32(1e-6), out=dy)
        depression = cv2.phase(cv2.magnitude(dx, dz), dy)          # atan2(d_y, horizontal)
        haze = cv2.exp(cv2.multiply(depression, -1.0 / L.haze))
        sea = cv2.addWeighted(haze, L.sea_horizon - L.sea_near, haze, 0.0, L.sea_near)
        s = cv2.divide(float(self.h), dy)                           # ray length to the sea plane
        fwd, right = cv2.multiply(s, dz), cv2.multiply(s, dx)
        k = cv2.magnitude(fwd, right)                               # ground range
        # m per pixel (radial): k (k / h + 1) / f
        footprint = cv2.addWeighted(cv2.multiply(k, k), 1.0 / (self.h * cam.f), k, 1.0 / cam.f, 0.0)
        c, sn = float(np.cos(yaw)), float(np.sin(yaw))
        # world position relative to the observer; the observer's own offset is taken modulo
        # the tile (remap wraps, and its fixed-point maps hold under 32767 texels)
        wx = cv2.addWeighted(fwd, c, right, sn, 0.0)
        wy = cv2.addWeighted(fwd, sn, right, -c, 0.0)
        for (amp, wavelength), drift in ((L.swell, L.swell_drift), (L.chop, L.chop_drift)):
            texel = wavelength / 16.0
            q = cv2.multiply(footprint, 4.0 / wavelength)
            fade = cv2.exp(cv2.multiply(q, q, scale=-1.0))
            ox = float(np.mod((observer_xy[0] - drift[0] * t) / texel, TILE))
            oy = float(np.mod((observer_xy[1] - drift[1] * t) / texel, TILE))
            mx = cv2.addWeighted(wx, 1.0 / texel, wx, 0.0, ox)
            my = cv2.addWeighted(wy, 1.0 / texel, wy, 0.0, oy)
            waves = cv2.remap(self.tile, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
            sea = cv2.scaleAdd(cv2.multiply(fade, waves), float(amp), sea)
        return sea

    def boat_polygons(self, tilt: float, roll: float, target: tuple[float, float, float]) -> list[np.ndarray]:
        """The silhouette's polygons in pixels; the waterline centre at the target's projection."""
        cam = self.cam
        alpha, beta, dist = target
        u0, v0 = cam_model.project(cam, alpha, beta, tilt, roll)
        k = dist * np.cos(beta)
        u1, v1 = cam_model.project(cam, alpha, np.arctan2(self.h - 1.0, k), tilt, roll)
        up = np.array([u1 - u0, v1 - v0])
        up /= np.linalg.norm(up)
        lateral = np.array([-up[1], up[0]])
        depth = dist * (cam_model.direction(alpha, beta, cam.pan) @ cam_model.rotation(tilt, roll))[2]
        scale = cam.f / depth
        return [np.array([u0, v0]) + scale * (p[:, :1] * lateral + p[:, 1:] * up) for p in (HULL, CABIN)]

    def _boat(self, img: np.ndarray, tilt: float, roll: float, target) -> None:
        polys = self.boat_polygons(tilt, roll, target)
        pts = np.concatenate(polys)
        if not np.all(np.isfinite(pts)):
            return
        H, W = img.shape
        x0, y0 = np.floor(pts.min(axis=0)).astype(int) - 2
        x1, y1 = np.ceil(pts.max(axis=0)).astype(int) + 3
        if x1 <= 0 or y1 <= 0 or x0 >= W or y0 >= H:
            return
        S = 16 if max(x1 - x0, y1 - y0) < 64 else 8
        canvas = np.zeros(((y1 - y0) * S, (x1 - x0) * S), np.uint8)
        shift = 4
        for p in polys:
            # fillPoly fills every canvas pixel whose centre is on or inside the outline, which
            # makes a polygon half a canvas pixel too big on each side: inset it by that much
            c = _inset((p - [x0, y0] + 0.5) * S - 0.5, 0.5) * (1 << shift)
            cv2.fillPoly(canvas, [np.round(c).astype(np.int32)], 255, cv2.LINE_8, shift)
        cover = cv2.resize(canvas, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
        # clip the patch to the frame
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
        c = cover[cy0 - y0: cy1 - y0, cx0 - x0: cx1 - x0]
        patch = img[cy0:cy1, cx0:cx1]
        img[cy0:cy1, cx0:cx1] = patch + (self.look.boat - patch) * c


def _inset(poly: np.ndarray, d: float) -> np.ndarray:
    """A convex polygon with every edge moved inwards by ``d`` (its vertices where the moved edges meet)."""
    n = len(poly)
    area2 = np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    sign = 1.0 if area2 > 0 else -1.0
    lines = []
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        t = (b - a) / np.linalg.norm(b - a)
        normal = sign * np.array([-t[1], t[0]])          # points inwards
        lines.append((a + d * normal, t))
    out = np.empty_like(poly)
    for i in range(n):
        (p1, t1), (p2, t2) = lines[i - 1], lines[i]
        s = np.linalg.solve(np.stack([t1, -t2], axis=1), p2 - p1)
        out[i] = p1 + s[0] * t1
    return out


def colour(gray: np.ndarray) -> np.ndarray:
    """A display colour (BGR) for a grey frame: sky blue above the sea's levels, sea blue-green below."""
    lut = np.zeros((256, 1, 3), np.uint8)
    g = np.arange(256, dtype=np.float32)
    sky = np.clip(g / 255.0, 0, 1)
    lut[:, 0, 0] = np.clip(g * 1.15, 0, 255)                       # B
    lut[:, 0, 1] = np.clip(g * np.where(g > 160, 1.0, 0.95), 0, 255)  # G
    lut[:, 0, 2] = np.clip(g * np.where(g > 160, 0.85 + 0.1 * sky, 0.55), 0, 255)  # R
    return cv2.LUT(cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR), lut)
