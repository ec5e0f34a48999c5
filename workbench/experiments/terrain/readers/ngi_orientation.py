"""The NGI folder's exterior orientation files, read strictly: ``camera_pos_ori.txt`` (name x y z
omega phi kappa, space separated, six decimals) and ``ngi_xyz_opk.csv`` (the same with a header
line, comma separated, three decimals).

The orientation is the truth every error is measured against, so no value in it is repaired: a
line with the wrong number of fields (a last line cut short by a copy that stopped mid-file
included), a value that is not a finite number, a frame given twice with different values, a
frame missing, or the two files disagreeing beyond the csv's rounding is a one-line
:class:`~workbench.errors.WorkbenchError` naming the file and the line (exit code 2). Tolerated:
a missing ``camera_pos_ori.txt`` when the csv is there (the csv's orientation is used and a
:class:`~workbench.errors.DataWarning` says so), and what a text export changes in the text but
not in a value, read by the shared reader (:mod:`workbench.io.text`): a byte-order
mark, blank lines at the end, a ``;`` separator with decimal commas (or a tab; in the text file
``,``), quoted fields, each counted (``<file stem>_<quirk>``, in the metrics' ``data_repairs``)
and said in one warning line.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from workbench.errors import DataWarning, WorkbenchError, require
from workbench.io import text as textfile

TEXT = "camera_pos_ori.txt"
CSV = "ngi_xyz_opk.csv"
CSV_HEADER = ("filename", "x", "y", "z", "omega", "phi", "kappa")
CSV_TOLERANCE = (0.002, 0.002)
"""How far the csv may differ from the text file (m, deg): its three decimals' rounding (5e-4)
with room for the text file's own."""
FRAME = re.compile(r"(\d{4})(?:_RGB)?(?:\.tiff?)?$", re.IGNORECASE)


def frame_id(name: str) -> str:
    """``3324c_2015_1004_05_0182_RGB`` -> ``0182`` (the last four digits before ``_RGB``)."""
    found = FRAME.search(name.strip())
    return found.group(1) if found else name.strip()


def _fields(path: Path, n: int, line: str, fields: list[str], cut: bool) -> tuple[str, np.ndarray]:
    """One data line: its frame id and its six numbers (x, y, z m; omega, phi, kappa deg)."""
    if len(fields) != 7:
        shown = line.strip()[:60]
        if cut and len(fields) < 7:
            raise WorkbenchError(f"{path.name} line {n} is cut short ({len(fields)} of 7 fields: {shown!r}): "
                                 "the file looks truncated")
        raise WorkbenchError(f"{path.name} line {n}: expected a name and 6 numbers (x y z omega phi kappa), "
                             f"got {len(fields)} fields: {shown!r}")
    try:
        values = np.array([float(v) for v in fields[1:]])
    except ValueError:
        raise WorkbenchError(f"{path.name} line {n}: not a number among {' '.join(fields[1:])[:60]!r}") from None
    require(bool(np.all(np.isfinite(values))), f"{path.name} line {n}: a value is not finite ({' '.join(fields[1:])})")
    require(bool(np.all(np.abs(values[3:]) <= 360.0)),
            f"{path.name} line {n}: omega, phi, kappa must be degrees within +-360 (got {' '.join(fields[4:])})")
    return frame_id(fields[0]), values


def read(path: Path, repairs: dict[str, int] | None = None) -> dict[str, np.ndarray]:
    """Frame id -> ``(x, y, z, omega, phi, kappa)`` from either file (by its name: ``.csv`` is
    comma separated with a header line, anything else space separated), through the shared text
    reader (:mod:`workbench.io.text`: its repairs counted in ``repairs`` under the
    file's stem, ``camera_pos_ori_bom``, ``ngi_xyz_opk_separator_semicolon``, ...)."""
    require(path.is_file(), f"orientation file not found: {path}")
    csv = path.suffix.lower() == ".csv"
    try:
        tab = textfile.table(path, path.stem, {} if repairs is None else repairs,
                             separator="," if csv else textfile.WHITESPACE, comments="#")
    except OSError as exc:
        raise WorkbenchError(f"cannot read {path.name}: {type(exc).__name__}") from None
    out: dict[str, np.ndarray] = {}
    where: dict[str, int] = {}
    for i, (n, fields) in enumerate(tab.rows):
        line = tab.lines[n - 1]
        if csv and i == 0 and fields[0].lower() == CSV_HEADER[0]:
            require(tuple(f.lower() for f in fields) == CSV_HEADER,
                    f"{path.name} line {n}: header {line.strip()!r}, expected {','.join(CSV_HEADER)}")
            continue
        frame, values = _fields(path, n, line, fields, not tab.ended and i == len(tab.rows) - 1)
        if frame in out and not np.array_equal(out[frame], values):
            raise WorkbenchError(f"{path.name}: frame {frame} on lines {where[frame]} and {n} with different values")
        out[frame], where[frame] = values, n
    require(bool(out), f"{path.name}: no orientation lines")
    return out


def check_agree(text: dict[str, np.ndarray], csv: dict[str, np.ndarray], frames: tuple[str, ...]) -> None:
    """The csv's orientation of ``frames`` is the text file's, to the csv's rounding."""
    for f in frames:
        d = np.abs(text[f] - csv[f])
        for part, cols, tol, unit in (("position", slice(0, 3), CSV_TOLERANCE[0], "m"),
                                      ("angles", slice(3, 6), CSV_TOLERANCE[1], "deg")):
            worst = float(d[cols].max())
            require(worst <= tol, f"{TEXT} and {CSV} disagree on frame {f}'s {part} by {worst:.3g} {unit} "
                                  f"(more than the csv's rounding, {tol:g} {unit})")


def orientation(folder: Path, frames: tuple[str, ...], repairs: dict[str, int] | None = None
                ) -> dict[str, np.ndarray]:
    """The orientation of ``frames`` from ``folder``: the text file's, checked against the csv
    where both are there; the csv's alone (with a warning) where the text file is missing. What
    reading the text repaired is counted in ``repairs`` (:func:`read`)."""
    text_path, csv_path = folder / TEXT, folder / CSV
    if not text_path.is_file() and csv_path.is_file():
        warnings.warn(DataWarning(f"{TEXT} not found in {folder}: the orientation is {CSV}'s (three decimals)"),
                      stacklevel=2)
        primary = read(csv_path, repairs)
        _require_frames(primary, frames, CSV)
        return primary
    primary = read(text_path, repairs)
    _require_frames(primary, frames, TEXT)
    if csv_path.is_file():
        second = read(csv_path, repairs)
        _require_frames(second, frames, CSV)
        check_agree(primary, second, frames)
    return primary


def _require_frames(table: dict[str, np.ndarray], frames: tuple[str, ...], name: str) -> None:
    for f in frames:
        require(f in table, f"{name} has no frame {f} (it has {', '.join(sorted(table)) or 'none'})")

