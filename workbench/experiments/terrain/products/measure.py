"""Measuring in the halftone model (seed 001: "coordinates, heights, slopes and areas can be
measured"): pixels of image II to ground points by the inverse of (1) on the DEM, and from
them distances, height differences, slopes and areas, each with its standard deviation
propagated (to first order, ``J C J'``) from the refined orientation's covariance ``C``.

Readings taken: the sigmas are the orientation's share only: the DEM is taken as exact and a
pixel as pointed exactly (the spec gives neither's error); a measurement's elements move
together (one orientation error moves every point), so a distance's sigma is not the two
points' sigmas combined as if independent. Areas and distances are horizontal (map) ones, as
a GIS measures them, and the slope distance beside them.

Pixels are image II's ``(u, v)``: column and row, pixel centres at whole numbers, ``0 <= u <=
width - 1``, ``0 <= v <= height - 1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.terrain.products.model import Model


@dataclass
class Quantity:
    """One measured value with its standard deviation (None without a covariance)."""

    name: str
    value: float
    sigma: float | None
    unit: str

    def text(self) -> str:
        """``name value +- sigma unit``, to the sigma's second significant digit."""
        good = self.sigma is not None and self.sigma > 0 and math.isfinite(self.sigma)
        digits = min(6, max(0, 1 - math.floor(math.log10(self.sigma)))) if good else 3
        s = f"{self.value:.{digits}f}"
        return f"{self.name} {s} +- {self.sigma:.{digits}f} {self.unit}" if self.sigma is not None else \
            f"{self.name} {s} {self.unit} (no covariance)"


@dataclass
class Measurement:
    kind: str                       # point | line | polygon
    pixels: list[tuple[float, float]]
    ground: np.ndarray              # (N, 3) the vertices' ground points
    quantities: list[Quantity]

    def to_json(self) -> dict:
        return {"kind": self.kind, "pixels": [list(p) for p in self.pixels], "ground": self.ground.tolist(),
                "quantities": {q.name: {"value": q.value, "sigma": q.sigma, "unit": q.unit} for q in self.quantities}}

    def text(self) -> str:
        where = " -> ".join(f"({u:g}, {v:g})" for u, v in self.pixels)
        return f"{self.kind} {where}: " + "; ".join(q.text() for q in self.quantities)


# --- parsing what a user types -----------------------------------------------------------------

def parse_pixels(text: str, what: str) -> list[tuple[float, float]]:
    """``"u,v"`` or ``"u1,v1:u2,v2:..."`` -> pixels; a one-line error naming ``what`` otherwise."""
    out = []
    for part in str(text).split(":"):
        pieces = part.split(",")
        try:
            require(len(pieces) == 2, "")
            u, v = float(pieces[0]), float(pieces[1])
        except (ValueError, WorkbenchError):
            raise WorkbenchError(f"{what} {text!r}: each vertex is u,v (two numbers, vertices joined by ':')"
                                 ) from None
        require(math.isfinite(u) and math.isfinite(v), f"{what} {text!r}: pixel coordinates must be finite")
        out.append((u, v))
    return out


def check_inside(model: Model, pixels: list[tuple[float, float]], what: str) -> None:
    k = model.k
    for u, v in pixels:
        require(0.0 <= u <= k.width - 1 and 0.0 <= v <= k.height - 1,
                f"{what}: pixel ({u:g}, {v:g}) is outside image II ({k.width} x {k.height}: u in 0..{k.width - 1}, "
                f"v in 0..{k.height - 1})")


def _segments_cross(p1, p2, p3, p4) -> bool:
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    d1, d2 = orient(p3, p4, p1), orient(p3, p4, p2)
    d3, d4 = orient(p1, p2, p3), orient(p1, p2, p4)
    return (d1 * d2 < 0) and (d3 * d4 < 0)


def check_polygon(pixels: list[tuple[float, float]], what: str = "--polygon") -> None:
    """At least three distinct vertices, a non-zero area, no edge crossing another."""
    require(len(pixels) >= 3, f"{what}: a polygon needs at least 3 vertices, got {len(pixels)}")
    require(len(set(pixels)) == len(pixels), f"{what}: a vertex is repeated")
    n = len(pixels)
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            require(not _segments_cross(pixels[i], pixels[(i + 1) % n], pixels[j], pixels[(j + 1) % n]),
                    f"{what}: the polygon crosses itself (edges {i + 1} and {j + 1})")
    p = np.array(pixels)
    area = 0.5 * abs(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(p[:, 1], np.roll(p[:, 0], -1)))
    require(area >= 1e-6 * max(1.0, float(np.ptp(p, axis=0).max()) ** 2),
            f"{what}: degenerate polygon (its vertices are on one line: no area)")


# --- the measurements ----------------------------------------------------------------------------

def _quantities(model: Model, pixels: list[tuple[float, float]], fn, names: list[tuple[str, str]]) -> tuple:
    u, v = np.array(pixels, float).T
    values, cov = model.propagate(lambda pose: fn(model.ground(u, v, pose)))
    sig = [None] * len(names) if cov is None else np.sqrt(np.maximum(np.diag(cov), 0.0))
    ground = model.ground(u, v)
    return ground, [Quantity(n, float(x), None if s is None else float(s), unit)
                    for (n, unit), x, s in zip(names, values, sig, strict=True)]


def point(model: Model, pixel: tuple[float, float]) -> Measurement:
    """A pixel's ground X, Y, H and the terrain's slope there (deg): the DEM's central differences
    over one grid spacing either side, a continuous function of the point (the bilinear surface's
    own gradient jumps at every cell edge, which no first-order sigma can follow)."""
    check_inside(model, [pixel], "--point")
    dx, dy = abs(model.dem.dx), abs(model.dem.dy)

    def fn(g: np.ndarray) -> np.ndarray:
        x, y = g[0, 0], g[0, 1]
        h, _, _ = model.dem.sample(np.array([x + dx, x - dx, x, x]), np.array([y, y, y + dy, y - dy]), strict=False)
        slope = math.atan(math.hypot((h[0] - h[1]) / (2 * dx), (h[2] - h[3]) / (2 * dy)))
        return np.array([x, y, g[0, 2], math.degrees(slope)])

    ground, q = _quantities(model, [pixel], fn, [("X", "m"), ("Y", "m"), ("H", "m"), ("terrain slope", "deg")])
    return Measurement("point", [pixel], ground, q)


def line(model: Model, a: tuple[float, float], b: tuple[float, float]) -> Measurement:
    """Between two pixels' ground points: the horizontal distance, the slope distance, the height
    difference (b - a) and the slope angle of the line."""
    check_inside(model, [a, b], "--line")
    require(a != b, "--line: its two ends are the same pixel")

    def fn(g: np.ndarray) -> np.ndarray:
        d = g[1] - g[0]
        horizontal = math.hypot(d[0], d[1])
        return np.array([horizontal, float(np.linalg.norm(d)), d[2], math.degrees(math.atan2(d[2], horizontal))])

    ground, q = _quantities(model, [a, b], fn, [("distance", "m"), ("slope distance", "m"),
                                                ("height difference", "m"), ("slope", "deg")])
    return Measurement("line", [a, b], ground, q)


def polygon(model: Model, pixels: list[tuple[float, float]]) -> Measurement:
    """A polygon's horizontal area (the shoelace formula on the ground X, Y), perimeter and mean
    height of its vertices."""
    check_polygon(pixels)
    check_inside(model, pixels, "--polygon")

    def fn(g: np.ndarray) -> np.ndarray:
        x, y = g[:, 0] - g[0, 0], g[:, 1] - g[0, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        edges = np.roll(g[:, :2], -1, axis=0) - g[:, :2]
        return np.array([area, float(np.hypot(edges[:, 0], edges[:, 1]).sum()), float(g[:, 2].mean())])

    ground, q = _quantities(model, pixels, fn, [("area", "m^2"), ("perimeter", "m"), ("mean height", "m")])
    return Measurement("polygon", pixels, ground, q)


def measure(model: Model, points: list[str] = (), lines: list[str] = (), polygons: list[str] = ()
            ) -> list[Measurement]:
    """Every measurement a user typed (``"u,v"``, ``"u1,v1:u2,v2"``, ``"u1,v1:u2,v2:u3,v3..."``)."""
    out = []
    for text in points:
        px = parse_pixels(text, "--point")
        require(len(px) == 1, f"--point {text!r}: one pixel u,v")
        out.append(point(model, px[0]))
    for text in lines:
        px = parse_pixels(text, "--line")
        require(len(px) == 2, f"--line {text!r}: two pixels u1,v1:u2,v2")
        out.append(line(model, *px))
    for text in polygons:
        out.append(polygon(model, parse_pixels(text, "--polygon")))
    return out


def examples(model: Model) -> list[Measurement]:
    """A point at image II's centre, a line across it and a quadrilateral inside it: what the
    recording shows of a run's model."""
    w, h = model.k.width - 1, model.k.height - 1

    def px(a: float, b: float) -> tuple[float, float]:
        return (round(a * w, 1), round(b * h, 1))

    return [point(model, px(0.25, 0.3)), line(model, px(0.1, 0.6), px(0.6, 0.9)),
            polygon(model, [px(0.55, 0.15), px(0.85, 0.2), px(0.8, 0.5), px(0.6, 0.45)])]


def edge_pixels(pixels: list[tuple[float, float]], closed: bool, per_edge: int = 40) -> np.ndarray:
    """Pixels along a line's or a polygon's edges, ``per_edge`` a side (to draw them on the
    terrain rather than as chords through it)."""
    p = np.array(pixels, float)
    ends = np.vstack([p, p[:1]]) if closed else p
    t = np.linspace(0.0, 1.0, per_edge, endpoint=False)[:, None]
    out = [a + t * (b - a) for a, b in zip(ends[:-1], ends[1:], strict=True)]
    return np.vstack([*out, ends[-1:]])
