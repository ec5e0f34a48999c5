"""A terrain log of your own, in an open format (``docs/log-formats.md``): what ``--scenario log
--data DIR`` reads and ``--export-data DIR`` writes (run 0's dataset of any scenario).

A folder; the world frame's x east, y north, z up in metres (the DEM's frame), the orientation
angles ``(psi, theta, gamma)`` in radians in the convention of :func:`.camera.rotation`:

====================  ========================================================================
``manifest.json``     the interior orientation ``fx_px``, ``fy_px``, ``cx_px``, ``cy_px`` (pixels
                      of the frames as they are), ``interval_s`` (between the exposures),
                      optionally ``label``
``image_1.tif``,      the two frames, image I first: grey (8 or 16 bits, scaled to [0, 1], or
``image_2.tif``       floating point as they are; colour frames are averaged), the same size;
                      PNG too (``image_1.png``)
``orientation.csv``   ``exposure`` (1, 2), ``x_m``, ``y_m``, ``z_m``, ``psi_rad``, ``theta_rad``,
                      ``gamma_rad``: the navigation system's measured orientation of each exposure
``truth.csv``         optional: the same columns, the true orientation (scores the estimates)
``dem.tif``           the DEM: a GeoTIFF placed by its pixel scale (33550) and tie point (33922)
====================  ========================================================================

The navigation error state that the scores read (``measured - true``) is solved from the two
orientations in the run's error mode (:func:`.navigation.error_map`: exact in both modes).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.scenario import Scene, TerrainData
from workbench.io import logs as logfiles

FORMAT = 1
COLUMNS = ("exposure", "x_m", "y_m", "z_m", "psi_rad", "theta_rad", "gamma_rad")
MANIFEST = ("fx_px", "fy_px", "cx_px", "cy_px", "interval_s")


def write(data: TerrainData, folder: Path, force: bool = False) -> list[Path]:
    """The dataset as a log folder: the frames as 64-bit float TIFFs (exact), the DEM as a
    GeoTIFF (north up; the synthetic DEM's rows turned over), the orientations as CSV."""
    import io

    import tifffile

    from workbench.experiments.terrain.products import geotiff
    from workbench.recording.stream import check_plain_output, write_bytes_atomic

    sc, folder = data.scene, Path(folder)
    k = sc.k
    files = {"orientation.csv": (COLUMNS, _rows(data.measured.position, data.measured.angles))}
    if np.isfinite(sc.position).all() and np.isfinite(sc.angles).all():
        files["truth.csv"] = (COLUMNS, _rows(sc.position, sc.angles))
    meta = {"format": FORMAT, "experiment": "terrain", "fx_px": k.fx, "fy_px": k.fy, "cx_px": k.cx, "cy_px": k.cy,
            "interval_s": sc.interval, "label": sc.label}
    dem = sc.dem
    north_up = dem.dy < 0
    heights = dem.heights if north_up else dem.heights[::-1]
    top = dem.y0 if north_up else dem.y0 + (len(dem.heights) - 1) * dem.dy  # the first row's y, north up
    require(abs(abs(dem.dy) - dem.dx) <= 1e-12 * dem.dx, "the DEM's spacing must be square to be written")
    source = sc.extras.get("dem_path")
    crs = geotiff.crs_of(Path(source)) if source else geotiff.local_crs("workbench synthetic frame, metres")
    rasters = {"dem.tif": geotiff.encode(np.ascontiguousarray(heights, np.float64), crs,
                                         corner=(dem.x0 - dem.dx / 2, top + dem.dx / 2),
                                         spacing=dem.dx, description=sc.label)}
    for i in range(2):
        buf = io.BytesIO()
        tifffile.imwrite(buf, np.ascontiguousarray(sc.images[i], np.float64), photometric="minisblack")
        rasters[f"image_{i + 1}.tif"] = buf.getvalue()
    for name in (*rasters, *files, "manifest.json"):  # every path checked before any is written
        check_plain_output(folder / name, force, "log file")
    paths = []
    for name, blob in rasters.items():
        write_bytes_atomic(folder / name, blob, force)
        paths.append(folder / name)
    return paths + logfiles.write(folder, files, meta, force)


def _rows(position: np.ndarray, angles: np.ndarray) -> np.ndarray:
    return np.column_stack([[1.0, 2.0], position, angles])


def read(folder: Path, cfg: TerrainConfig, run: int) -> TerrainData:
    """A log folder as a :class:`TerrainData` (the true orientation NaN where the log has none)."""
    from workbench.experiments.terrain.dem import read_geotiff

    folder = Path(folder).expanduser()
    require(folder.is_dir(), f"--data {folder}: not a log folder (it needs manifest.json, image_1.tif, "
                             "image_2.tif, orientation.csv, dem.tif)")
    where = folder / "manifest.json"
    m = logfiles.manifest(where, MANIFEST, positive=("fx_px", "fy_px", "interval_s"))
    frames = [_frame(folder, i) for i in (1, 2)]
    require(frames[0].shape == frames[1].shape, f"{folder}: the two frames differ in size "
                                                f"({frames[0].shape[1]}x{frames[0].shape[0]} and "
                                                f"{frames[1].shape[1]}x{frames[1].shape[0]})")
    images = np.stack(frames)
    h, w = images[0].shape
    k = Intrinsics(m["fx_px"], m["fy_px"], m["cx_px"], m["cy_px"], w, h)
    repairs: dict[str, int] = {}
    measured = _orientation(folder, "orientation", repairs)
    truth = (_orientation(folder, "truth", repairs) if logfiles.has(folder, "truth")
             else (np.full((2, 3), np.nan), np.full((2, 3), np.nan)))
    dem_path = folder / "dem.tif"
    if not dem_path.is_file():
        raise WorkbenchError(f"{dem_path}: missing (the DEM, a GeoTIFF)")
    dem = read_geotiff(dem_path)
    scene = Scene(str(m.get("label") or f"log {folder.name}"), dem, k, truth[0], truth[1], images,
                  float(m["interval_s"]), extras={"dem_path": str(dem_path), "repairs": repairs})
    meas = Estimate(*measured)
    state = np.full(len(navigation.STATE[cfg.mode]), np.nan)
    if np.isfinite(truth[0]).all():
        state = _state(cfg.mode, scene.interval, meas, truth)
    rng = np.random.default_rng([cfg.seed, run, 1])
    return TerrainData(scene, meas, state, cfg.mode, rng.bit_generator.state)


def _state(mode: str, interval: float, meas: Estimate, truth: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The navigation error state (``measured - true``) in ``mode``, from the two orientations:
    the least-squares solution of :func:`.navigation.error_map` (exact where they fit the mode)."""
    err = np.concatenate([meas.position - truth[0], meas.angles - truth[1]], axis=1)  # (2, 6), POSE's order
    M = navigation.error_map(mode, interval)
    state, *_ = np.linalg.lstsq(M.reshape(12, -1), err.reshape(12), rcond=None)
    return state


def _orientation(folder: Path, name: str, repairs: dict) -> tuple[np.ndarray, np.ndarray]:
    path = folder / f"{name}.csv"
    tab = logfiles.table(folder, name, COLUMNS, repairs)
    ids = logfiles.integers(path, tab, "exposure")
    require(sorted(ids.tolist()) == [1, 2], f"{path}: needs one row for exposure 1 and one for exposure 2, "
                                            f"got {sorted(ids.tolist())}")
    for col in ("psi_rad", "theta_rad", "gamma_rad"):
        logfiles.within(path, tab, col, 2 * math.pi)
    order = np.argsort(ids)
    position = np.column_stack([tab[c] for c in ("x_m", "y_m", "z_m")])[order]
    angles = np.column_stack([tab[c] for c in ("psi_rad", "theta_rad", "gamma_rad")])[order]
    return position, angles


def _frame(folder: Path, i: int) -> np.ndarray:
    """Frame ``i`` as grey irradiance: integers scaled to [0, 1], floats as they are."""
    import cv2

    path = next((folder / f"image_{i}.{ext}" for ext in ("tif", "tiff", "png") if (folder / f"image_{i}.{ext}")
                 .is_file()), None)
    if path is None:
        raise WorkbenchError(f"{folder / f'image_{i}.tif'}: missing (frame {'I' if i == 1 else 'II'}; .tif or .png)")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    require(img is not None and img.ndim in (2, 3) and min(img.shape[:2]) >= 16,
            f"{path}: not an image OpenCV reads, or smaller than 16 x 16 pixels")
    if img.ndim == 3:
        img = img[..., :3].astype(np.float64).mean(axis=2) if img.shape[2] >= 3 else img[..., 0]
    if img.dtype == np.uint8:
        img = img / 255.0
    elif img.dtype == np.uint16:
        img = img / 65535.0
    img = np.asarray(img, np.float64)
    require(np.isfinite(img).all(), f"{path}: has pixels that are not finite numbers")
    return img
