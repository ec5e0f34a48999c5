"""The terrain recording: the scene in 3D and the search over its own timeline.

Everything 3D is in one world frame (X east, Y north, Z up, metres) under ``/world``; for real
data far from the origin a round local origin is subtracted (float32 in the viewer would
otherwise quantise the cameras to decimetres), and the summary says which. Entity layout
(run 0 in full):

* ``world/dem`` (the DEM mesh, textured with both true-orientation orthophotos where the images
  see it and a hillshade elsewhere), ``world/cameras/<who>/<I|II>`` for ``truth`` (with the
  images and the baseline's tie points on them), ``navigation`` and every estimator (frusta in
  its colour);
* ``world/search/hypotheses``: every hypothesis drawn at the image II position it implies,
  its attitude error as a small offset (:class:`Glyph`), coloured by the rank of its
  functional; one row per evaluated chunk on the timelines ``hypothesis`` (the last hypothesis
  of the chunk) and ``search`` (the chunk's step); the views accumulate them up to the cursor.
  ``world/search/winner`` and ``world/search/winner_cell`` (the lowest hypothesis so far and
  its position cell, a row where it changes: the winner at the end), ``world/search/markers``
  (truth and every estimate in the same drawing);
* ``world/ba/{tie_points,rays}`` (the baseline's landmarks and rays from both BA cameras to a
  subset of them);
* ``world/halftone/<estimator>`` (image II draped on its ground coordinates: the halftone
  model, a textured mesh); ``errors/<estimator>`` (its per-pixel ground error map in metres, a
  colour-mapped depth image with its own legend); ``orthophoto`` (image II resampled north-up
  on the ground with the best orientation, transparent outside the image);
* ``functional`` (I_pq - min per hypothesis), ``functional/lowest`` (lowest so far) and
  ``functional/winner`` on the same timelines; ``summary`` (the table and how to read all this).

This module lays the views out and writes the summary; the drawing is in :mod:`.record_scene`
(colours, world frame, DEM, frusta, baseline), :mod:`.record_search` (the hypotheses and the
functional) and :mod:`.record_ground` (halftone models, error maps, orthophoto), on the shared
primitives of :mod:`workbench.recording.draw`.
"""

from __future__ import annotations

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from workbench.errors import WorkbenchError
from workbench.experiments.terrain.estimators import ITERATED, POSTERIOR, REFINED, SEARCH, TABLE
from workbench.experiments.terrain.evaluate import RunSummary
from workbench.experiments.terrain.metrics import truth_known
from workbench.experiments.terrain.products.model import PREFERRED
from workbench.experiments.terrain.recording.ground import (
    _stride,
    halftone_texcoords,
    record_error_map,
    record_halftones,
    record_orthophoto,
)
from workbench.experiments.terrain.recording.scene import (
    COLOUR_NAMES,
    TRUTH,
    color,
    dem_texture,
    footprint_bounds,
    ground_sample_distance,
    local_origin,
    placement,
    record_baseline,
    record_cameras,
    record_dem,
)
from workbench.experiments.terrain.recording.search import (
    TIMELINES,
    Glyph,
    estimate_errors,
    glyph,
    lowest_so_far,
    pose_errors,
    record_search,
)
from workbench.experiments.terrain.run import RunResult
from workbench.metrics.curves import narrow_tables
from workbench.recording import draw
from workbench.recording import layout as views

__all__ = [  # the experiment contract's, what moved to the record_* modules, and what the tests read
    "layout", "record_run", "record_runs", "blueprint", "legend", "narrow_tables", "measurements_markdown",
    "local_origin", "footprint_bounds", "ground_sample_distance", "dem_texture", "color", "COLOUR_NAMES",
    "halftone_texcoords", "Glyph", "glyph", "pose_errors", "estimate_errors", "lowest_so_far",
    "NICE", "_nice_ceiling", "_stride",
]
NICE, _nice_ceiling = draw.NICE, draw.nice_ceiling   # a legend's tops (the error maps': draw.error_image)


def _best(names: list[str]) -> str:
    """The estimator whose halftone model and orthophoto are shown by default."""
    return next((n for n in (POSTERIOR, ITERATED, REFINED, "gtsam-ba", SEARCH) if n in names), "navigation")


def _accumulate() -> rrb.VisibleTimeRanges:
    """Everything from the start of the search up to the time cursor, on both timelines."""
    return rrb.VisibleTimeRanges([rrb.VisibleTimeRange(t, start=rrb.TimeRangeBoundary.infinite(),
                                                       end=rrb.TimeRangeBoundary.cursor_relative())
                                  for t in TIMELINES])


def blueprint(names: list[str]) -> rrb.Blueprint:
    """The 3D scene (and the halftone model) on the left; the search (hypothesis cloud and the
    functional), the images, the ground error maps, the orthophoto and the table on the right."""
    cloud = {"/world/search/hypotheses": _accumulate()}
    quiet = rr.Points3D.from_fields(show_labels=False)   # the markers' labels only in the search view
    scene = rrb.Spatial3DView(origin="/world", contents=["+ $origin/**", "- $origin/halftone/**"],
                              name="scene (m, z up): DEM, frusta, tie points, hypotheses",
                              background=views.MAP_BACKGROUND,
                              overrides={**cloud, "/world/search/markers": quiet, "/world/search/winner": quiet})
    best = next((n for n in PREFERRED if n in names), _best(names))  # the estimator the model files are built from
    model = rrb.Spatial3DView(
        origin="/world", contents=["+ $origin/halftone/**", "+ $origin/ba/tie_points"],
        name=f"halftone model ({best}; others hidden)", background=views.MAP_BACKGROUND,
        overrides={f"/world/halftone/{n}": rrb.EntityBehavior(visible=False) for n in names if n != best})
    search = rrb.Spatial3DView(
        origin="/world", contents=["+ $origin/search/**"], background=views.MAP_BACKGROUND, overrides=cloud,
        name="hypotheses: image II position + attitude offset, colour = I_pq rank (yellow lowest)")
    # not views.plot: that opens on a span of seconds; this plot is on the sequence timelines, all of them
    whole = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    functional = rrb.TimeSeriesView(origin="/functional", name="functional I_pq - min I per hypothesis",
                                    plot_legend=rrb.Corner2D.RightTop, axis_x=rrb.TimeAxis(view_range=whole))
    images = rrb.Vertical(
        rrb.Spatial2DView(origin="/world/cameras/truth/I", name="image I + tie points"),
        rrb.Spatial2DView(origin="/world/cameras/truth/II", name="image II + tie points, measurements"),
        name="images")
    errors = rrb.Grid(*[rrb.Spatial2DView(origin=f"/errors/{n}", name=n) for n in names], name="ground error (m)")
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Tabs(scene, model),
            rrb.Tabs(rrb.Vertical(search, functional, row_shares=[3, 2], name="search"), images, errors,
                     rrb.Spatial2DView(origin="/orthophoto", name="orthophoto"),
                     rrb.TextDocumentView(origin="/summary", name="results")),
            column_shares=[3, 2]),
        rrb.TimePanel(state="collapsed", timeline="hypothesis"),
        collapse_panels=True,
    )


def legend(first: RunResult, origin: np.ndarray) -> str:
    """How to read the recording (markdown, after the table)."""
    shown = {n: first.estimators.get(n) or TABLE[n] for n in first.estimates}
    frusta = f"truth {draw.colour_name(TRUTH)}, " + draw.colour_key(shown, plugin="a plugin")
    tie_points, winner = (draw.colour_name(color(first, n)) for n in ("gtsam-ba", SEARCH))
    where = ("" if not origin.any() else
             f"; local origin at X = {origin[0]:.0f} m, Y = {origin[1]:.0f} m of the data's projection")
    lines = [
        "",
        "**Reading the recording** (run 0, error mode `" + first.scene_mode + "`; world X east, Y north, "
        "Z up, metres" + where + ")",
        "",
        f"- frusta: {frusta}; the truth's carry the images (tie points {tie_points}).",
        "- DEM: textured with both images at the true orientation; warm hillshade where no image sees it.",
    ]
    if first.search is not None:
        g = glyph(first, origin)
        lines.append(
            f"- search: each hypothesis at the image II position it implies, its attitude error as an offset of "
            f"{g.scale / 1000.0:.3g} m per mrad (pitch along X, roll along Y, yaw along Z); colour = rank of I_pq "
            f"(yellow lowest, dark purple highest); the {winner} point and box: the lowest hypothesis so far and its "
            "position cell (the winner at the end); markers: truth and every estimate drawn the same way. Scrub the "
            "`hypothesis` (or `search` step) timeline.")
    lines.append("- ground error maps: per-pixel horizontal error of each halftone model over image II, "
                 "each on its own colour scale (bar in metres).")
    return "\n".join(lines)


def layout(first: RunResult, runs: list[RunSummary]) -> rrb.Blueprint:
    """The default layout of a run's recording."""
    return blueprint(list(first.estimates))


def record_run(rec: rr.RecordingStream, first: RunResult, zero: RunSummary) -> None:
    """Log run 0 (``zero`` is its evaluation): scene, cameras, the search, the baseline's
    tie points, the halftone models and their ground error maps. A log without the true
    orientation places the frames (and frames the DEM) at the navigation's measured one."""
    placed = placement(first)
    origin = local_origin(placed)
    rec.log("/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    bounds = record_dem(rec, placed, origin)
    record_cameras(rec, first, origin, placed)
    if first.search is not None:
        record_search(rec, first, origin)
    record_baseline(rec, first, origin)
    record_halftones(rec, first, origin)
    for name, err in zero.ground_maps.items():
        record_error_map(rec, name, err)
    record_orthophoto(rec, placed, first.estimates[_best(list(first.estimates))], bounds)
    _measurements(rec, first, origin)


MEASURE_RGB = (255, 235, 60)


def _measurements(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """A few measurements in the run's halftone model (:func:`.measure.examples`): on image II
    (pixels) and on the model's surface in 3D (the edges' ground points, along the terrain,
    lifted a little above it to stay in sight), labelled value +- sigma."""
    from workbench.experiments.terrain.products import measure, model

    try:
        m = model.from_run(first)
        found = measure.examples(m)
    except WorkbenchError:
        return  # a model the DEM does not hold: the recording goes without its measurements
    lift = np.array([0.0, 0.0, 0.002 * (m.position[2] - m.dem.mean_height)])
    for i, ms in enumerate(found):
        q = ms.quantities[{"point": 2, "line": 0, "polygon": 0}[ms.kind]]
        label = q.text().replace(" +- ", " ± ").replace("m^2", "m²")
        if ms.kind == "point":
            rec.log(f"/world/cameras/truth/II/measurements/{i}",
                    rr.Points2D(np.array(ms.pixels) + 0.5, radii=[draw.ui_points(5)], colors=[MEASURE_RGB],
                                labels=[label]), static=True)
            rec.log(f"/world/halftone/measurements/{i}",
                    rr.Points3D(ms.ground - origin + lift, radii=[draw.ui_points(6)], colors=[MEASURE_RGB],
                                labels=[label]), static=True)
            continue
        closed = ms.kind == "polygon"
        px = np.array(ms.pixels + ms.pixels[:1] if closed else ms.pixels) + 0.5  # Rerun's pixel centres: +0.5
        along = measure.edge_pixels(ms.pixels, closed)
        g = m.ground(along[:, 0], along[:, 1]) - origin + lift
        rec.log(f"/world/cameras/truth/II/measurements/{i}",
                rr.LineStrips2D([px], radii=[draw.ui_points(2)], colors=[MEASURE_RGB], labels=[label]), static=True)
        rec.log(f"/world/halftone/measurements/{i}",
                rr.LineStrips3D([g], radii=[draw.ui_points(3)], colors=[MEASURE_RGB], labels=[label]), static=True)


def measurements_markdown(first: RunResult) -> str:
    """The recorded measurements as a table, beside what the same pixels measure under the
    true orientation (the scene's truth; for NGI its published orientation)."""
    from workbench.experiments.terrain.products import measure, model

    try:
        m = model.from_run(first)
        found = measure.examples(m)
        sc = first.scene
        truth = (measure.examples(model.Model("truth", sc.dem, sc.k, sc.position[1], sc.angles[1], None))
                 if truth_known(sc) else None)
    except WorkbenchError:
        return ""
    rows = ["", f"**halftone model** (image II under {m.estimator}'s orientation, model {m.model_id}; "
            "`workbench measure` reads its files): a few measurements, +- the orientation covariance's sigma",
            "", "| measurement | value | sigma | true orientation | error / sigma |", "|---|---|---|---|---|"]
    for a, b in zip(found, truth or [None] * len(found), strict=True):
        for j, q in enumerate(a.quantities):
            r = b.quantities[j] if b is not None else None
            z = f"{(q.value - r.value) / q.sigma:+.2f}" if q.sigma and r is not None else "-"
            sig = f"{q.sigma:.3g}" if q.sigma is not None else "-"
            rows.append(f"| {a.kind} {q.name} ({q.unit}) | {q.value:.6g} | {sig} | "
                        f"{'-' if r is None else f'{r.value:.6g}'} | {z} |")
    return "\n".join(rows) + "\n"


def record_runs(rec: rr.RecordingStream, first: RunResult, runs: list[RunSummary], table_md: str) -> None:
    """Log the results table (the Monte Carlo statistics) and how to read the recording."""
    text = narrow_tables(table_md) + "\n" + legend(first, local_origin(placement(first))) + measurements_markdown(first)
    rec.log("/summary", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
