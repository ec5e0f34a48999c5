"""Trajectories in the TUM format, so ``evo`` (``evo_ape tum truth.tum ekf.tum``) can check them.

One line per pose: ``timestamp tx ty tz qx qy qz qw``; planar poses have ``tz = 0`` and a
rotation about z: ``q = (0, 0, sin(phi/2), cos(phi/2))``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.io import text as textfile
from workbench.recording.stream import check_plain_output, write_text_atomic


def format_tum(t: np.ndarray, pose: np.ndarray) -> str:
    ok = np.isfinite(pose).all(axis=1) & np.isfinite(t)
    t, pose = t[ok], pose[ok]
    half = pose[:, 2] / 2
    rows = np.column_stack([t, pose[:, 0], pose[:, 1], np.zeros(len(t)), np.zeros(len(t)), np.zeros(len(t)),
                            np.sin(half), np.cos(half)])
    return "".join(f"{r[0]:.6f} {r[1]:.6f} {r[2]:.6f} {r[3]:.1f} {r[4]:.1f} {r[5]:.1f} {r[6]:.9f} {r[7]:.9f}\n"
                   for r in rows)


def read_tum(path: Path, repairs: dict[str, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Times and planar poses ``(x, y, phi)`` back from a TUM file, through the shared text reader
    (:mod:`workbench.io.text`: ``#`` comments; a text export's quirks repaired, counted
    in ``repairs`` as ``tum_*``, said in a warning)."""
    tab = textfile.table(Path(path), "tum", {} if repairs is None else repairs, separator=textfile.WHITESPACE,
                         comments="#")
    a = np.loadtxt(["\t".join(fields) for _, fields in tab.rows], delimiter="\t", ndmin=2)
    phi = 2 * np.arctan2(a[:, 6], a[:, 7])
    return a[:, 0], np.column_stack([a[:, 1], a[:, 2], np.angle(np.exp(1j * phi))])


def export(folder: Path, trajectories: dict[str, tuple[np.ndarray, np.ndarray]], force: bool) -> list[Path]:
    """Write ``<name>.tum`` per trajectory into ``folder`` (checked first, written atomically)."""
    folder = Path(folder).expanduser()
    paths = {name: check_plain_output(folder / f"{name}.tum", force, "TUM trajectory") for name in trajectories}
    for name, (t, pose) in trajectories.items():
        write_text_atomic(paths[name], format_tum(t, pose))
    return list(paths.values())
