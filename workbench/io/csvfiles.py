"""Reading a real CSV log that has the quirks real logs have (the AIS reports, the UAV's GPS log).

What is repaired, counted in a ``repairs`` dict and said in one
:class:`~workbench.errors.DataWarning` line each (the model is the MRCLAM loader,
:mod:`workbench.experiments.omni.readers.mrclam`):

* a **last line cut short** (fewer fields than the header, or a field that is not a number: a
  writer that stopped mid-line) is left out (``<what>_cut_last_line``);
* rows stamped **out of time order** by up to ``max_backstep`` seconds are put back in order
  (``<what>_reordered``: the rows that moved);
* **repeated time stamps** (of one ship, for AIS) keep the last row of each repeat
  (``<what>_repeated_stamps``: the rows dropped).

The text itself is read by :mod:`.textfile`, under every reader's: a byte-order mark, blank lines at
the end, a ``;`` (with decimal commas) or tab separator, quoted fields are repaired with a count
(``<what>_bom``, ``<what>_trailing_empty_lines``, ``<what>_separator_semicolon``,
``<what>_decimal_commas``, ``<what>_quoted_fields``, ...), what is ambiguous refused in one line.

What cannot be repaired stays a one-line :class:`~workbench.errors.WorkbenchError`: no header
or no rows, a needed column missing (the message lists the header's), a bad field anywhere but
the last line, time running back by more than ``max_backstep``.

What both readers share besides lives here too: a file's stamp for their caches (:func:`stamp`)
and the local east-north frame (:func:`to_local`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from workbench.errors import DataWarning, WorkbenchError
from workbench.io import text as textfile

EARTH_RADIUS = 6371008.8


def stamp(path: Path) -> tuple[str, int, int]:
    """What identifies a file's contents for the caches: its path, mtime and size."""
    st = path.stat()
    return str(path.resolve()), st.st_mtime_ns, st.st_size


def to_local(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
    """Latitude/longitude (deg) to east/north metres about ``(lat0, lon0)``."""
    east = np.deg2rad(lon - lon0) * EARTH_RADIUS * np.cos(np.deg2rad(lat0))
    north = np.deg2rad(lat - lat0) * EARTH_RADIUS
    return np.stack([east, north], axis=-1)


def finite(text: str) -> float:
    """A field as a finite number (a ValueError otherwise, which :func:`read_rows` reports)."""
    v = float(text)
    if not np.isfinite(v):
        raise ValueError(f"non-finite value {text!r}")
    return v


def degrees(text: str, limit: float, what: str, unavailable: float | None = None) -> float:
    """A latitude (``limit`` 90) or longitude (180) in degrees: finite and within +-``limit``
    (a ValueError otherwise); AIS's "not available" value (91, 181) as NaN."""
    v = finite(text)
    if unavailable is not None and v == unavailable:
        return float("nan")
    if abs(v) > limit:
        raise ValueError(f"{what} {v:g} deg is outside -{limit:g}..{limit:g}")
    return v


def say(path: Path, what: str) -> None:
    """One warning line about a repair of ``path``."""
    warnings.warn(DataWarning(f"{path.name}: {what}"), stacklevel=3)


def count(repairs: dict[str, int], key: str, n: int) -> None:
    if n:
        repairs[key] = repairs.get(key, 0) + int(n)


def read_table(path: Path, columns: Sequence[str], what: str, repairs: dict[str, int]) -> textfile.Table:
    """A CSV file with a header holding ``columns``, read by :func:`.textfile.table` (a BOM, blank
    lines at the end, a ``;`` or tab separator, decimal commas, quoted fields: repaired and counted);
    no header, a column missing or no rows is one line."""
    tab = textfile.table(path, what, repairs, columns=columns)
    if not tab.header or not any(tab.header):
        raise WorkbenchError(f"malformed {what} file {path}: no header line")
    missing = [c for c in columns if c not in tab.header]
    if missing:
        raise WorkbenchError(f"malformed {what} file {path}: missing column(s) {', '.join(missing)} "
                             f"(its columns: {', '.join(tab.header)[:120]})")
    if not tab.rows:
        raise WorkbenchError(f"malformed {what} file {path}: no rows after the header")
    return tab


def read_rows(path: Path, columns: Sequence[str], parse: Callable[[dict[str, str]], tuple],
              what: str, repairs: dict[str, int]) -> tuple[list[tuple], list[int]]:
    """The parsed rows of a CSV file with a header (:func:`read_table`), and each one's line number."""
    return parse_rows(read_table(path, columns, what, repairs), parse, what, repairs)


def parse_rows(tab: textfile.Table, parse: Callable[[dict[str, str]], tuple], what: str,
               repairs: dict[str, int]) -> tuple[list[tuple], list[int]]:
    """``parse(record)`` of each row of ``tab`` (column -> text), with its line number.

    ``parse`` raises ``ValueError`` / ``TypeError`` for a bad field. A bad last line is left out
    and counted as cut short; a bad line elsewhere is an error naming it.
    """
    path, header = tab.path, tab.header or []
    rows, numbers = [], []
    for i, (number, fields) in enumerate(tab.rows):
        try:
            if len(fields) < len(header):
                raise ValueError(f"{len(fields)} field(s), the header has {len(header)}")
            rows.append(parse(dict(zip(header, fields, strict=False))))
            numbers.append(number)
        except (TypeError, ValueError) as exc:
            if i == len(tab.rows) - 1 and i > 0:
                count(repairs, f"{what}_cut_last_line", 1)
                say(path, f"line {number} is cut short ({tab.lines[number - 1].strip()[:40]!r}): left out")
                break
            raise WorkbenchError(f"malformed {what} file {path}, line {number}: {exc}") from None
    return rows, numbers


def in_order(path: Path, t: np.ndarray, numbers: Sequence[int] | Callable[[], Sequence[int]], max_backstep: float,
             what: str, repairs: dict[str, int]) -> np.ndarray:
    """The permutation that puts rows in time order: rows stamped up to ``max_backstep`` s
    behind the latest before them are put back (counted as ``<what>_reordered``, said); further
    back is an error naming the two lines. ``numbers``: each row's line in the file, or a function
    giving them (read only for the error)."""
    if not (np.diff(t) < 0).any():
        return np.arange(len(t))
    latest = np.maximum.accumulate(t)
    behind = latest[:-1] - t[1:]
    if behind.max() > max_backstep:
        row = int(np.argmax(behind > max_backstep)) + 1
        prev = int(np.flatnonzero(t[:row] == latest[row - 1])[-1])
        lines = numbers() if callable(numbers) else numbers
        raise WorkbenchError(f"{what} file {path}, line {lines[row]}: time goes backwards by "
                             f"{_seconds(latest[row - 1] - t[row])} s from line {lines[prev]} "
                             f"(more than {max_backstep:g} s: not a row out of order)")
    order = np.argsort(t, kind="stable")
    moved = int(np.sum(order != np.arange(len(t))))
    count(repairs, f"{what}_reordered", moved)
    say(path, f"{moved} row(s) out of time order (by up to {_seconds(behind.max())} s): put back in order")
    return order


def _seconds(s: float) -> str:
    """A time step as a repair names it: tenths from a second up, milliseconds below."""
    return f"{s:.1f}" if s >= 1.0 else f"{s:.3f}"


def last_of_repeats(keys: np.ndarray) -> np.ndarray:
    """A mask keeping the last row of each run of equal ``keys`` (rows already sorted by them)."""
    if len(keys) == 0:
        return np.zeros(0, bool)
    same = np.all(keys[1:] == keys[:-1], axis=-1) if keys.ndim > 1 else keys[1:] == keys[:-1]
    return np.append(~same, True)
