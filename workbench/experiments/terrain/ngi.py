"""The real scene: two overlapping NGI aerial frames (Intergraph DMC, ~5 km above ground), their
known exterior orientation as the truth, and the real DEM (``data/ngi``, see its README).

Readings: the orientation file ``camera_pos_ori.txt`` (x, y, z in the transverse Mercator
frame, omega, phi, kappa in degrees; checked against ``ngi_xyz_opk.csv``, both read strictly by
:mod:`.ngi_orientation`) follows orthority's convention: ``R = Rx(omega) Ry(phi)
Rz(kappa)`` maps a PATB camera (x right, y up, z back) to the world, so the OpenCV camera's
``R_wc = R diag(1, -1, -1)``; it is turned into this package's (psi, theta, gamma). The frames
are read as grey (mean of RGB) and shrunk to ``--size`` (same aspect as 640 x 1152, no larger);
the interior orientation (120 mm over a 92.16 x 165.888 mm frame, principal point at the
centre) scales with them. The time between the exposures (for the common-error dynamics) is the
baseline over ``--speed``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.errors import DataNotFound, require
from workbench.experiments.terrain import camera, ngi_orientation
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.config import SCENARIOS, TerrainConfig
from workbench.experiments.terrain.dem import read_geotiff
from workbench.experiments.terrain.scenario import Scene
from workbench.paths import data_root

NATIVE = (640, 1152)
FOCAL_MM = 120.0
SENSOR_MM = (92.16, 165.888)
PREFIX = "3324c_2015_1004_"
FRAME_FILES = {"0182": "05_0182", "0184": "05_0184", "0251": "06_0251", "0253": "06_0253"}
DEFAULT_SIZE = SCENARIOS["ngi"].defaults["size"]


def folder(cfg: TerrainConfig) -> Path:
    path = Path(cfg.data).expanduser() if cfg.data is not None else data_root() / "ngi"
    hint = "" if cfg.data is not None else " (set WORKBENCH_DATA or pass --data)"
    if not path.is_dir():
        raise DataNotFound(f"ngi data folder not found: {path}{hint}")
    return path


def opk_rotation(omega: float, phi: float, kappa: float) -> np.ndarray:
    """``R_wc`` (OpenCV camera to world) from orthority's omega, phi, kappa (radians)."""
    co, so, cp, sp, ck, sk = np.cos(omega), np.sin(omega), np.cos(phi), np.sin(phi), np.cos(kappa), np.sin(kappa)
    rx = np.array([[1, 0, 0], [0, co, -so], [0, so, co]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[ck, -sk, 0], [sk, ck, 0], [0, 0, 1]])
    return rx @ ry @ rz @ np.diag([1.0, -1.0, -1.0])


def read_orientation(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Frame id -> (position (3,), R_wc (3, 3)) from ``camera_pos_ori.txt`` or ``ngi_xyz_opk.csv``
    (read strictly: :mod:`.ngi_orientation`)."""
    return {f: _pose(v) for f, v in ngi_orientation.read(path).items()}


def _pose(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.array(values[:3]), opk_rotation(*np.radians(values[3:]))


def _frame(path: Path, size: tuple[int, int]) -> np.ndarray:
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # it warns of every GeoTIFF tag; errors are ours
    require(path.is_file(), f"frame not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    require(img is not None, f"cannot read the frame {path.name} (corrupt TIFF?)")
    img = img.astype(float)
    grey = img.mean(axis=2) if img.ndim == 3 else img
    grey = grey / (255.0 if img.max() > 1.5 else 1.0)
    require(grey.shape == (NATIVE[1], NATIVE[0]),
            f"{path.name} is {grey.shape[1]}x{grey.shape[0]}, expected {NATIVE[0]}x{NATIVE[1]}")
    return cv2.resize(grey, size, interpolation=cv2.INTER_AREA)


def check_size(size: tuple[int, int]) -> None:
    w, h = size
    require(w <= NATIVE[0] and h <= NATIVE[1],
            f"--size {w}x{h} is larger than the ngi frames ({NATIVE[0]}x{NATIVE[1]})")
    require(abs((w / h) / (NATIVE[0] / NATIVE[1]) - 1.0) < 0.05,
            f"--size {w}x{h} does not keep the ngi frames' aspect (640x1152; e.g. {DEFAULT_SIZE} or 320x576)")


def load(cfg: TerrainConfig) -> Scene:
    """The pair ``cfg.pair`` (image I first) with its true orientation and the DEM."""
    root = folder(cfg)
    w, h = cfg.image_size
    check_size((w, h))
    orient = {f: _pose(v) for f, v in ngi_orientation.orientation(root, tuple(cfg.pair)).items()}
    dem = read_geotiff(root / "dem.tif")
    fx = FOCAL_MM * w / SENSOR_MM[0]
    fy = FOCAL_MM * h / SENSOR_MM[1]
    k = Intrinsics(fx, fy, (w - 1) / 2.0, (h - 1) / 2.0, w, h)
    position = np.stack([orient[f][0] for f in cfg.pair])
    angles = np.stack([camera.angles_from_rotation(orient[f][1]) for f in cfg.pair])
    images = np.stack([_frame(root / f"{PREFIX}{FRAME_FILES[f]}_RGB.tif", (w, h)) for f in cfg.pair])
    for i in range(2):
        u, v = k.pixel_grid(max(1, w // 20))
        camera.ground_points(dem, k, position[i], camera.rotation(angles[i]), u, v,
                             what=f"frame {cfg.pair[i]}'s footprint")
    interval = float(np.linalg.norm(position[1, :2] - position[0, :2]) / cfg.speed)
    depth = position[:, 2].mean() - dem.mean_height
    label = f"ngi {cfg.pair[0]}/{cfg.pair[1]} at {w}x{h}, ~{depth / fx:.0f} m pixels"
    return Scene(label, dem, k, position, angles, images, interval)
