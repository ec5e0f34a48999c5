"""Digital elevation maps h(X, Y): a regular grid sampled bilinearly (with the interpolant's
gradient), a synthetic relief at several scales, and the real GeoTIFF DEM read without GDAL.

Grid convention: ``heights[row, col]`` is at ``X = x0 + col * dx``, ``Y = y0 + row * dy``
(``dy < 0`` for a north-up raster).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require


@dataclass
class Dem:
    heights: np.ndarray
    x0: float
    y0: float
    dx: float
    dy: float

    @property
    def mean_height(self) -> float:
        return float(np.nanmean(self.heights))

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of the grid nodes."""
        rows, cols = self.heights.shape
        xs = (self.x0, self.x0 + (cols - 1) * self.dx)
        ys = (self.y0, self.y0 + (rows - 1) * self.dy)
        return min(xs), max(xs), min(ys), max(ys)

    def _fractional(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(x, float) - self.x0) / self.dx, (np.asarray(y, float) - self.y0) / self.dy

    def covers(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        c, r = self._fractional(x, y)
        rows, cols = self.heights.shape
        return (c >= 0) & (c <= cols - 1) & (r >= 0) & (r <= rows - 1) & np.isfinite(c) & np.isfinite(r)

    def sample(self, x: np.ndarray, y: np.ndarray, strict: bool = True
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bilinear height and its exact X, Y derivatives; outside the grid the edge is held
        (``strict`` raises instead)."""
        c, r = self._fractional(x, y)
        if strict:
            require(bool(self.covers(x, y).all()), "the DEM does not cover the requested points")
        rows, cols = self.heights.shape
        c = np.clip(np.nan_to_num(c), 0.0, cols - 1.000001)
        r = np.clip(np.nan_to_num(r), 0.0, rows - 1.000001)
        c0, r0 = np.floor(c).astype(np.intp), np.floor(r).astype(np.intp)
        fc, fr = c - c0, r - r0
        z = self.heights
        z00, z01 = z[r0, c0], z[r0, c0 + 1]
        z10, z11 = z[r0 + 1, c0], z[r0 + 1, c0 + 1]
        top = z00 + fc * (z01 - z00)
        bot = z10 + fc * (z11 - z10)
        h = top + fr * (bot - top)
        dh_dc = (z01 - z00) + fr * ((z11 - z10) - (z01 - z00))
        dh_dr = bot - top
        return h, dh_dc / self.dx, dh_dr / self.dy


def _band_noise(rng: np.random.Generator, shape: tuple[int, int], spacing: float, scale: float) -> np.ndarray:
    """Gaussian noise low-passed to correlation length ``scale`` (m), unit standard deviation."""
    noise = rng.standard_normal(shape)
    ky = np.fft.fftfreq(shape[0], d=spacing)[:, None]
    kx = np.fft.rfftfreq(shape[1], d=spacing)[None, :]
    filt = np.exp(-0.5 * (2 * np.pi * scale) ** 2 * (kx ** 2 + ky ** 2) / 4.0)
    out = np.fft.irfft2(np.fft.rfft2(noise) * filt, s=shape)
    return (out - out.mean()) / (out.std() + 1e-12)


def synthetic(rng: np.random.Generator, extent: tuple[float, float, float, float], spacing: float,
              relief: float, base: float = 200.0) -> Dem:
    """A relief at several scales: a few broad Gaussian hills (kilometres), band-limited noise
    at 600 m, 200 m and 60 m. ``relief`` is the standard deviation of the heights (m)."""
    x_min, x_max, y_min, y_max = extent
    cols = int(np.ceil((x_max - x_min) / spacing)) + 1
    rows = int(np.ceil((y_max - y_min) / spacing)) + 1
    xs = x_min + spacing * np.arange(cols)
    ys = y_min + spacing * np.arange(rows)
    gx, gy = np.meshgrid(xs, ys)
    z = np.zeros((rows, cols))
    for _ in range(6):
        cx, cy = rng.uniform(x_min, x_max), rng.uniform(y_min, y_max)
        s = rng.uniform(300.0, 900.0)
        z += rng.uniform(-1.0, 1.0) * np.exp(-((gx - cx) ** 2 + (gy - cy) ** 2) / (2 * s * s))
    z = (z - z.mean()) / (z.std() + 1e-12)
    for scale, weight in ((600.0, 0.6), (200.0, 0.35), (60.0, 0.12)):
        z += weight * _band_noise(rng, (rows, cols), spacing, scale)
    z = base + relief * (z - z.mean()) / z.std()
    return Dem(z, float(x_min), float(y_min), float(spacing), float(spacing))


# --- the real DEM: a float32 GeoTIFF, placed by its ModelPixelScale and ModelTiepoint tags ---

TAG_PIXEL_SCALE = 33550
TAG_TIEPOINT = 33922
_TYPES = {3: ("H", 2), 4: ("I", 4), 11: ("f", 4), 12: ("d", 8), 16: ("Q", 8)}


def geotiff_tags(path: Path) -> dict[int, tuple]:
    """The first IFD's tags 33550 and 33922 (doubles), read with ``struct``; a corrupt or
    non-TIFF file raises a one-line error."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise WorkbenchError(f"cannot read {path}: {exc.strerror}") from None
    require(len(data) >= 8 and data[:2] in (b"II", b"MM"), f"not a TIFF file: {path}")
    end = "<" if data[:2] == b"II" else ">"
    magic = struct.unpack(end + "H", data[2:4])[0]
    require(magic == 42, f"not a classic TIFF (magic {magic}): {path}")
    ifd = struct.unpack(end + "I", data[4:8])[0]
    require(ifd + 2 <= len(data), f"corrupt TIFF (IFD offset past the end): {path}")
    count = struct.unpack(end + "H", data[ifd:ifd + 2])[0]
    require(ifd + 2 + 12 * count <= len(data), f"corrupt TIFF (IFD runs past the end): {path}")
    out: dict[int, tuple] = {}
    for i in range(count):
        entry = data[ifd + 2 + 12 * i: ifd + 14 + 12 * i]
        tag, typ, n = struct.unpack(end + "HHI", entry[:8])
        if tag not in (TAG_PIXEL_SCALE, TAG_TIEPOINT) or typ not in _TYPES:
            continue
        fmt, size = _TYPES[typ]
        nbytes = size * n
        offset = struct.unpack(end + "I", entry[8:12])[0] if nbytes > 4 else ifd + 2 + 12 * i + 8
        require(offset + nbytes <= len(data), f"corrupt TIFF (tag {tag} past the end): {path}")
        out[tag] = struct.unpack(end + fmt * n, data[offset:offset + nbytes])
    return out


def read_geotiff(path: Path) -> Dem:
    """The real DEM: pixels through OpenCV, placement from tags 33550/33922 (pixel-is-area:
    the tie point is the outer corner of the top-left pixel, so node (0, 0) is half a pixel in)."""
    import cv2

    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)  # it warns of every GeoTIFF tag; errors are ours
    path = Path(path)
    require(path.is_file(), f"DEM not found: {path}")
    tags = geotiff_tags(path)
    require(TAG_PIXEL_SCALE in tags and TAG_TIEPOINT in tags,
            f"{path.name} lacks the GeoTIFF tags 33550/33922 that place it")
    z = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    require(z is not None and z.ndim == 2, f"cannot read the DEM raster in {path} (corrupt TIFF?)")
    z = z.astype(float)
    z[z < -1e4] = np.nan
    require(bool(np.isfinite(z).any()), f"the DEM {path.name} has no valid heights")
    require(len(tags[TAG_PIXEL_SCALE]) >= 2 and len(tags[TAG_TIEPOINT]) >= 6,
            f"{path.name}: the GeoTIFF pixel scale (33550) needs 2 values and the tie point (33922) 6; got "
            f"{len(tags[TAG_PIXEL_SCALE])} and {len(tags[TAG_TIEPOINT])}")
    sx, sy = tags[TAG_PIXEL_SCALE][:2]
    i, j, _k, x, y, _z = tags[TAG_TIEPOINT][:6]
    require(all(np.isfinite([sx, sy, i, j, x, y])), f"{path.name}: a GeoTIFF placement value is not finite")
    require(sx > 0 and sy > 0, f"{path.name}: non-positive pixel scale")
    if np.isnan(z).any():
        z = np.where(np.isnan(z), np.nanmean(z), z)
    return Dem(z, float(x + (0.5 - i) * sx), float(y - (0.5 - j) * sy), float(sx), -float(sy))
