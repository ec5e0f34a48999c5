"""The terrain recording read back with ``rerun.chunk.RrdReader`` and checked in numbers: one
world frame and scale, valid textured meshes, images the right way up, distinct frusta, the
hypothesis cloud over the search timelines, the winner, the error maps and their legends, the
blueprint's views pointing at logged data."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

from workbench.experiments.terrain import metrics as terrain_metrics
from workbench.experiments.terrain import navigation, record, run
from workbench.experiments.terrain.config import TerrainConfig
from workbench.experiments.terrain.experiment import EXPERIMENT
from workbench.experiments.terrain.products import halftone
from workbench.paths import data_root
from workbench.recording import stream

NGI = data_root() / "ngi"

LEVELS = (4, 2)             # grid levels, linear and angular
CORE = ("navigation", "recurrent-search", "recurrent-search-refined", "gtsam-ba")   # at least these


def _flat(a: pa.Array) -> np.ndarray:
    """Every leaf value of a (nested) list array, as numpy."""
    while pa.types.is_list(a.type) or pa.types.is_large_list(a.type) or pa.types.is_fixed_size_list(a.type):
        a = a.flatten()
    return a.to_numpy(zero_copy_only=False)


def _rgba(packed: np.ndarray) -> np.ndarray:
    """Rerun's 0xRRGGBBAA colours as (N, 4) uint8."""
    p = np.asarray(packed, np.uint64)
    return np.stack([(p >> s) & 0xFF for s in (24, 16, 8, 0)], axis=-1).astype(np.uint8)


class Recording:
    """Every chunk of an .rrd by entity: static values and temporal rows."""

    def __init__(self, path: Path):
        self.static: dict[str, dict[str, pa.Array]] = defaultdict(dict)
        self.temporal: dict[str, list[pa.RecordBatch]] = defaultdict(list)
        reader = RrdReader(str(path))
        for chunk in reader.store().stream():
            batch = chunk.to_record_batch()
            entity = str(chunk.entity_path)
            if chunk.is_static:
                for name in batch.schema.names:
                    if ":" in name:
                        self.static[entity][name] = batch.column(name)[0].values
            else:
                self.temporal[entity].append(batch)
        self.blueprint: dict[str, dict[str, list]] = defaultdict(dict)
        for chunk in reader.store(store=reader.blueprints()[0]).stream():
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" in name:
                    self.blueprint[str(chunk.entity_path)][name] = batch.column(name).to_pylist()[0]

    def values(self, entity: str, column: str, width: int | None = None) -> np.ndarray:
        v = _flat(self.static[entity][column])
        return v.reshape(-1, width) if width else v

    def rows(self, entity: str, column: str, width: int) -> tuple[dict[str, np.ndarray], list[np.ndarray]]:
        """Temporal rows of one component: the timelines' values and each row's (n, width) array."""
        times: dict[str, list] = defaultdict(list)
        out: list[np.ndarray] = []
        for batch in self.temporal[entity]:
            col = batch.column(column)
            for name in ("hypothesis", "search"):
                times[name].extend(batch.column(name).to_pylist())
            for i in range(batch.num_rows):
                out.append(_flat(col[i].values).reshape(-1, width))
        order = np.argsort(times["hypothesis"], kind="stable")
        return {k: np.asarray(v)[order] for k, v in times.items()}, [out[i] for i in order]

    def image(self, entity: str, prefix: str = "Image:") -> np.ndarray:
        """An image (``Image:``, ``DepthImage:``, a mesh's ``Mesh3D:albedo_texture_``) as (H, W) or
        (H, W, C) in its own datatype."""
        fmt = self.static[entity][f"{prefix}format"].to_pylist()[0]
        dtype = {6: np.uint8, 34: np.float32}[fmt["channel_datatype"]]
        data = np.frombuffer(_flat(self.static[entity][f"{prefix}buffer"]).astype(np.uint8).tobytes(), dtype)
        data = data.reshape(fmt["height"], fmt["width"], -1)
        return data[..., 0] if data.shape[2] == 1 else data


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> tuple[run.RunResult, Recording, np.ndarray]:
    """One small run (64 position x 8 attitude cells, several chunks) recorded like the CLI does."""
    cfg = TerrainConfig(size="100x100", levels_linear=LEVELS[0], levels_angular=LEVELS[1], seed=4).validate()
    first = EXPERIMENT.run_once(cfg, 0, EXPERIMENT.select(), record=True)
    path = tmp_path_factory.mktemp("terrain_record") / "t.rrd"
    with stream.recording(path, "terrain", cfg.to_json(), cfg.seed, record.blueprint(list(first.estimates))) as rec:
        EXPERIMENT.record(rec, first, [EXPERIMENT.evaluate(first, cfg, 0)], "| a | b |\n|---|---|\n| 1 | 2 |")
    return first, Recording(path), record.local_origin(first.scene)


def test_one_world_frame_and_scale(recorded):
    first, r, origin = recorded
    sc = first.scene
    assert not origin.any()                                  # synthetic: no local origin needed
    dem = r.values("/world/dem", "Mesh3D:vertex_positions", 3)
    lo, hi = np.nanmin(sc.dem.heights), np.nanmax(sc.dem.heights)
    assert lo - 1 <= dem[:, 2].min() and dem[:, 2].max() <= hi + 1
    h, _, _ = sc.dem.sample(dem[:, 0], dem[:, 1])
    assert np.abs(dem[:, 2] - h).max() < 0.5                 # the mesh is the DEM, in metres
    for i, ex in enumerate(("I", "II")):
        t = r.values(f"/world/cameras/truth/{ex}", "Transform3D:translation")
        assert np.allclose(t, sc.position[i], atol=0.01)
        assert 1300 < t[2] - sc.dem.mean_height < 1700        # ~1500 m above the terrain
    # the footprints lie inside the DEM mesh's extent
    for i in range(2):
        g = halftone.ground(sc.dem, sc.k, sc.position[i], sc.angles[i], step=10).reshape(-1, 3)
        assert dem[:, 0].min() <= g[:, 0].min() and g[:, 0].max() <= dem[:, 0].max()
        assert dem[:, 1].min() <= g[:, 1].min() and g[:, 1].max() <= dem[:, 1].max()
    # tie points on the terrain, hypotheses around image II's camera, halftone models on the DEM
    tp = r.values("/world/ba/tie_points", "Points3D:positions", 3)
    h, _, _ = sc.dem.sample(tp[:, 0], tp[:, 1])
    assert len(tp) >= 20 and np.median(np.abs(tp[:, 2] - h)) < 10.0
    _, pts = r.rows("/world/search/hypotheses", "Points3D:positions", 3)
    cloud = np.concatenate(pts)
    assert np.abs(cloud - first.measured.position[1]).max() < 2 * 100.0 + 1
    assert set(CORE) <= set(first.estimates)
    for name in first.estimates:
        v = r.values(f"/world/halftone/{name}", "Mesh3D:vertex_positions", 3)
        h, _, _ = sc.dem.sample(v[:, 0], v[:, 1])
        assert np.abs(v[:, 2] - h).max() < 0.5, name


def test_meshes_are_valid_and_textured(recorded):
    first, r, _ = recorded
    for entity in ["/world/dem", *[f"/world/halftone/{n}" for n in first.estimates]]:
        v = r.values(entity, "Mesh3D:vertex_positions", 3)
        tri = r.values(entity, "Mesh3D:triangle_indices", 3)
        uv = r.values(entity, "Mesh3D:vertex_texcoords", 2)
        assert tri.min() >= 0 and tri.max() < len(v) and len(uv) == len(v), entity
        area = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]), axis=1)
        assert area.min() > 0, entity
        # counter-clockwise seen from above: the faces point up
        up = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])[:, 2]
        assert (up > 0).mean() > 0.95 or (up < 0).mean() > 0.95, entity
        assert uv.min() >= 0 and uv.max() <= 1, entity
        tex = r.image(entity, "Mesh3D:albedo_texture_")
        assert tex.ndim == 3 and tex.shape[2] == 3 and tex.std() > 10, entity
    # the DEM texture: grey image pixels over most of it, the warm hillshade elsewhere
    tex = r.image("/world/dem", "Mesh3D:albedo_texture_").astype(int)
    grey = (tex[..., 0] == tex[..., 1]) & (tex[..., 1] == tex[..., 2])
    assert 0.3 < grey.mean() < 0.99
    # the halftone texture is image II itself, and vertex (row 0, col 0) reads its top-left pixel
    k = first.scene.k
    tex = r.image("/world/halftone/recurrent-search-refined", "Mesh3D:albedo_texture_")
    assert tex.shape[:2] == (k.height, k.width)
    assert np.array_equal(tex[..., 0], (255 * np.clip(first.scene.images[1], 0, 1)).astype(np.uint8))
    uv = r.values("/world/halftone/recurrent-search-refined", "Mesh3D:vertex_texcoords", 2)
    assert np.allclose(uv[0], [0.5 / k.width, 0.5 / k.height])


def test_images_frusta_and_tie_points(recorded):
    first, r, _ = recorded
    k = first.scene.k
    for i, ex in enumerate(("I", "II")):
        img = r.image(f"/world/cameras/truth/{ex}")
        assert img.shape == (k.height, k.width)               # rows = image rows: not flipped or transposed
        assert np.array_equal(img, (255 * np.clip(first.scene.images[i], 0, 1)).astype(np.uint8))
        pin = r.values(f"/world/cameras/truth/{ex}", "Pinhole:image_from_camera").reshape(3, 3).T
        assert np.allclose(pin[:2, 2], [k.cx + 0.5, k.cy + 0.5]) and np.isclose(pin[0, 0], k.fx)
        uv = r.values(f"/world/cameras/truth/{ex}/tie_points", "Points2D:positions", 2)
        assert uv.min() >= 0 and uv[:, 0].max() <= k.width and uv[:, 1].max() <= k.height
    colours = {who: tuple(_rgba(r.values(f"/world/cameras/{who}/II", "Pinhole:color"))[0][:3])
               for who in ("truth", *first.estimates)}
    assert len(set(colours.values())) == len(colours)         # every frustum distinguishable
    for who in first.estimates:
        assert np.allclose(r.values(f"/world/cameras/{who}/II", "Transform3D:translation"),
                           first.estimates[who].position[1], atol=0.01)
        assert r.values(f"/world/cameras/{who}/II", "TransformAxes3D:axis_length")[0] == 0.0


def test_hypothesis_cloud_over_the_search(recorded):
    first, r, origin = recorded
    s = first.search
    n = len(s.functional)
    times, pts = r.rows("/world/search/hypotheses", "Points3D:positions", 3)
    _, cols = r.rows("/world/search/hypotheses", "Points3D:colors", 1)
    chunks = -(-n // s.chunk)
    assert chunks >= 2 and len(pts) == chunks                 # one row per evaluated chunk
    assert np.array_equal(times["search"], np.arange(chunks))
    assert np.all(np.diff(times["hypothesis"]) > 0) and times["hypothesis"][-1] == n - 1
    cloud, colours = np.concatenate(pts), _rgba(np.concatenate(cols)[:, 0])
    assert len(cloud) == n == LEVELS[0] ** 3 * LEVELS[1] ** 3
    g = record.glyph(first, origin)
    assert np.allclose(cloud, g(record.pose_errors(first, s.centres)), atol=0.01)
    # attitude drawn as a small cube (35 % of a 50 m position cell) around each position cell
    assert np.allclose(g.cell, 2 * 100.0 / LEVELS[0], rtol=1e-6) and g.scale > 0
    lin = navigation.error_map(first.scene_mode, first.scene.interval)[1, :3] @ s.centres.T
    offset = np.abs(cloud - (first.measured.position[1] - lin.T))
    assert 0.1 * g.cell.min() < offset.max() <= 0.175 * g.cell.min() + 1e-3   # float32 in the recording
    # coloured by the functional's rank: the lowest bright yellow, brightness falling with rank
    order = np.argsort(s.functional)
    assert tuple(colours[order[0], :3]) == (253, 231, 37)
    bright = colours[order, :3].astype(float).sum(axis=1)
    assert np.all(np.diff(bright) <= 2) and bright[0] > 2 * bright[-1]   # up to rounding
    assert len(np.unique(colours[:, :3], axis=0)) > n // 4
    radius = r.values("/world/search/hypotheses", "Points3D:radii")[0]
    assert 0.01 * g.cell.min() < radius < 0.1 * g.cell.min()


def test_winner_and_functional(recorded):
    first, r, origin = recorded
    s = first.search
    n = len(s.functional)
    g = record.glyph(first, origin)
    times, pos = r.rows("/world/search/winner", "Points3D:positions", 3)
    _, centres = r.rows("/world/search/winner_cell", "Boxes3D:centers", 3)
    assert len(pos) == len(centres) >= 1 and np.all(np.diff(times["hypothesis"]) > 0)
    pose = record.pose_errors(first, s.centres)
    assert np.allclose(pos[-1][0], g(pose[s.winner]), atol=0.01)   # the last row is the winner
    half = r.values("/world/search/winner_cell", "Boxes3D:half_sizes", 3)[0]
    assert np.allclose(2 * half, g.cell) and np.all(np.abs(pos[-1][0] - centres[-1][0]) < half)
    labels = r.values("/world/search/markers", "Points3D:labels")
    assert list(labels) == ["truth", *[n for n in first.estimates if n != "recurrent-search"]]
    markers = r.values("/world/search/markers", "Points3D:positions", 3)
    assert np.allclose(markers[1], first.measured.position[1])         # zero error: the measured position
    cfg = TerrainConfig(size="100x100", levels_linear=LEVELS[0], levels_angular=LEVELS[1], seed=4).validate()
    summary = EXPERIMENT.evaluate(first, cfg, 0)
    if summary.winner_in_true_position_cell:
        assert np.all(np.abs(markers[0] - centres[-1][0]) <= half + 1e-6)
    f = np.asarray(s.functional)
    t, vals = r.rows("/functional", "Scalars:scalars", 1)
    assert len(vals) == n and np.array_equal(t["hypothesis"], np.arange(n))
    assert np.allclose(np.concatenate(vals)[:, 0], f - f.min())
    _, low = r.rows("/functional/lowest", "Scalars:scalars", 1)
    low = np.concatenate(low)[:, 0]
    assert np.all(np.diff(low) <= 0) and low[-1] == 0.0
    t, w = r.rows("/functional/winner", "Scalars:scalars", 1)
    assert t["hypothesis"].tolist() == [s.winner] and w[0][0, 0] == 0.0
    assert s.winner == record.lowest_so_far(f)[-1]


def test_error_maps_with_legends(recorded):
    first, r, _ = recorded
    for name in first.estimates:
        err = r.image(f"/errors/{name}", "DepthImage:")
        assert np.allclose(err, terrain_metrics.ground_errors(first)[name], atol=1e-3)  # m, image II's pixels
        assert r.values(f"/errors/{name}", "DepthImage:meter")[0] == 1.0
        lo, top = r.values(f"/errors/{name}", "DepthImage:depth_range")
        widest = max(b / a for a, b in zip(record.NICE[:-1], record.NICE[1:], strict=True))  # 3 -> 4, 6 -> 8
        assert lo == 0.0 and err.max() <= top <= widest * err.max()        # each map on its own scale
        bar = r.image(f"/errors/{name}/legend", "DepthImage:")
        assert bar.shape[1] == err.shape[1] and np.all(np.diff(bar[0]) > 0) and bar.max() <= top
        assert r.values(f"/errors/{name}/legend", "Transform3D:translation")[1] > err.shape[0]  # below the map
        ticks = r.values(f"/errors/{name}/legend/ticks", "Points2D:labels")
        assert len(ticks) == 3 and all(t.endswith(" m") for t in ticks)
        assert np.allclose([float(t[:-2]) for t in ticks], np.array([0.2, 0.5, 0.8]) * top, rtol=1e-2)
        title = r.values(f"/errors/{name}/legend/title", "Points2D:labels")[0]
        below = r.values(f"/errors/{name}/legend/title", "Points2D:positions", 2)
        assert len(below) == 2 and below[1, 1] > below[0, 1]      # a spacer under the title keeps it in view
        assert name in title and f"{halftone.rmse(terrain_metrics.ground_errors(first)[name]):.2f} m" in title
    nav = r.values("/errors/navigation", "DepthImage:depth_range")[1]
    refined = r.values("/errors/recurrent-search-refined", "DepthImage:depth_range")[1]
    assert refined < 0.5 * nav


def test_orthophoto_and_summary(recorded):
    first, r, _ = recorded
    ortho = r.image("/orthophoto")
    assert ortho.ndim == 3 and ortho.shape[2] == 4
    alpha = ortho[..., 3]
    assert 0.1 < (alpha == 255).mean() < 0.95 and set(np.unique(alpha)) <= {0, 255}
    text = r.values("/summary", "TextDocument:text")[0]
    assert "Reading the recording" in text and "scrub" in text.lower()
    assert all(f"{n} {record.COLOUR_NAMES[n]}" in text for n in first.estimates)   # every frustum's colour named


def test_blueprint_points_at_logged_data(recorded):
    _, r, _ = recorded
    entities = set(r.static) | set(r.temporal)
    views = {k: v for k, v in r.blueprint.items() if "ViewBlueprint:space_origin" in v}
    assert len(views) >= 12
    for v in views.values():
        origin = v["ViewBlueprint:space_origin"][0]
        assert any(e == origin or e.startswith(origin.rstrip("/") + "/") for e in entities), origin
    assert r.blueprint["/time_panel"]["TimePanelBlueprint:timeline"] == ["hypothesis"]
    ranges = [v["VisibleTimeRanges:ranges"] for k, v in r.blueprint.items()
              if k.endswith("/overrides/world/search/hypotheses/visualizers")]
    assert len(ranges) == 2                                       # the scene and the search view accumulate
    for rr_ in ranges:
        assert {x["timeline"] for x in rr_} == {"hypothesis", "search"}
        assert all(x["range"]["start"] is None and x["range"]["end"] == 0 for x in rr_)


def test_glyph_origin_and_tables():
    g = record.Glyph(np.array([10.0, 20.0, 1700.0]), 1000.0, np.array([40.0, 40.0, 40.0]))
    assert np.allclose(g(np.zeros(6)), [10, 20, 1700])
    # pitch along X, roll along Y, yaw along Z; a position error moves the other way
    assert np.allclose(g(np.array([5.0, 0, 0, 0.001, 0.002, 0.003])), [10 - 5 - 2, 20 - 3, 1700 - 1])
    far = SimpleNamespace(position=np.array([[-55094.5, -3727407.0, 5258.3], [-57710.4, -3727433.9, 5256.8]]))
    assert np.array_equal(record.local_origin(far), [-56000.0, -3727000.0, 0.0])
    assert not record.local_origin(SimpleNamespace(position=np.array([[0.0, 0, 1700], [560, 0, 1700]]))).any()
    assert [record._stride(np.zeros(s)) for s in ((1024, 8), (1025, 8), (1188, 2000))] == [1, 2, 2]
    assert record._nice_ceiling(130.4) == 150.0 and record._nice_ceiling(4.67) == 5.0
    assert record._nice_ceiling(100.0) == 100.0 and record._nice_ceiling(0.0) == 1.0
    assert np.array_equal(record.lowest_so_far(np.array([3.0, 4, 1, 1, 0.5, 2])), [0, 0, 2, 2, 4, 4])
    wide = "x\n| e | 1 | 2 | 3 | 4 | 5 | 6 | 7 | 8 | 9 |\n|---|---|---|---|---|---|---|---|---|---|\n" + \
           "| n | a | b | c | d | e | f | g | h | i |\ny"
    out = record.narrow_tables(wide)
    tables = [line for line in out.splitlines() if line.startswith("| e ")]
    assert len(tables) == 3 and all(t.count("|") == 5 for t in tables)
    assert out.startswith("x\n") and out.endswith("\ny")


@pytest.mark.skipif(not (NGI / "dem.tif").is_file(), reason=f"no ngi data at {NGI}")
def test_real_pair_in_a_local_frame(tmp_path):
    """Real coordinates (millions of metres) shifted to a local origin, the same for everything."""
    cfg = TerrainConfig(scenario="ngi", size="80x144", levels_linear=3, levels_angular=1).validate()
    first = EXPERIMENT.run_once(cfg, 0, EXPERIMENT.select(), record=True)
    path = tmp_path / "ngi.rrd"
    with stream.recording(path, "terrain", cfg.to_json(), cfg.seed, record.blueprint(list(first.estimates))) as rec:
        EXPERIMENT.record(rec, first, [EXPERIMENT.evaluate(first, cfg, 0)], "table")
    r, origin = Recording(path), record.local_origin(first.scene)
    assert np.abs(origin[:2]).max() > 1e5 and origin[2] == 0.0
    cam = r.values("/world/cameras/truth/II", "Transform3D:translation")
    assert np.abs(cam[:2]).max() < 5e3 and np.allclose(cam + origin, first.scene.position[1], atol=0.01)
    dem = r.values("/world/dem", "Mesh3D:vertex_positions", 3) + origin
    h, _, _ = first.scene.dem.sample(dem[:, 0], dem[:, 1])
    assert np.abs(dem[:, 2] - h).max() < 0.5
    tp = r.values("/world/ba/tie_points", "Points3D:positions", 3) + origin
    h, _, _ = first.scene.dem.sample(tp[:, 0], tp[:, 1])
    # on the DEM to tens of metres (a handful of tie points on 46 m pixels, heights estimated by BA with its
    # fitted height sigma); a frame mix-up would put them 1e5 m or more away
    assert np.median(np.abs(tp[:, 2] - h)) < 100.0
    _, pts = r.rows("/world/search/hypotheses", "Points3D:positions", 3)
    assert np.abs(np.concatenate(pts) + origin - first.measured.position[1]).max() < 2 * cfg.max_linear
    assert f"X = {origin[0]:.0f} m" in r.values("/summary", "TextDocument:text")[0]
