"""The spatial halftone model as files: seed 001's "terrain model in which coordinates,
heights, slopes and areas can be measured", built from image II, the DEM and an estimator's
refined orientation of image II (the inverse of (1) at every pixel).

A model folder holds

=====================  ===================================================================
``model.json``         the manifest: format, the model's id, the estimator, the coordinate
                       system, the mesh's origin, and every file's SHA-256
``model.npz``          what measuring needs: the DEM, the interior orientation, image II's
                       position and angles and their covariance ``(6, 6)``, the id
``orthophoto.tif``     image II on a north-up ground grid (GeoTIFF, placed, the DEM's CRS)
``ground.tif``         per image pixel, its ground X, Y, H (3 float bands, image geometry;
                       a grid of ground control points lets a GIS warp it)
``ground_sigma.tif``   their standard deviations, propagated from the orientation covariance
``mesh.obj``           the textured surface (``mesh.mtl``, ``texture.png``), vertices in
                       metres from the manifest's ``mesh_origin``
=====================  ===================================================================

:mod:`.measure` reads the folder back (:func:`load`) and measures in it.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.experiments.terrain import camera
from workbench.experiments.terrain.camera import Intrinsics
from workbench.experiments.terrain.dem import Dem
from workbench.experiments.terrain.products import geotiff, halftone

FORMAT = "workbench-halftone-model/1"
FILES = ("model.npz", "orthophoto.tif", "ground.tif", "ground_sigma.tif", "mesh.obj", "mesh.mtl", "texture.png")
PREFERRED = ("gtsam-ba", "recurrent-search-iterated", "recurrent-search-refined")
"""The estimator a run's model is built from by default: the first of these that gave image II's
orientation covariance. Bundle adjustment's comes first: its covariance is consistent (position
ANEES 1.56 in a 1.25-5.5 band, synthetic, seed 4, 5 runs) and does not rest on the search; the
search's filters' covariances (the MSE under its posterior) are consistent on the synthetic pairs
but not on two of the four real pair-modes."""


@dataclass
class Model:
    """The halftone model of image II under one orientation (world frame: x east, y north, z up)."""

    estimator: str
    dem: Dem
    k: Intrinsics
    position: np.ndarray          # (3,) image II's projection centre, m
    angles: np.ndarray            # (3,) its psi, theta, gamma, rad
    pose_cov: np.ndarray | None   # (6, 6) their covariance (position, angles), or None
    crs: str = ""                 # the coordinate system, in words
    model_id: str = ""

    @property
    def pose(self) -> np.ndarray:
        return np.concatenate([self.position, self.angles])

    def ground(self, u: np.ndarray, v: np.ndarray, pose: np.ndarray | None = None,
               what: str = "the measured pixels") -> np.ndarray:
        """Ground points ``(N, 3)`` of pixels ``(u, v)`` under ``pose`` (default the model's): (1) inverse."""
        p = self.pose if pose is None else pose
        return camera.ground_points(self.dem, self.k, p[:3], camera.rotation(p[3:]), np.asarray(u, float),
                                    np.asarray(v, float), what=what)

    def propagate(self, fn, pose: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """``fn(pose) -> values (m,)`` at the model's orientation, and their covariance by the
        unscented transform over the orientation covariance (:mod:`workbench.estimation.unscented`:
        13 sigma points, 2.6 sigma out); None where the model has no covariance. Not central
        differences: a terrain slope read from a real DEM changes across grid cells within the
        ground point's uncertainty, and its first-order sigma was 2-30 times too small on the
        NGI pair."""
        from workbench.estimation.unscented import moments, sigma_points

        p = self.pose if pose is None else np.asarray(pose, float)
        value = np.asarray(fn(p), float)
        if self.pose_cov is None or not np.isfinite(self.pose_cov).all():
            return value, None
        points, weights = sigma_points(p, self.pose_cov)
        return value, moments(np.array([np.asarray(fn(x), float).ravel() for x in points]), weights).cov

    def arrays(self) -> dict[str, np.ndarray]:
        d = self.dem
        return {"dem_heights": d.heights, "dem_grid": np.array([d.x0, d.y0, d.dx, d.dy]),
                "intrinsics": np.array([self.k.fx, self.k.fy, self.k.cx, self.k.cy, self.k.width, self.k.height]),
                "position": np.asarray(self.position, float), "angles": np.asarray(self.angles, float),
                "pose_cov": np.full((6, 6), np.nan) if self.pose_cov is None else np.asarray(self.pose_cov, float)}


def fingerprint(arrays: dict[str, np.ndarray]) -> str:
    """The model's id: SHA-256 over its arrays (names, shapes and bytes), 16 hex digits."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name], float)
        h.update(name.encode() + str(a.shape).encode() + a.tobytes())
    return h.hexdigest()[:16]


def from_run(first, name: str | None = None) -> Model:
    """Run 0's model from estimator ``name`` (default: the first of :data:`PREFERRED` with a pose
    covariance, else the first estimator with one, else the best without)."""
    est = first.estimates
    if name is None:
        with_cov = [n for n in est if est[n].pose_cov is not None and np.isfinite(est[n].pose_cov).all()]
        name = next((n for n in PREFERRED if n in with_cov), with_cov[0] if with_cov else
                    next((n for n in PREFERRED if n in est), next(iter(est))))
    require(name in est, f"no estimate {name!r} in this run to build the model from (have {', '.join(est)})")
    e, sc = est[name], first.scene
    m = Model(name, sc.dem, sc.k, np.asarray(e.position[1], float), np.asarray(e.angles[1], float),
              None if e.pose_cov is None else np.asarray(e.pose_cov, float), _crs_text(sc))
    m.model_id = fingerprint(m.arrays())
    return m


def _crs_text(sc) -> str:
    return "the DEM's (dem.tif)" if "dem_path" in sc.extras else f"a local frame of {sc.label}, metres"


def _crs_tags(sc) -> list[tuple]:
    path = sc.extras.get("dem_path")
    tags = geotiff.crs_of(Path(path)) if path is not None else []
    return tags or geotiff.local_crs(f"workbench local frame ({sc.label}), metres")


# --- writing ---------------------------------------------------------------------------------

def contents(model: Model, scene) -> dict[str, bytes]:
    """Every file of the model folder, as bytes (the manifest last: it holds their hashes)."""
    import cv2

    k, image = model.k, np.asarray(scene.images[1], float)
    tags = _crs_tags(scene)
    desc = json.dumps({"model": model.model_id, "estimator": model.estimator})
    g = model.ground(*k.pixel_grid(1), what="the image footprint under the model's orientation")
    g = g.reshape(k.height, k.width, 3)
    sigma = _pixel_sigmas(model, g)
    rows = np.linspace(0, k.height - 1, 5).round().astype(int)
    cols = np.linspace(0, k.width - 1, 5).round().astype(int)
    gcps = [(c, r, 0.0, *g[r, c]) for r in rows for c in cols]
    spacing = float((model.position[2] - model.dem.mean_height) / max(k.fx, k.fy))
    x_min, x_max = float(np.min(g[..., 0])), float(np.max(g[..., 0]))
    y_min, y_max = float(np.min(g[..., 1])), float(np.max(g[..., 1]))
    ortho = halftone.orthophoto(model.dem, k, model.position, model.angles, image, (x_min, x_max, y_min, y_max),
                                spacing)
    files: dict[str, bytes] = {}
    buf = io.BytesIO()
    np.savez_compressed(buf, model_id=np.array(model.model_id), estimator=np.array(model.estimator),
                        crs=np.array(model.crs), **model.arrays())
    files["model.npz"] = buf.getvalue()
    files["orthophoto.tif"] = geotiff.encode(np.where(np.isfinite(ortho), ortho, np.nan).astype(np.float32), tags,
                                             (x_min - spacing / 2, y_max + spacing / 2), spacing, desc)
    files["ground.tif"] = geotiff.encode(np.moveaxis(g, -1, 0).astype(np.float64), tags, description=desc,
                                         gcps=np.array(gcps))
    files["ground_sigma.tif"] = geotiff.encode(np.moveaxis(sigma, -1, 0).astype(np.float32), tags,
                                               description=desc, gcps=np.array(gcps))
    origin = np.round(g.reshape(-1, 3).mean(axis=0), 0)
    step = max(1, min(k.width, k.height) // 200)
    files["mesh.obj"] = _obj(halftone.mesh(g[::step, ::step]), origin, k, step, model.model_id).encode()
    files["mesh.mtl"] = b"newmtl halftone\nKa 1 1 1\nKd 1 1 1\nillum 1\nmap_Kd texture.png\n"
    ok, png = cv2.imencode(".png", np.clip(image * 255.0, 0, 255).round().astype(np.uint8))
    require(ok, "could not encode the model's texture as PNG")
    files["texture.png"] = png.tobytes()
    manifest = {"format": FORMAT, "model_id": model.model_id, "estimator": model.estimator, "crs": model.crs,
                "image_size": [k.width, k.height], "mesh_origin": origin.tolist(),
                "has_covariance": model.pose_cov is not None,
                "files": {n: hashlib.sha256(b).hexdigest() for n, b in files.items()}}
    files["model.json"] = (json.dumps(manifest, indent=1) + "\n").encode()
    return files


def _pixel_sigmas(model: Model, g: np.ndarray) -> np.ndarray:
    """Per pixel, the standard deviations of X, Y, H ``(rows, cols, 3)`` from the orientation
    covariance (NaN without one): the whole grid through :meth:`Model.propagate`'s sigma points
    at once, so a pixel's sigma here is the one ``measure`` gives it."""
    from workbench.estimation.unscented import sigma_points

    if model.pose_cov is None or not np.isfinite(model.pose_cov).all():
        return np.full(g.shape, np.nan)
    u, v = model.k.pixel_grid(1)
    points, weights = sigma_points(model.pose, model.pose_cov)
    grids = np.array([model.ground(u, v, p, what="the image footprint") for p in points])   # (13, N, 3)
    d = grids - np.einsum("s,snc->nc", weights, grids)
    var = np.einsum("s,snc->nc", weights, d * d)
    return np.sqrt(np.maximum(var, 0.0)).reshape(g.shape)


def _obj(mh: halftone.Mesh, origin: np.ndarray, k: Intrinsics, step: int, model_id: str) -> str:
    """Wavefront OBJ text: vertices from ``origin``, texture coordinates in image II (v up)."""
    rows = len(range(0, k.height, step))
    cols = len(range(0, k.width, step))
    vv, uu = np.mgrid[0:k.height:step, 0:k.width:step]
    tex = np.stack([(uu.ravel() + 0.5) / k.width, 1.0 - (vv.ravel() + 0.5) / k.height], axis=1)
    assert len(tex) == rows * cols == len(mh.vertices)
    v = mh.vertices - origin
    lines = [f"# workbench halftone model {model_id}; metres from origin {origin[0]:.3f} {origin[1]:.3f} "
             f"{origin[2]:.3f} (x east, y north, z up)", "mtllib mesh.mtl", "usemtl halftone"]
    lines += [f"v {a:.3f} {b:.3f} {c:.3f}" for a, b, c in v]
    lines += [f"vt {a:.6f} {b:.6f}" for a, b in tex]
    lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in mh.triangles + 1]
    return "\n".join(lines) + "\n"


def write(folder: Path, model: Model, scene, force: bool) -> list[Path]:
    """Write the model folder (each file checked first, then written atomically)."""
    from workbench.recording.stream import check_plain_output, write_bytes_atomic

    folder = Path(folder).expanduser()
    require(not folder.exists() or folder.is_dir(), f"--model {folder}: not a folder")
    paths = {n: check_plain_output(folder / n, force, "halftone model file") for n in (*FILES, "model.json")}
    files = contents(model, scene)
    folder.mkdir(parents=True, exist_ok=True)
    for name in (*FILES, "model.json"):
        write_bytes_atomic(paths[name], files[name], force)
    return list(paths.values())


# --- reading ---------------------------------------------------------------------------------

def load(path: str | Path) -> Model:
    """A model folder (or its ``model.json``) back, every file checked against the manifest; a
    missing, foreign or damaged file is a one-line error."""
    path = Path(path).expanduser()
    require(path.exists(), f"model not found: {path}")
    folder = path if path.is_dir() else path.parent
    manifest_path = folder / "model.json"
    require(manifest_path.is_file(), f"{folder} is not a halftone model folder (no model.json; a terrain run "
                                     "writes one with --model)")
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8-sig"))  # a BOM as logfiles.manifest
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise WorkbenchError(f"cannot read {manifest_path}: {exc}") from None
    require(isinstance(manifest, dict) and manifest.get("format") == FORMAT,
            f"{manifest_path} is not a {FORMAT} manifest")
    hashes = manifest.get("files")
    require(isinstance(hashes, dict) and "model.npz" in hashes, f"{manifest_path}: no file list")
    for name, digest in hashes.items():
        f = folder / name
        require(f.is_file(), f"the model's {name} is missing from {folder}")
        require(hashlib.sha256(f.read_bytes()).hexdigest() == digest,
                f"{f} is not this model's (another run's, or changed since it was written): its SHA-256 "
                "differs from model.json's")
    try:
        with np.load(folder / "model.npz") as z:
            a = {n: z[n] for n in z.files}
    except (OSError, ValueError) as exc:
        raise WorkbenchError(f"cannot read {folder / 'model.npz'}: {exc}") from None
    fx, fy, cx, cy, w, h = a["intrinsics"]
    x0, y0, dx, dy = a["dem_grid"]
    cov = a["pose_cov"]
    m = Model(str(a["estimator"]), Dem(a["dem_heights"], float(x0), float(y0), float(dx), float(dy)),
              Intrinsics(float(fx), float(fy), float(cx), float(cy), int(w), int(h)), a["position"], a["angles"],
              None if not np.isfinite(cov).all() else cov, str(a["crs"]), str(a["model_id"]))
    require(m.model_id == manifest.get("model_id") == fingerprint(m.arrays()),
            f"{folder / 'model.npz'} does not match its id: from another run")
    return m
