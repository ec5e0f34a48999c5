"""The NGI folder's interior orientation, ``ngi_int_param.yaml``, read strictly (orthority's
format: one camera, ``type``, ``im_size [width, height]`` px, ``focal_len`` and ``sensor_size
[width, height]`` in the same units, ``cx``, ``cy`` principal point offsets in normalised image
coordinates, i.e. pixels over ``max(width, height)``, from the image centre).

Only the pinhole model is read; distortion coefficients other than zero, a missing or
non-positive size, focal length or sensor, a principal point off the frame, or a file that is
not such YAML are one-line :class:`~workbench.errors.WorkbenchError` naming the file. A folder
without the file (older copies of the data) gets the Intergraph DMC's values the data README
gives, with a :class:`~workbench.errors.DataWarning` saying so.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

from workbench.errors import DataWarning, WorkbenchError, require
from workbench.experiments.terrain.camera import Intrinsics

FILE = "ngi_int_param.yaml"
DISTORTION = ("k1", "k2", "k3", "k4", "p1", "p2")


@dataclass(frozen=True)
class Interior:
    """A frame camera: ``size`` (width, height) px, the focal length and the sensor's size
    (width, height) in one unit, the principal point's offset from the centre in normalised
    image coordinates."""

    name: str
    size: tuple[int, int]
    focal: tuple[float, float]
    sensor: tuple[float, float]
    offset: tuple[float, float] = (0.0, 0.0)

    def intrinsics(self, width: int, height: int) -> Intrinsics:
        """The pinhole in pixels of a frame resampled to ``width x height`` (the same field of
        view): ``f_x = f w / sensor_w``, ``f_y = f h / sensor_h``, the principal point at the
        centre plus ``offset * max(w, h)``."""
        fx = self.focal[0] * width / self.sensor[0]
        fy = self.focal[1] * height / self.sensor[1]
        scale = max(width, height)
        return Intrinsics(fx, fy, (width - 1) / 2.0 + self.offset[0] * scale,
                          (height - 1) / 2.0 + self.offset[1] * scale, width, height)


DMC = Interior("Intergraph DMC (the data README's values)", (640, 1152), (120.0, 120.0), (92.16, 165.888))
"""The camera of the NGI frames, as the data README states it."""


def _pair(path: Path, key: str, value, positive: bool = True, whole: bool = False) -> tuple:
    items = value if isinstance(value, (list, tuple)) else [value]
    if key == "focal_len" and len(items) == 1:
        items = [items[0], items[0]]
    require(len(items) == 2, f"{path.name}: {key} must be two numbers [width, height], got {value!r}")
    out = []
    for x in items:
        require(isinstance(x, (int, float)) and not isinstance(x, bool),
                f"{path.name}: {key} must be numbers, got {value!r}")
        require(math.isfinite(x) and (x > 0 if positive else True) and abs(x) <= 1e6,
                f"{path.name}: {key} must be {'positive ' if positive else ''}finite numbers, got {value!r}")
        require(not whole or float(x).is_integer(), f"{path.name}: {key} must be whole pixels, got {value!r}")
        out.append(int(x) if whole else float(x))
    return tuple(out)


def read(path: Path) -> Interior:
    """The one camera in ``path`` (orthority's interior parameter YAML)."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise WorkbenchError(f"cannot read {path.name}: {type(exc).__name__}") from None
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        line = f" line {where.line + 1}" if where is not None else ""
        raise WorkbenchError(f"{path.name}{line}: not valid YAML") from None
    require(isinstance(doc, dict) and len(doc) == 1 and isinstance(next(iter(doc.values())), dict),
            f"{path.name}: expected one camera (a name, then its parameters)")
    name, cam = next(iter(doc.items()))
    kind = str(cam.get("type", "")).lower()
    require(kind == "pinhole", f"{path.name}: camera type {cam.get('type')!r} is not supported (only pinhole)")
    for key in ("im_size", "focal_len", "sensor_size"):
        require(key in cam, f"{path.name}: {key} is missing")
    size = _pair(path, "im_size", cam["im_size"], whole=True)
    require(all(8 <= s <= 100_000 for s in size), f"{path.name}: im_size {list(size)} is not a frame's size")
    focal = _pair(path, "focal_len", cam["focal_len"])
    sensor = _pair(path, "sensor_size", cam["sensor_size"])
    offset = _pair(path, "cx, cy", [cam.get("cx", 0.0), cam.get("cy", 0.0)], positive=False)
    require(all(abs(o) < 0.5 for o in offset),
            f"{path.name}: the principal point offset {list(offset)} is off the frame (normalised: |cx|, |cy| < 0.5)")
    for key in DISTORTION:
        value = cam.get(key, 0.0)
        require(isinstance(value, (int, float)) and value == 0,
                f"{path.name}: distortion {key} = {value!r} is not supported (a pinhole without distortion)")
    unknown = sorted(set(cam) - {"type", "im_size", "focal_len", "sensor_size", "cx", "cy", *DISTORTION})
    require(not unknown, f"{path.name}: unknown parameter(s) {', '.join(map(str, unknown))}")
    return Interior(str(name), size, focal, sensor, offset)


def interior(folder: Path) -> Interior:
    """The folder's camera; the DMC's values with a warning where the file is missing."""
    path = folder / FILE
    if not path.exists():
        warnings.warn(DataWarning(f"{FILE} not found in {folder}: using the Intergraph DMC's interior orientation "
                                  "from the data README (120 mm, 92.16 x 165.888 mm, 640 x 1152 px)"), stacklevel=2)
        return DMC
    return read(path)
