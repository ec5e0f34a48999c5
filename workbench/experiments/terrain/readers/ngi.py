"""The real scene: two overlapping NGI aerial frames (Intergraph DMC, ~5 km above ground), their
known exterior orientation as the truth, and the real DEM (``data/ngi``, see its README).

Readings: the orientation file ``camera_pos_ori.txt`` (x, y, z in the transverse Mercator
frame, omega, phi, kappa in degrees; checked against ``ngi_xyz_opk.csv``, both read strictly by
:mod:`.ngi_orientation`) follows orthority's convention: ``R = Rx(omega) Ry(phi)
Rz(kappa)`` maps a PATB camera (x right, y up, z back) to the world, so the OpenCV camera's
``R_wc = R diag(1, -1, -1)``; it is turned into this package's (psi, theta, gamma). The frames
are read as grey (mean of RGB; an alpha channel left out; 8 or 16 bits) and shrunk to ``--size``
(the frames' aspect, no larger); the interior orientation is ``ngi_int_param.yaml``'s (read
strictly by :mod:`.ngi_interior`: 120 mm over a 92.16 x 165.888 mm frame of 640 x 1152 px,
principal point at the centre, for these frames) and scales with them. The time between the
exposures (for the common-error dynamics) is the baseline over ``--speed``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.errors import DataNotFound, require
from workbench.experiments.terrain import camera
from workbench.experiments.terrain.config import SCENARIOS, TerrainConfig
from workbench.experiments.terrain.dem import read_geotiff
from workbench.experiments.terrain.readers import ngi_interior, ngi_orientation
from workbench.experiments.terrain.scenario import Scene
from workbench.paths import data_root

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


def _frame(path: Path, size: tuple[int, int], native: tuple[int, int]) -> np.ndarray:
    """A frame as grey in [0, 1] at ``size``: colour averaged (alpha left out), 8 or 16 bits."""
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # it warns of every GeoTIFF tag; errors are ours
    require(path.is_file(), f"frame not found: {path}")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    require(img is not None, f"cannot read the frame {path.name} (corrupt TIFF?)")
    require(img.ndim == 2 or (img.ndim == 3 and img.shape[2] in (1, 3, 4)),
            f"{path.name}: {img.shape[2] if img.ndim == 3 else img.ndim} channels, expected grey, RGB or RGBA")
    full = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}.get(img.dtype)
    require(full is not None or img.dtype.kind == "f", f"{path.name}: {img.dtype} pixels (expected 8 or 16 bits)")
    if img.ndim == 3:
        img = img[:, :, :3] if img.shape[2] == 4 else img
    grey = img.astype(float).mean(axis=2) if img.ndim == 3 else img.astype(float)
    if full is not None:
        grey = grey / full
    require(bool(np.isfinite(grey).all()) and grey.min() >= 0.0 and grey.max() <= 1.0,
            f"{path.name}: floating-point pixels outside [0, 1] or not finite")
    require(grey.shape == (native[1], native[0]),
            f"{path.name} is {grey.shape[1]}x{grey.shape[0]}, but {ngi_interior.FILE} says {native[0]}x{native[1]}")
    return cv2.resize(grey, size, interpolation=cv2.INTER_AREA)


def check_size(size: tuple[int, int], native: tuple[int, int] = ngi_interior.DMC.size) -> None:
    w, h = size
    require(w <= native[0] and h <= native[1],
            f"--size {w}x{h} is larger than the ngi frames ({native[0]}x{native[1]})")
    require(abs((w / h) / (native[0] / native[1]) - 1.0) < 0.05,
            f"--size {w}x{h} does not keep the ngi frames' aspect ({native[0]}x{native[1]}; e.g. {DEFAULT_SIZE})")


def load(cfg: TerrainConfig) -> Scene:
    """The pair ``cfg.pair`` (image I first) with its true orientation and the DEM."""
    root = folder(cfg)
    w, h = cfg.image_size
    cam = ngi_interior.interior(root)
    check_size((w, h), cam.size)
    repairs: dict[str, int] = {}
    orient = {f: _pose(v) for f, v in ngi_orientation.orientation(root, tuple(cfg.pair), repairs).items()}
    dem = read_geotiff(root / "dem.tif")
    k = cam.intrinsics(w, h)
    position = np.stack([orient[f][0] for f in cfg.pair])
    angles = np.stack([camera.angles_from_rotation(orient[f][1]) for f in cfg.pair])
    images = np.stack([_frame(root / f"{PREFIX}{FRAME_FILES[f]}_RGB.tif", (w, h), cam.size) for f in cfg.pair])
    for i in range(2):
        u, v = k.pixel_grid(max(1, w // 20))
        camera.ground_points(dem, k, position[i], camera.rotation(angles[i]), u, v,
                             what=f"frame {cfg.pair[i]}'s footprint")
    interval = float(np.linalg.norm(position[1, :2] - position[0, :2]) / cfg.speed)
    depth = position[:, 2].mean() - dem.mean_height
    label = f"ngi {cfg.pair[0]}/{cfg.pair[1]} at {w}x{h}, ~{depth / k.fx:.0f} m pixels"
    return Scene(label, dem, k, position, angles, images, interval,
                 extras={"dem_path": str(root / "dem.tif"), "repairs": repairs})
