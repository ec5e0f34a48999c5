"""Reading a recording back with ``rerun.chunk.RrdReader``: rows per entity, properties."""

from __future__ import annotations

import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow as pa
from rerun.chunk import RrdReader


def row_counts(path: Path, temporal_only: bool = True) -> Counter:
    """Rows per entity path, summed over chunks (static rows left out unless asked)."""
    counts: Counter = Counter()
    for chunk in RrdReader(str(path)).store().stream():
        if temporal_only and chunk.is_static:
            continue
        counts[str(chunk.entity_path)] += chunk.num_rows
    return counts


def properties(path: Path, name: str = "workbench") -> dict:
    """The recording property ``name`` (stored by :func:`stream.recording`) as a dict."""
    out: dict = {}
    for chunk in RrdReader(str(path)).store().stream():
        if str(chunk.entity_path) == f"/__properties/{name}":
            batch = chunk.to_record_batch()
            for field in batch.schema:
                value = batch.column(field.name).to_pylist()[0]
                key = field.name.split(":")[-1]
                out[key] = value[0] if isinstance(value, list) and len(value) == 1 else value
    return out


def series(path: Path, entity: str, timeline: str = "time") -> tuple[np.ndarray, np.ndarray]:
    """A scalar time series back from a recording: times (s) and values, sorted by time."""
    ts, vs = [], []
    for chunk in RrdReader(str(path)).store().stream():
        if str(chunk.entity_path) != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if timeline not in names or "Scalars:scalars" not in names:
            continue
        t = batch.column(timeline).cast(pa.int64()).to_numpy(zero_copy_only=False) / 1e9
        v = np.array([x[0] if x else np.nan for x in batch.column("Scalars:scalars").to_pylist()], float)
        ts.append(t)
        vs.append(v)
    if not ts:
        raise KeyError(f"no scalar series {entity!r} on timeline {timeline!r} in {path}")
    t, v = np.concatenate(ts), np.concatenate(vs)
    order = np.argsort(t, kind="stable")
    return t[order], v[order]


def all_series(path: Path, under: tuple[str, ...], timeline: str = "time") -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Every scalar time series at an entity under one of the paths ``under``, in one pass over
    the file: entity -> (times (s), values), sorted by time."""
    parts: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    roots = tuple(u.rstrip("/") + "/" for u in under)
    for chunk in RrdReader(str(path)).store().stream():
        entity = str(chunk.entity_path)
        if chunk.is_static or not entity.startswith(roots):
            continue
        batch = chunk.to_record_batch()
        if timeline not in batch.schema.names or "Scalars:scalars" not in batch.schema.names:
            continue
        t = batch.column(timeline).cast(pa.int64()).to_numpy(zero_copy_only=False) / 1e9
        v = np.array([x[0] if x else np.nan for x in batch.column("Scalars:scalars").to_pylist()], float)
        parts.setdefault(entity, []).append((t, v))
    out = {}
    for entity, pieces in parts.items():
        t, v = np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces])
        order = np.argsort(t, kind="stable")
        out[entity] = (t[order], v[order])
    return out


def static_values(path: Path, entity: str, component: str) -> list:
    """A static component's values (e.g. ``SeriesLines:colors``) as logged, first chunk that has it."""
    for chunk in RrdReader(str(path)).store().stream():
        if str(chunk.entity_path) != entity or not chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if component in batch.schema.names:
            return batch.column(component).to_pylist()[0]
    raise KeyError(f"no static {component!r} at {entity!r} in {path}")


def rgb(packed: int) -> tuple[int, int, int]:
    """A Rerun colour (0xRRGGBBAA) as ``(r, g, b)``."""
    return (packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255


FOOTED = (0, 41)
"""The Rerun version (major, minor) from which a recording file ends with a footer."""


def check_recording(path: Path) -> None:
    """A one-line :class:`~workbench.errors.WorkbenchError` unless ``path`` is a readable
    Rerun recording with something in it (not empty, not truncated, not another kind of file)."""
    from workbench.errors import WorkbenchError

    path = Path(path)
    if not path.is_file():
        raise WorkbenchError(f"no such recording: {path}")
    try:
        with open(path, "rb") as f:
            head = f.read(8)  # "RRF2", then the writer's Rerun version (major, minor, patch, 0)
    except OSError as exc:
        raise WorkbenchError(f"cannot read {path}: {exc.strerror}") from None
    if head[:4] != b"RRF2":
        raise WorkbenchError(f"{path} is not a Rerun recording (.rrd)")
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")  # "no footer": a legacy or cut file, read by a whole-file scan
            chunks = sum(1 for _ in RrdReader(str(path)).stream())
    except Exception as exc:  # the reader's errors on a damaged file
        raise WorkbenchError(f"{path} is a damaged recording: {str(exc).splitlines()[0] if str(exc) else exc}"
                             ) from None
    if len(head) >= 6 and (head[4], head[5]) >= FOOTED and any("no footer" in str(w.message) for w in said):
        # a file cut exactly between two messages reads as a shorter one; only its missing footer
        # (which writers from Rerun 0.41 on always end with) tells
        raise WorkbenchError(f"{path} is a damaged recording: it ends without the footer its writer "
                             f"(Rerun {head[4]}.{head[5]}) puts last, so it was cut short")
    if chunks == 0:
        raise WorkbenchError(f"{path} is an empty recording")
