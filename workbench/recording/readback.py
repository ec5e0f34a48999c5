"""Reading a recording back with ``rerun.chunk.RrdReader``: rows per entity, properties."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

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
