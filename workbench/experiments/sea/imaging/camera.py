"""The sea camera: a pinhole on a platform that tilts and rolls a little, looking over a flat sea.

Frames (the image convention of OpenCV): pixel ``(u, v)``, u to the right, v down, the
centre of pixel ``(row i, column j)`` at ``(u, v) = (j, i)``; the principal point is the
image centre ``((W - 1) / 2, (H - 1) / 2)`` and the focal length ``f = (W / 2) / tan(fov / 2)``
(70 deg over 1920 px: f = 1371 px, 2.19' per pixel at the centre).

The *nominal* camera frame is level: x right, y down, z along the optical axis, which points
horizontally at azimuth ``pan`` from the platform's course psi (left positive, as alpha in
(1)). The platform's tilt theta (nose up positive) and roll phi (right side down positive)
turn the real camera: ``v_nominal = R v_camera`` with ``R = Rx(theta) Rz(phi)``.

A direction of azimuth alpha (from the course, left positive) and depression beta (below the
horizontal, as in (2)) is ``d = (-cos b sin a', sin b, cos b cos a')`` in the nominal frame,
``a' = alpha - pan``. The sea is flat (the paper's model (2)): the horizon is the image of
the horizontal directions, a straight line ``v = cy + f tan(theta) / cos(phi) - tan(phi) (u - cx)``,
so a detected horizon gives the tilt and roll back (:meth:`Camera.attitude_from_horizon`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    width: int = 1920
    height: int = 1080
    fov_deg: float = 70.0   # horizontal field of view
    pan: float = 0.0        # optical axis azimuth from the course, rad (left positive)

    @property
    def f(self) -> float:
        return (self.width / 2.0) / np.tan(np.deg2rad(self.fov_deg) / 2.0)

    @property
    def cx(self) -> float:
        return (self.width - 1) / 2.0

    @property
    def cy(self) -> float:
        return (self.height - 1) / 2.0

    @property
    def arcmin_per_pixel(self) -> float:
        return float(np.rad2deg(1.0 / self.f) * 60.0)


def rotation(tilt: float, roll: float) -> np.ndarray:
    """``R = Rx(tilt) Rz(roll)``: camera axes in the nominal (level) frame."""
    ct, st, cr, sr = np.cos(tilt), np.sin(tilt), np.cos(roll), np.sin(roll)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ct, -st], [0.0, st, ct]])
    rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    return rx @ rz


def direction(alpha, beta, pan: float) -> np.ndarray:
    """Unit direction ``(..., 3)`` in the nominal frame of azimuth alpha, depression beta."""
    a, b = np.broadcast_arrays(np.asarray(alpha, float) - pan, np.asarray(beta, float))
    return np.stack([-np.cos(b) * np.sin(a), np.sin(b), np.cos(b) * np.cos(a)], axis=-1)


def project(cam: Camera, alpha, beta, tilt: float = 0.0, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Pixel ``(u, v)`` of the direction (alpha, beta); NaN behind the camera."""
    d = direction(alpha, beta, cam.pan) @ rotation(tilt, roll)  # R^T d, row vectors
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(d[..., 2] > 1e-9, d[..., 2], np.nan)
        return cam.cx + cam.f * d[..., 0] / z, cam.cy + cam.f * d[..., 1] / z


def back_project(cam: Camera, u, v, tilt: float = 0.0, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth alpha (from the course) and depression beta of the pixel ``(u, v)``."""
    u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
    ray = np.stack([(u - cam.cx) / cam.f, (v - cam.cy) / cam.f, np.ones_like(u)], axis=-1)
    d = ray @ rotation(tilt, roll).T
    alpha = np.arctan2(-d[..., 0], d[..., 2]) + cam.pan
    beta = np.arctan2(d[..., 1], np.hypot(d[..., 0], d[..., 2]))
    return alpha, beta


def horizon_line(cam: Camera, tilt: float, roll: float) -> tuple[float, float]:
    """The horizon as ``(v at u = cx, slope dv/du)``."""
    return cam.cy + cam.f * np.tan(tilt) / np.cos(roll), -np.tan(roll)


def attitude_from_horizon(cam: Camera, v_centre: float, slope: float) -> tuple[float, float]:
    """Tilt and roll from a horizon line ``v = v_centre + slope (u - cx)``."""
    roll = -np.arctan(slope)
    tilt = np.arctan((v_centre - cam.cy) * np.cos(roll) / cam.f)
    return float(tilt), float(roll)


def parse_size(text: str) -> tuple[int, int]:
    """``"960x540"`` -> ``(960, 540)``; ValueError on anything else."""
    parts = text.lower().replace(" ", "").split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        raise ValueError(f"image size must be WIDTHxHEIGHT, e.g. 960x540, got {text!r}")
    return int(parts[0]), int(parts[1])
