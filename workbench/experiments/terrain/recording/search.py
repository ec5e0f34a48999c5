"""The terrain recording's search: every hypothesis drawn in 3D at the image II position it implies
(its attitude error as a small offset, :class:`Glyph`), coloured by the rank of its functional, over
the sequence timelines ``hypothesis`` and ``search``; the lowest hypothesis so far and its cell; the
truth and every estimate drawn the same way; and the functional itself (entities under
``world/search/`` and ``functional``: :mod:`.record`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from workbench.estimation.angles import wrap
from workbench.experiments.terrain import navigation
from workbench.experiments.terrain.estimate import Estimate
from workbench.experiments.terrain.estimators import SEARCH
from workbench.experiments.terrain.recording.scene import color
from workbench.experiments.terrain.run import RunResult
from workbench.recording import draw

TIMELINES = ("hypothesis", "search")


@dataclass
class Glyph:
    """How a hypothesis (image II's six pose errors ``dX, dY, dH, dpsi, dtheta, dgamma``) is
    drawn in 3D: at the position it implies (measured minus the position error) moved by
    ``scale`` metres per radian of its attitude error, pitch along X, roll along Y, yaw along Z.
    On a grid the attitude cells form a small cube (35 % of a position cell) around each
    position cell."""

    measured: np.ndarray      # (3,) image II's measured position (world frame of the recording)
    scale: float              # m per rad
    cell: np.ndarray          # (3,) the position cell's size, m

    def __call__(self, pose_errors: np.ndarray) -> np.ndarray:
        p = np.asarray(pose_errors, float)
        return self.measured - p[..., :3] - self.scale * p[..., [4, 5, 3]]


def pose_errors(first: RunResult, centres: np.ndarray) -> np.ndarray:
    """Image II's pose errors ``(..., 6)`` of error states (the search's hypotheses)."""
    m = navigation.error_map(first.scene_mode, first.scene.interval)[1]
    return np.asarray(centres, float) @ m.T


def estimate_errors(first: RunResult, e: Estimate | tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Image II's pose errors (measured - this pose), as the search would state them."""
    pos, ang = (e.position, e.angles) if isinstance(e, Estimate) else e
    return np.concatenate([first.measured.position[1] - pos[1], wrap(first.measured.angles[1] - ang[1])])


def glyph(first: RunResult, origin: np.ndarray) -> Glyph:
    """The drawing of this run's hypotheses (their grid's cell, or for samples the cube's
    volume shared among them)."""
    s = first.search
    pose = pose_errors(first, s.centres)
    lin, ang = pose[:, :3], pose[:, 3:]
    ptp = np.ptp(lin, axis=0)
    if s.kind == "grid":
        levels = np.array([len(np.unique(np.round(lin[:, a], 6))) for a in range(3)])
        cell = np.where(levels > 1, ptp / np.maximum(levels - 1, 1), np.nan)
    else:
        cell = np.where(ptp > 0, ptp / len(lin) ** (1.0 / 3.0), np.nan)
    cell = np.where(np.isfinite(cell), cell, np.nanmax(cell) if np.isfinite(cell).any() else 1.0)
    spread = float(np.ptp(ang, axis=0).max())
    scale = 0.35 * float(cell.min()) / spread if spread > 0 else 0.0
    return Glyph(first.measured.position[1] - origin, scale, cell)


def lowest_so_far(f: np.ndarray) -> np.ndarray:
    """For every hypothesis, the index of the lowest functional up to it (the first on ties)."""
    low = np.minimum.accumulate(f)
    new = np.r_[True, low[1:] < low[:-1]]
    return np.maximum.accumulate(np.where(new, np.arange(len(f)), 0))


def _ramp(rank: np.ndarray) -> np.ndarray:
    """A viridis-like ramp for ``rank`` in [0, 1], reversed: 0 (the lowest functional) bright
    yellow, 1 dark purple (fading into the dark background). uint8 RGB."""
    stops = np.array([[253, 231, 37], [94, 201, 98], [33, 145, 140], [59, 82, 139], [68, 1, 84]], float)
    x = np.clip(np.nan_to_num(rank), 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(x.astype(int), len(stops) - 2)
    f = (x - i)[..., None]
    return (stops[i] * (1 - f) + stops[i + 1] * f).round().astype(np.uint8)


def record_search(rec: rr.RecordingStream, first: RunResult, origin: np.ndarray) -> None:
    """The hypothesis cloud over the search's timelines, the winner and its cell, the truth and
    every estimate drawn the same way, and the functional."""
    s = first.search
    g = glyph(first, origin)
    pose = pose_errors(first, s.centres)
    pts = g(pose)
    f = np.asarray(s.functional, float)
    n = len(f)
    rank = np.argsort(np.argsort(f, kind="stable"), kind="stable") / max(1, n - 1)
    starts = np.arange(0, n, max(1, s.chunk))
    counts = np.diff(np.r_[starts, n])
    radius = 0.04 * float(g.cell.min())
    rec.log("/world/search/hypotheses", rr.Points3D.from_fields(radii=[radius]), static=True)
    rec.send_columns("/world/search/hypotheses",
                     indexes=[rr.TimeColumn("hypothesis", sequence=starts + counts - 1),
                              rr.TimeColumn("search", sequence=np.arange(len(starts)))],
                     columns=rr.Points3D.columns(positions=pts, colors=_ramp(rank)).partition(counts))
    # the lowest hypothesis so far (and its position cell), a row wherever it changes; the last is the winner
    w = s.winner
    ends = starts + counts - 1
    best = lowest_so_far(f)[ends]
    best[-1] = w
    change = np.flatnonzero(np.r_[True, best[1:] != best[:-1]])
    labels = [f"lowest so far #{b}" for b in best[change]]
    labels[-1] = f"winner #{w}"
    steps = [rr.TimeColumn("hypothesis", sequence=ends[change]), rr.TimeColumn("search", sequence=change)]
    rec.log("/world/search/winner", rr.Points3D.from_fields(radii=[2.5 * radius], colors=[color(first, SEARCH)]),
            static=True)
    rec.send_columns("/world/search/winner", indexes=steps,
                     columns=rr.Points3D.columns(positions=pts[best[change]], labels=labels))
    rec.log("/world/search/winner_cell",
            rr.Boxes3D.from_fields(half_sizes=[g.cell / 2.0], colors=[color(first, SEARCH)],
                                   radii=[draw.ui_points(1.5)], fill_mode="MajorWireframe"), static=True)
    rec.send_columns("/world/search/winner_cell", indexes=steps,
                     columns=rr.Boxes3D.columns(centers=g.measured - pose[best[change], :3]))
    known = bool(np.isfinite(first.scene.position).all())  # (a log may have no truth)
    names = ["truth"] * known + [name for name in first.estimates if name != SEARCH]
    poses = [estimate_errors(first, (first.scene.position, first.scene.angles))] * known
    poses += [estimate_errors(first, first.estimates[name]) for name in names[known:]]
    rec.log("/world/search/markers", rr.Points3D(g(np.stack(poses)), radii=[2.0 * radius], labels=names,
                                                 colors=[color(first, name) for name in names]), static=True)
    _functional(rec, first)


def _functional(rec: rr.RecordingStream, first: RunResult) -> None:
    """The functional on both timelines: every hypothesis (I_pq - min I), the lowest so far, the winner."""
    s = first.search
    f = np.asarray(s.functional, float)
    n, w = len(f), s.winner
    hyp = np.arange(n)
    indexes = [rr.TimeColumn("hypothesis", sequence=hyp), rr.TimeColumn("search", sequence=hyp // max(1, s.chunk))]
    rel = f - f.min()
    rec.log("/functional", rr.SeriesLines(colors=[color(first, SEARCH)], names=["I_pq - min I"]), static=True)
    rec.send_columns("/functional", indexes=indexes, columns=rr.Scalars.columns(scalars=rel))
    rec.log("/functional/lowest", rr.SeriesLines(colors=[(40, 140, 255)], names=["lowest so far"], widths=[2.0]),
            static=True)
    rec.send_columns("/functional/lowest", indexes=indexes,
                     columns=rr.Scalars.columns(scalars=np.minimum.accumulate(rel)))
    rec.log("/functional/winner", rr.SeriesPoints(colors=[(200, 30, 30)], names=[f"winner #{w}"], marker_sizes=[6.0]),
            static=True)
    rec.send_columns("/functional/winner",
                     indexes=[rr.TimeColumn("hypothesis", sequence=[w]),
                              rr.TimeColumn("search", sequence=[w // max(1, s.chunk)])],
                     columns=rr.Scalars.columns(scalars=[rel[w]]))
