"""The open log formats' files, shared by every experiment's (``docs/log-formats.md``): a folder of
CSV tables (or Parquet tables of the same names and columns), a row per time, the columns named
with their units, and a ``manifest.json`` for what is not a column.

Reading: what real logs carry is repaired with a count (:mod:`.csvfile`: a last line cut short,
rows out of time order by up to a second, repeated stamps where a table has one row a time; under
it :mod:`.textfile`: a byte-order mark, blank lines at the end, a ``;`` separator with decimal
commas, quoted fields);
what cannot be read unambiguously is one line naming the file, the line and the column.
Writing: every number as Python writes it back exactly (``repr``), each file to a temporary
name and renamed, none over an existing one without ``force``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from workbench.errors import WorkbenchError, require
from workbench.io import csvfiles as csvfile


def manifest(path: Path, numbers: Iterable[str], positive: Iterable[str] = ()) -> dict:
    """The folder's manifest: a JSON object whose ``numbers`` are non-negative finite numbers
    (``positive`` ones above zero)."""
    if not path.is_file():
        raise WorkbenchError(f"{path}: missing (the log's manifest: {', '.join(numbers)})")
    try:
        m = json.loads(path.read_text(encoding="utf-8-sig"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise WorkbenchError(f"{path}: not JSON ({str(exc).splitlines()[0]})") from None
    require(isinstance(m, dict), f"{path}: not a JSON object")
    for key in numbers:
        number(path, m, key, positive=key in positive)
    return m


def number(path: Path, m: dict, key: str, positive: bool = False, default: float | None = None) -> float:
    """A manifest's number ``key`` (finite, non-negative; above zero if ``positive``), or
    ``default`` where it is absent and one is given."""
    v = m.get(key, default)
    ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and (v > 0 if positive
                                                                                          else v >= 0)
    require(ok, f"{path}: {key} must be a {'positive' if positive else 'non-negative'} number, got {v!r}")
    return float(v)


def numbers(path: Path, m: dict, key: str, shape: tuple[int, ...]) -> np.ndarray | None:
    """A manifest's array of finite numbers of ``shape`` (None where absent)."""
    if key not in m:
        return None
    try:
        v = np.array(m[key], float)
    except (TypeError, ValueError):
        v = None
    require(v is not None and v.shape == shape and np.isfinite(v).all(),
            f"{path}: {key} must be {' x '.join(map(str, shape))} finite numbers, got {m[key]!r}")
    return v


def has(folder: Path, name: str) -> bool:
    """Whether the folder holds table ``name`` (CSV or Parquet)."""
    return (folder / f"{name}.csv").exists() or (folder / f"{name}.parquet").exists()


def table(folder: Path, name: str, columns: tuple[str, ...], repairs: dict, optional: tuple[str, ...] = (),
          one_per_time: bool = True) -> dict:
    """A CSV (or Parquet) table's columns as float arrays, in time order (repairs counted), with
    each row's line in the file (``lines``). ``one_per_time``: a repeated stamp keeps the last row
    (counted); else rows may share a time (bearings of one image)."""
    parquet, path = folder / f"{name}.parquet", folder / f"{name}.csv"
    if parquet.exists() and not path.exists():
        return _parquet(parquet, columns, optional, one_per_time)
    if not path.is_file():
        raise WorkbenchError(f"{path}: missing")
    tab = csvfile.read_table(path, columns, name, repairs)
    present = [c for c in optional if c in tab.header]

    def parse(record: dict[str, str]) -> tuple:
        out = []
        for c in (*columns, *present):
            try:
                out.append(csvfile.finite(record[c]))
            except ValueError as exc:
                raise ValueError(f"column {c}: {exc}") from None
        return tuple(out)

    rows, lines = csvfile.parse_rows(tab, parse, name, repairs)
    values = np.array(rows, float).reshape(len(rows), -1)
    order = csvfile.in_order(path, values[:, 0], lines, 1.0, name, repairs)
    values, lines = values[order], np.asarray(lines)[order]
    keep = csvfile.last_of_repeats(values[:, 0]) if one_per_time else np.ones(len(values), bool)
    if not keep.all():
        csvfile.count(repairs, f"{name}_repeated_stamps", int((~keep).sum()))
        csvfile.say(path, f"{int((~keep).sum())} repeated time stamp(s): the last row of each kept")
    out = {c: values[keep, i] for i, c in enumerate((*columns, *present))}
    out["lines"] = lines[keep]
    return out


def _parquet(path: Path, columns: tuple[str, ...], optional: tuple[str, ...], one_per_time: bool) -> dict:
    import pyarrow.parquet as pq

    data = pq.read_table(path)
    missing = [c for c in columns if c not in data.column_names]
    require(not missing, f"{path}: missing column(s) {', '.join(missing)} (its columns: "
                         f"{', '.join(data.column_names)[:120]})")
    require(data.num_rows > 0, f"{path}: no rows")
    out = {}
    for c in (*columns, *[c for c in optional if c in data.column_names]):
        v = np.asarray(data[c].to_numpy(zero_copy_only=False), float)
        if not np.isfinite(v).all():
            raise WorkbenchError(f"{path}, row {int(np.flatnonzero(~np.isfinite(v))[0]) + 1}, column {c}: "
                                 "not a finite number")
        out[c] = v
    step = np.diff(out[columns[0]])
    back = np.flatnonzero(step <= 0 if one_per_time else step < 0)
    if back.size:
        raise WorkbenchError(f"{path}, row {int(back[0]) + 2}, column {columns[0]}: times out of order"
                             + (" or repeated" if one_per_time else ""))
    out["lines"] = np.arange(2, data.num_rows + 2)
    return out


def integers(path: Path, tab: dict, column: str) -> np.ndarray:
    """A column that must hold whole numbers (ids), as ints; one line naming the first that is not."""
    v = tab[column]
    bad = np.flatnonzero(v != np.round(v))
    if bad.size:
        i = int(bad[0])
        raise WorkbenchError(f"{path}, line {tab['lines'][i]}, column {column}: {float(v[i])!r} is not an integer")
    return v.astype(np.int64)


def within(path: Path, tab: dict, column: str, limit: float) -> None:
    """Every value of ``column`` within +-``limit``; one line naming the first beyond."""
    out = np.abs(tab[column]) > limit
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise WorkbenchError(f"{path}, line {tab['lines'][i]}, column {column}: {float(tab[column][i])!r} is "
                             f"beyond +-{limit:.4f}")


def write(folder: Path, files: dict[str, tuple[tuple[str, ...], np.ndarray]], meta: dict, force: bool = False
          ) -> list[Path]:
    """The tables ``{name.csv: (columns, rows)}`` and ``manifest.json``; every path checked
    before any is written."""
    from workbench.recording.stream import check_plain_output, write_text_atomic

    folder = Path(folder)
    paths = [folder / name for name in (*files, "manifest.json")]
    for p in paths:
        check_plain_output(p, force, "log file")
    for name, (columns, rows) in files.items():
        text = ",".join(columns) + "\n" + "".join(",".join(_exact(v) for v in row) + "\n" for row in rows)
        write_text_atomic(folder / name, text, force)
    write_text_atomic(folder / "manifest.json", json.dumps(meta, indent=1) + "\n", force)
    return paths


def _exact(v: float) -> str:
    f = float(v)
    return str(int(f)) if f.is_integer() and abs(f) < 2 ** 53 else repr(f)
