"""GeoTIFFs a GIS opens: rasters with their placement (ModelPixelScale 33550, ModelTiepoint
33922, pixel-is-area) and their coordinate system (the GeoKey directory 34735-34737), written
with ``tifffile``; the coordinate system is copied from the DEM the model stands on (the NGI
DEM's transverse Mercator) or, for a synthetic scene, a user-defined metric frame.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import tifffile

from workbench.errors import require

PIXEL_SCALE, TIEPOINT = 33550, 33922
GEOKEYS, GEO_DOUBLES, GEO_ASCII = 34735, 34736, 34737
_TIFF_TYPE = {GEOKEYS: 3, GEO_DOUBLES: 12, GEO_ASCII: 2}   # SHORT, DOUBLE, ASCII


def crs_of(path: Path) -> list[tuple]:
    """The GeoKey tags of an existing GeoTIFF (its coordinate system), as ``tifffile`` extratags;
    empty where it has none."""
    with tifffile.TiffFile(path) as tif:
        tags = tif.pages[0].tags
        out = []
        for code in (GEOKEYS, GEO_DOUBLES, GEO_ASCII):
            if code in tags:
                value = tags[code].value
                count = len(value) + 1 if isinstance(value, str) else len(value)
                out.append((code, _TIFF_TYPE[code], count, value, True))
        return out


def local_crs(citation: str) -> list[tuple]:
    """GeoKeys of a user-defined projected frame in metres (a synthetic scene's x east, y north)."""
    text = citation.replace("|", "/") + "|"
    keys = [1, 1, 0, 5,
            1024, 0, 1, 1,                 # GTModelType: projected
            1025, 0, 1, 1,                 # GTRasterType: pixel is area
            1026, GEO_ASCII, len(text), 0,  # GTCitation
            3072, 0, 1, 32767,             # ProjectedCSType: user-defined
            3076, 0, 1, 9001]              # ProjLinearUnits: metre
    return [(GEOKEYS, 3, len(keys), keys, True), (GEO_ASCII, 2, len(text) + 1, text, True)]


def encode(bands: np.ndarray, crs: list[tuple], corner: tuple[float, float] | None = None,
           spacing: float | None = None, description: str = "", gcps: np.ndarray | None = None) -> bytes:
    """A GeoTIFF's bytes: ``bands`` ``(H, W)`` or ``(B, H, W)`` (planar), placed with the outer
    corner of its top-left pixel at ``corner`` (x, y) and square ``spacing`` (north up), or, in
    image geometry, by ground control points ``gcps (N, 6)``: ``(column, row, 0, X, Y, H)`` each
    (several tie points and no pixel scale: GDAL reads them as GCPs, a GIS warps with them)."""
    bands = np.asarray(bands)
    require(bands.ndim in (2, 3), f"a GeoTIFF needs 2 or 3 dimensions, got {bands.shape}")
    extratags = list(crs)
    if corner is not None:
        require(spacing is not None and spacing > 0, "a placed GeoTIFF needs a positive spacing")
        extratags += [(PIXEL_SCALE, 12, 3, (float(spacing), float(spacing), 0.0), True),
                      (TIEPOINT, 12, 6, (0.0, 0.0, 0.0, float(corner[0]), float(corner[1]), 0.0), True)]
    elif gcps is not None:
        g = np.asarray(gcps, float).reshape(-1)
        extratags.append((TIEPOINT, 12, len(g), tuple(g.tolist()), True))
    buf = io.BytesIO()
    tifffile.imwrite(buf, bands, photometric="minisblack", planarconfig="separate" if bands.ndim == 3 else None,
                     description=description or None, extratags=extratags, metadata=None)
    return buf.getvalue()
