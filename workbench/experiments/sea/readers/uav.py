"""A real UAV flight as the camera's path (``--observer uav`` with ``scenario ais``).

``UAV_Rot.csv`` (Stone Soup's test data) is a UAV's GPS log at 1 Hz: 965 rows, columns time
(``YYYY-MM-DD HH:MM:SS``), timestamp (seconds of the day), latitude, longitude,
altitude (m), speed, heading, date, groupNb, Vx, Vy. The flight is not over the Solent, so
only its **shape** is used.

Readings taken here (the spec only says the path "can serve as the observer"):

* **Time base**: the ``time`` column (a date and time, so midnight cannot wrap it), in
  seconds from the first row; the run uses the flight from ``uav_start`` seconds on, and the
  1 Hz positions are put on the filter's step by a shape-preserving cubic (PCHIP) in a local
  east-north frame (equirectangular about the flight's centre; the flight spans about 2 km).
* **Placement**: the flight is translated, not rotated or scaled, so that at the run's first
  step the UAV is where the default mast stands (``ais_range`` abeam of the ship's segment
  middle); from there it flies its own recorded path (east stays east). The camera's axis
  keeps the mast's bearing (a gimbal holding its azimuth): the ``heading`` column reads 0
  while the UAV hovers, and the angle model needs a course psi, not the airframe's yaw.
* **Height**: the paper's model has one known camera height, so the camera stays at
  ``--height`` (the ``altitude (m)`` column, 708-768 m above the datum here, rises 60 m from
  take-off and is read and checked but not used).
* Quirks (:mod:`.csvfile`): rows up to ``MAX_BACKSTEP`` s out of order are put back, repeated
  time stamps keep the last row, a last line cut short is left out, and gaps over
  ``SHORT_GAP`` s (missing fixes) are interpolated across; each counted (``uav_*`` in the
  metrics' ``data_repairs``) and said in one warning line. A gap over ``MAX_GAP`` s inside the
  run's stretch, or a run longer than the flight, is a one-line error.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from workbench.errors import WorkbenchError
from workbench.io import csvfiles as csvfile
from workbench.paths import data_file

DEFAULT_FILE = "ais/UAV_Rot.csv"
COLUMNS = ("time", "latitude", "longitude", "altitude (m)")
MAX_BACKSTEP = 5.0
"""How far back (s) a fix may be stamped and still be put back in order; beyond it, an error."""
SHORT_GAP = 1.5
"""A gap (s) between fixes of the 1 Hz log counted as missing fixes, interpolated across."""
MAX_GAP = 10.0
"""The longest gap (s) a run's stretch may cross: a path is not invented over a longer one."""


@dataclass
class UavLog:
    """The flight: seconds from its first fix, degrees, metres; sorted, without repeats."""

    path: Path
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    repairs: dict[str, int] = field(default_factory=dict)

    @property
    def local(self) -> np.ndarray:
        """East/north metres about the flight's centre, ``(N, 2)``."""
        return csvfile.to_local(self.lat, self.lon, float(np.mean(self.lat)), float(np.mean(self.lon)))


def read(path: Path | None) -> UavLog:
    """Read the UAV log (cached while the file is unchanged); bad files are a WorkbenchError."""
    return _read(*csvfile.stamp(data_file(path, DEFAULT_FILE)))


def _parse(rec: dict[str, str]) -> tuple:
    altitude = csvfile.finite(rec["altitude (m)"])
    if not -500.0 <= altitude <= 1e5:
        raise ValueError(f"altitude {altitude:g} m is not a flight's")
    return (datetime.fromisoformat(rec["time"].strip()).timestamp(), csvfile.degrees(rec["latitude"], 90.0, "latitude"),
            csvfile.degrees(rec["longitude"], 180.0, "longitude"), altitude)


@functools.lru_cache(maxsize=4)
def _read(name: str, mtime: int, size: int) -> UavLog:
    path = Path(name)
    repairs: dict[str, int] = {}
    rows, numbers = csvfile.read_rows(path, COLUMNS, _parse, "uav", repairs)
    a = np.array(rows, float)
    a = a[csvfile.in_order(path, a[:, 0], numbers, MAX_BACKSTEP, "uav", repairs)]
    keep = csvfile.last_of_repeats(a[:, 0])
    if (~keep).any():
        csvfile.count(repairs, "uav_repeated_stamps", int((~keep).sum()))
        csvfile.say(path, f"{int((~keep).sum())} fix(es) repeat a time stamp: the last of each kept")
    a = a[keep]
    if len(a) < 2:
        raise WorkbenchError(f"malformed uav file {path}: fewer than two fixes")
    t = a[:, 0] - a[0, 0]
    gaps = np.diff(t)
    short = int(np.sum(gaps > SHORT_GAP))
    if short:
        csvfile.count(repairs, "uav_gaps", short)
        csvfile.say(path, f"{short} gap(s) over {SHORT_GAP:g} s between fixes (longest {gaps.max():.0f} s): "
                          "interpolated across")
    return UavLog(path, t, a[:, 1], a[:, 2], a[:, 3], repairs)


def positions(log: UavLog, times: np.ndarray) -> np.ndarray:
    """The flight's east/north position (m, about its centre) at ``times`` (s from its first fix)."""
    times = np.asarray(times, float)
    if times[0] < log.t[0] - 1e-9 or times[-1] > log.t[-1] + 1e-9:
        raise WorkbenchError(f"the UAV flight lasts {log.t[-1]:g} s; the run needs {times[0]:g}-{times[-1]:g} s "
                             "of it (lower --uav-start or --duration)")
    i0 = int(np.searchsorted(log.t, times[0], side="right")) - 1     # the fixes bracketing the stretch
    i1 = int(np.searchsorted(log.t, times[-1], side="left"))
    gaps = np.diff(log.t[max(i0, 0):i1 + 1])
    if gaps.size and gaps.max() > MAX_GAP:
        raise WorkbenchError(f"the UAV log has a {gaps.max():.0f} s gap inside the run's stretch "
                             f"({times[0]:g}-{times[-1]:g} s; over {MAX_GAP:g} s cannot be interpolated)")
    return PchipInterpolator(log.t, log.local, axis=0)(times)


def placed(log: UavLog, times: np.ndarray) -> np.ndarray:
    """The camera's path for a run: the flight at ``times`` translated to start at the origin
    (where the mast stands in the ais scenario's frame), ``(T, 2)``."""
    p = positions(log, times)
    return p - p[0]
