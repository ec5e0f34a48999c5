"""A real ship from AIS reports as the target's true motion (``scenario ais``).

The Solent file (Stone Soup's test data) has columns Time, MMSI, Latitude_degrees,
Longitude_degrees, COG_degrees, SOG_knots. Positions go to a local east-north frame
(equirectangular about the track's centre: under 1e-6 relative error over a few km),
then a shape-preserving cubic (PCHIP) puts them on the run's time step. The observer is a
stationary mast ``ais_range`` metres abeam of the segment's middle, looking at it, or (``observer
= "uav"``) the real UAV flight of :mod:`.uav` started from the mast's place.

Readings taken here:

* A ship is **usable** for a run of ``duration`` seconds if some stretch that long has no gap
  between its reports over ``max_gap`` seconds (default 200 s: AIS class A ships at anchor
  report every 3 minutes, under way every 2-10 s; across a longer silence the interpolation
  would invent the motion). Of the usable stretches the one that turns most is run (turning
  counted where the ship makes at least 3 kn); a ship that never moves runs its first one.
  A ship with no usable stretch is skipped with the reason (:func:`why_unusable`), never
  silently: ``--mmsi all`` lists them, ``--mmsi N`` refuses it in one line.
* Reading the file meets its quirks (:mod:`.csvfile`): reports stamped up to
  ``MAX_BACKSTEP`` s out of order are put back, repeated reports of one ship at one time keep
  the last (the real file has three exact duplicates), a last line cut short is left out; each
  is counted (``ais_*`` in the metrics' ``data_repairs``) and said in one warning line. AIS
  reports come irregularly by nature, so their gaps are not repairs but the usability rule.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from workbench.errors import WorkbenchError
from workbench.estimation.angles import wrap
from workbench.io import csvfiles as csvfile
from workbench.paths import data_file

DEFAULT_FILE = "ais/SolentAIS_20160112_130211.csv"
COLUMNS = ("Time", "MMSI", "Latitude_degrees", "Longitude_degrees", "COG_degrees", "SOG_knots")
MAX_BACKSTEP = 60.0
"""How far back (s) a report may be stamped behind the latest before it and still be put back in
order (a report relayed late); beyond it the file's time runs backwards and is refused."""
MAX_GAP = 200.0
"""The default longest silence (s) between a ship's reports inside a run (``--ais-max-gap``)."""


@dataclass
class ShipTrack:
    """One ship's reports, sorted by time: seconds from the file's first report, degrees."""

    mmsi: int
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    cog: np.ndarray
    sog: np.ndarray


@dataclass
class AisFile:
    """The tracks of an AIS file by MMSI, and what reading it repaired (see the module)."""

    path: Path
    tracks: dict[int, ShipTrack]
    repairs: dict[str, int] = field(default_factory=dict)


def read(path: Path | None) -> AisFile:
    """Read an AIS CSV (cached while the file is unchanged); bad files are a WorkbenchError."""
    path = data_file(path, DEFAULT_FILE)
    return _read(*csvfile.stamp(path))


def load(path: Path | None) -> dict[int, ShipTrack]:
    """The tracks of an AIS CSV by MMSI (:func:`read`'s)."""
    return read(path).tracks


NOT_AVAILABLE = (91.0, 181.0)
"""AIS's latitude and longitude for "not available" (ITU-R M.1371)."""


def _parse(rec: dict[str, str]) -> tuple:
    return (datetime.fromisoformat(rec["Time"].strip()).timestamp(), int(rec["MMSI"]),
            csvfile.degrees(rec["Latitude_degrees"], 90.0, "latitude", NOT_AVAILABLE[0]),
            csvfile.degrees(rec["Longitude_degrees"], 180.0, "longitude", NOT_AVAILABLE[1]),
            csvfile.finite(rec["COG_degrees"]), csvfile.finite(rec["SOG_knots"]))


@functools.lru_cache(maxsize=4)
def _read(name: str, mtime: int, size: int) -> AisFile:
    path = Path(name)
    repairs: dict[str, int] = {}
    rows, numbers = csvfile.read_rows(path, COLUMNS, _parse, "ais", repairs)
    a = np.array([r[2:] for r in rows], float)
    t = np.array([r[0] for r in rows], float)
    ids = np.array([r[1] for r in rows], np.int64)
    blind = np.isnan(a[:, 0]) | np.isnan(a[:, 1])
    if blind.any():  # AIS's "position not available" (latitude 91, longitude 181)
        csvfile.count(repairs, "ais_no_position", int(blind.sum()))
        csvfile.say(path, f"{int(blind.sum())} report(s) say their position is not available (91 / 181): left out")
        a, t, ids = a[~blind], t[~blind], ids[~blind]
        numbers = [n for n, b in zip(numbers, blind, strict=True) if not b]
        if not len(t):
            raise WorkbenchError(f"malformed ais file {path}: no report has a position")
    order = csvfile.in_order(path, t, numbers, MAX_BACKSTEP, "ais", repairs)
    t, ids, a = t[order] - t.min(), ids[order], a[order]
    by = np.lexsort((t, ids))                      # by ship, then time (stable: file order in a repeat)
    t, ids, a = t[by], ids[by], a[by]
    keep = csvfile.last_of_repeats(np.stack([ids.astype(float), t], axis=1))
    dropped = int((~keep).sum())
    if dropped:
        csvfile.count(repairs, "ais_repeated_stamps", dropped)
        csvfile.say(path, f"{dropped} report(s) repeat a ship's time stamp: the last of each kept")
    t, ids, a = t[keep], ids[keep], a[keep]
    tracks = {}
    for mmsi in np.unique(ids):
        m = ids == mmsi
        tracks[int(mmsi)] = ShipTrack(int(mmsi), t[m], a[m, 0], a[m, 1], a[m, 2], a[m, 3])
    return AisFile(path, tracks, repairs)


def usable(track: ShipTrack, duration: float, max_gap: float = MAX_GAP) -> np.ndarray:
    """Per report: a ``duration``-long stretch starting there ends within the track and has no
    gap between reports over ``max_gap`` (counting the gap to the first report after its end)."""
    t = track.t
    if len(t) < 2:
        return np.zeros(len(t), bool)
    big = np.concatenate([[0], np.cumsum(np.diff(t) > max_gap)])   # big gaps before report i
    ends = np.minimum(np.searchsorted(t, t + duration, side="left"), len(t) - 1)
    return (t + duration <= t[-1]) & (big[ends] == big)


def why_unusable(track: ShipTrack, duration: float, max_gap: float = MAX_GAP) -> str | None:
    """Why the ship cannot be run for ``duration`` seconds (None if it can)."""
    t = track.t
    if len(t) < 2:
        return "a single report"
    span = t[-1] - t[0]
    if span < duration:
        return f"tracked for {span:.0f} s, less than the run's {duration:g} s"
    if not usable(track, duration, max_gap).any():
        return (f"no {duration:g} s stretch without a gap over {max_gap:g} s between reports "
                f"(longest gap {np.diff(t).max():.0f} s)")
    return None


def best_segment(track: ShipTrack, duration: float, max_gap: float = MAX_GAP) -> tuple[float, float]:
    """The usable segment start with the most turning, and that turning (rad); ``(nan, -1)`` if
    none is usable; turning -1 where the ship moves under 3 kn for over a tenth of the stretch.

    Turning is the summed absolute change of course over ground between reports whose speed
    is at least 3 kn (course is noise when a ship is nearly still).
    """
    t = track.t
    ok = usable(track, duration, max_gap)
    if not ok.any():
        return float("nan"), -1.0
    moving = track.sog >= 3.0
    dcog = np.abs(wrap(np.diff(np.deg2rad(track.cog))))
    dcog[~(moving[1:] & moving[:-1])] = 0.0
    # windows that start at a report: sum of turning within [t_i, t_i + duration]
    cum = np.concatenate([[0.0], np.cumsum(dcog)])
    ends = np.searchsorted(t, t + duration, side="right") - 1
    slow = np.array([np.mean(moving[i:j + 1]) < 0.9 for i, j in enumerate(ends)])
    score = np.where(ok & ~slow, cum[ends] - cum[np.arange(len(t))], -1.0)
    score = np.where(ok, score, -2.0)
    i = int(np.argmax(score))
    return float(t[i]), float(max(score[i], -1.0))


def default_mmsi(tracks: dict[int, ShipTrack], duration: float, max_gap: float = MAX_GAP) -> int:
    """The ship whose best ``duration``-long segment turns the most (a long manoeuvring track)."""
    scored = [(best_segment(tr, duration, max_gap)[1], mmsi) for mmsi, tr in tracks.items()]
    score, mmsi = max(scored)
    if score < 0:
        raise WorkbenchError(f"no ship in the AIS file moves for {duration:g} s")
    return mmsi


def ship_set(path: Path | None, duration: float, max_gap: float = MAX_GAP) -> tuple[list[int], dict[int, str]]:
    """The ships that can be run for ``duration`` seconds (by MMSI) and the others with the reason."""
    tracks = load(path)
    ships, skipped = [], {}
    for mmsi in sorted(tracks):
        why = why_unusable(tracks[mmsi], duration, max_gap)
        if why is None:
            ships.append(mmsi)
        else:
            skipped[mmsi] = why
    return ships, skipped


def ship_scenario(path: Path | None, mmsi: int | None, duration: float, dt: float, standoff: float,
                  max_gap: float = MAX_GAP) -> dict:
    """Target truth and observer (the mast) for ``scenario ais``, ready for :func:`scenario.simulate`;
    ``--observer uav`` puts the UAV's path in its place (:func:`.run.make_data`, :mod:`.uav`).

    Cached while the file is unchanged: every run of a Monte Carlo set shares one ship, so
    the file is read once per process (the arrays are read-only by convention).
    """
    path = data_file(path, DEFAULT_FILE)
    return _ship_scenario(csvfile.stamp(path), mmsi, duration, dt, standoff, max_gap)


@functools.lru_cache(maxsize=8)
def _ship_scenario(file: tuple, mmsi: int | None, duration: float, dt: float, standoff: float,
                   max_gap: float) -> dict:
    ais = _read(*file)
    tracks = ais.tracks
    if mmsi is None:
        mmsi = default_mmsi(tracks, duration, max_gap)
    if mmsi not in tracks:
        raise WorkbenchError(f"unknown MMSI {mmsi}: the AIS file has {len(tracks)} ships")
    track = tracks[mmsi]
    why = why_unusable(track, duration, max_gap)
    if why is not None:
        raise WorkbenchError(f"ship {mmsi} cannot be run for --duration {duration:g} s: {why}")
    start, turning = best_segment(track, duration, max_gap)
    xy = csvfile.to_local(track.lat, track.lon, float(np.mean(track.lat)), float(np.mean(track.lon)))
    steps = int(round(duration / dt)) + 1
    times = start + np.arange(steps) * dt
    interp = PchipInterpolator(track.t, xy, axis=0)
    pos = interp(times)
    vel = interp.derivative()(times)
    mid = pos[steps // 2]
    heading = pos[-1] - pos[0]
    if np.linalg.norm(heading) < 1e-6:   # a ship that does not move at all: stand north of it
        heading = np.array([1.0, 0.0])
    normal = np.array([-heading[1], heading[0]]) / np.linalg.norm(heading)
    obs = mid + standoff * normal
    look = np.arctan2(*(mid - obs)[::-1])
    label = f"ais MMSI {mmsi}, t0 = {start:.0f} s, turning {np.rad2deg(max(turning, 0.0)):.0f} deg"
    repairs = dict(ais.repairs)
    observer_path = np.zeros((steps, 2))
    # shift the frame so the mast (the UAV's start) stands at the origin, as in the paper's scenario
    target = np.concatenate([pos - obs, vel], axis=1)
    return {"target": target, "observer": observer_path, "course": np.full(steps, look), "label": label,
            "mmsi": mmsi, "repairs": repairs}
