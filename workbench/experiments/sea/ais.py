"""A real ship from AIS reports as the target's true motion (``scenario ais``).

The Solent file (Stone Soup's test data) has columns Time, MMSI, Latitude_degrees,
Longitude_degrees, COG_degrees, SOG_knots. Positions go to a local east-north frame
(equirectangular about the segment's centre: under 1e-6 relative error over a few km),
then a shape-preserving cubic (PCHIP) puts them on the run's time step. The observer is a
stationary mast ``ais_range`` metres abeam of the segment's middle, looking at it.
"""

from __future__ import annotations

import csv
import functools
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from workbench.errors import WorkbenchError
from workbench.estimation.angles import wrap
from workbench.paths import data_file

DEFAULT_FILE = "ais/SolentAIS_20160112_130211.csv"
COLUMNS = ("Time", "MMSI", "Latitude_degrees", "Longitude_degrees", "COG_degrees", "SOG_knots")
EARTH_RADIUS = 6371008.8


@dataclass
class ShipTrack:
    """One ship's reports, sorted by time: seconds from the file's first report, degrees."""

    mmsi: int
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    cog: np.ndarray
    sog: np.ndarray


def load(path: Path | None) -> dict[int, ShipTrack]:
    """Read an AIS CSV into tracks by MMSI; a missing or malformed file is a WorkbenchError."""
    path = data_file(path, DEFAULT_FILE)
    rows: dict[int, list[tuple[float, float, float, float, float]]] = {}
    try:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
            if missing:
                raise WorkbenchError(f"malformed AIS file {path}: missing column(s) "
                                     f"{', '.join(missing)}")
            t0 = None
            for line, rec in enumerate(reader, start=2):
                try:
                    stamp = datetime.fromisoformat(rec["Time"]).timestamp()
                    t0 = stamp if t0 is None else t0
                    item = (stamp - t0, float(rec["Latitude_degrees"]),
                            float(rec["Longitude_degrees"]), float(rec["COG_degrees"]),
                            float(rec["SOG_knots"]))
                    rows.setdefault(int(rec["MMSI"]), []).append(item)
                except (TypeError, ValueError) as exc:
                    raise WorkbenchError(f"malformed AIS file {path}, line {line}: {exc}") from None
    except UnicodeDecodeError:
        raise WorkbenchError(f"malformed AIS file {path}: not text") from None
    if not rows:
        raise WorkbenchError(f"malformed AIS file {path}: no reports")
    tracks = {}
    for mmsi, items in rows.items():
        a = np.array(sorted(items))
        keep = np.concatenate([[True], np.diff(a[:, 0]) > 0])  # drop repeated time stamps
        a = a[keep]
        tracks[mmsi] = ShipTrack(mmsi, a[:, 0], a[:, 1], a[:, 2], a[:, 3], a[:, 4])
    return tracks


def to_local(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float) -> np.ndarray:
    """Latitude/longitude (deg) to east/north metres about ``(lat0, lon0)``."""
    east = np.deg2rad(lon - lon0) * EARTH_RADIUS * np.cos(np.deg2rad(lat0))
    north = np.deg2rad(lat - lat0) * EARTH_RADIUS
    return np.stack([east, north], axis=-1)


def best_segment(track: ShipTrack, duration: float) -> tuple[float, float]:
    """The segment start with the most turning, and that turning (rad), among moving stretches.

    Turning is the summed absolute change of course over ground between reports whose speed
    is at least 3 kn (course is noise when a ship is nearly still).
    """
    t = track.t
    if t[-1] - t[0] < duration:
        return float("nan"), -1.0
    moving = track.sog >= 3.0
    dcog = np.abs(wrap(np.diff(np.deg2rad(track.cog))))
    dcog[~(moving[1:] & moving[:-1])] = 0.0
    # windows that start at a report: sum of turning within [t_i, t_i + duration]
    cum = np.concatenate([[0.0], np.cumsum(dcog)])
    ends = np.searchsorted(t, t + duration, side="right") - 1
    valid = t + duration <= t[-1]
    slow = np.array([np.mean(moving[i:j + 1]) < 0.9 for i, j in enumerate(ends)])
    score = np.where(valid & ~slow, cum[ends] - cum[np.arange(len(t))], -1.0)
    i = int(np.argmax(score))
    return float(t[i]), float(score[i])


def default_mmsi(tracks: dict[int, ShipTrack], duration: float) -> int:
    """The ship whose best ``duration``-long segment turns the most (a long manoeuvring track)."""
    scored = [(best_segment(tr, duration)[1], mmsi) for mmsi, tr in tracks.items()]
    score, mmsi = max(scored)
    if score < 0:
        raise WorkbenchError(f"no ship in the AIS file moves for {duration:g} s")
    return mmsi


@functools.lru_cache(maxsize=4)
def ship_scenario(path: Path | None, mmsi: int | None, duration: float, dt: float,
                  standoff: float) -> dict:
    """Target truth and observer for ``scenario ais``, ready for :func:`scenario.simulate`.

    Cached: every run of a Monte Carlo set shares one ship, so the file is read once per
    process (the arrays are read-only by convention).
    """
    tracks = load(path)
    if mmsi is None:
        mmsi = default_mmsi(tracks, duration)
    if mmsi not in tracks:
        raise WorkbenchError(f"unknown MMSI {mmsi}: the AIS file has {len(tracks)} ships")
    track = tracks[mmsi]
    start, turning = best_segment(track, duration)
    if not np.isfinite(start):
        raise WorkbenchError(f"ship {mmsi} is tracked for {track.t[-1] - track.t[0]:.0f} s, "
                             f"less than --duration {duration:g} s")
    xy = to_local(track.lat, track.lon, float(np.mean(track.lat)), float(np.mean(track.lon)))
    steps = int(round(duration / dt)) + 1
    times = start + np.arange(steps) * dt
    interp = PchipInterpolator(track.t, xy, axis=0)
    pos = interp(times)
    vel = interp.derivative()(times)
    mid = pos[steps // 2]
    heading = pos[-1] - pos[0]
    normal = np.array([-heading[1], heading[0]]) / max(np.linalg.norm(heading), 1e-9)
    obs = mid + standoff * normal
    look = np.arctan2(*(mid - obs)[::-1])
    # shift the frame so the observer stands at the origin, as in the paper's scenario
    target = np.concatenate([pos - obs, vel], axis=1)
    return {"target": target, "observer": np.zeros((steps, 2)), "course": np.full(steps, look),
            "label": f"ais MMSI {mmsi}, t0 = {start:.0f} s, turning {np.rad2deg(turning):.0f} deg",
            "mmsi": mmsi}
