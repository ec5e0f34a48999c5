"""Data association without simulation ids: image bearings to landmarks through the filter.

``spec/omni.md`` (Images): associate bearings to landmarks by the filter's predicted bearings
with a chi-square gate. The front end runs the cloned-pose EKF (:mod:`ekf`) over the
detections; at every epoch

1. each initialised landmark's predicted bearing (9) and innovation variance
   ``S = H P H' + R`` give a Mahalanobis cost to every detection; the assignment (Hungarian,
   ``scipy.optimize.linear_sum_assignment``) inside the ``nis_gate`` quantile of chi2(1)
   (0.99 when the config has none) becomes the update, but only where it is unambiguous
   (one detection in the line's gate, the detection in one gate); ambiguous detections are
   not used at all (a wrong pairing costs a filter far more than a missed one);
2. the rest go to pending lines (seen, not initialised). A pending line's range is unknown,
   so its last ray, seen from the current pose, predicts an interval of bearings (from a
   line 1 m away to one at infinity); a detection's cost is its distance outside that
   interval, and matches within ``track_gate`` (3 sigma + 0.5 deg) feed the landmark
   initialiser (1)-(5);
3. what is left starts a new pending line.

Every detection thus gets a track id. The tracks then stand for landmarks: every estimator
runs on the same associated bearings. For scoring only, each track is given the true
landmark that most of its detections came from (its "majority" landmark).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from workbench.estimation.angles import wrap
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni import ekf
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData

BIG = 1e9


@dataclass
class Association:
    """Track id per detection (``-1``: none), how it was made (``kind``: 0 a mapped line's
    gate, 1 a pending line's ray, 2 a new line), and the number of tracks."""

    track: np.ndarray
    kind: np.ndarray
    n_tracks: int


def associate(data: OmniData, cfg: OmniConfig, track_gate: float | None = None) -> Association:
    """Run the association front end over ``data``'s bearings (their ``meas_lm`` is ignored)."""
    m = len(data.meas_bearing)
    if track_gate is None:
        track_gate = 3.0 * data.sigma_bearing + math.radians(0.5)
    shell = replace(data, landmarks=np.zeros((max(m, 1), 2)), landmark_ids=np.arange(max(m, 1)))
    f = ekf.BearingEkf(shell, cfg, "clone")
    p_gate = cfg.nis_gate if cfg.nis_gate > 0 else 0.99
    gate = chi2_quantile(p_gate, 1)
    track = np.full(m, -1)
    kind = np.full(m, -1)
    n_tracks = 0
    last_seen: dict[int, tuple[float, np.ndarray]] = {}  # pending line -> (bearing, pose) when last seen
    dt = data.dt
    last = 0
    for step, idx in data.epochs():
        if step > last:
            f.predict(data.controls[last:step], dt[last:step])
            last = step
        b = data.meas_bearing[idx]
        free = np.ones(len(idx), bool)
        mapped = np.flatnonzero(f.slot >= 0)
        if len(mapped):
            cost = _mahalanobis(f, mapped, b)
            inside = cost < gate
            rows, cols = linear_sum_assignment(np.where(inside, cost, BIG))
            # only unambiguous pairs: the detection in no other line's gate, no other
            # detection in this line's gate; ambiguous detections are left out altogether
            ok = inside[rows, cols] & (inside[rows].sum(axis=1) == 1) & (inside[:, cols].sum(axis=0) == 1)
            free[np.flatnonzero(inside.sum(axis=1) > 1)] = False
            free[np.flatnonzero(inside[:, cols[~ok]].any(axis=1))] = False
            rows, cols = rows[ok], cols[ok]
            if len(rows):
                track[idx[rows]] = mapped[cols]
                kind[idx[rows]] = 0
                free[rows] = False
                f.update(mapped[cols], b[rows])
        pending = list(f.pending)
        rest = np.flatnonzero(free)
        if pending and len(rest):
            cost = np.stack([_ray_distance(last_seen[p], f.x[:3], b[rest]) for p in pending], axis=1)
            rows, cols = linear_sum_assignment(np.where(cost < track_gate, cost, BIG))
            ok = cost[rows, cols] < track_gate
            for r, c in zip(rows[ok], cols[ok], strict=True):
                lm, det = pending[c], rest[r]
                track[idx[det]] = lm
                kind[idx[det]] = 1
                free[det] = False
                last_seen[lm] = (float(b[det]), f.x[:3].copy())
                f.try_initialise(lm, float(b[det]), step)
        for det in np.flatnonzero(free):
            lm = n_tracks
            n_tracks += 1
            track[idx[det]] = lm
            kind[idx[det]] = 2
            f.first_seen[lm] = step
            f.start(lm, float(b[det]), step)
            last_seen[lm] = (float(b[det]), f.x[:3].copy())
        now = data.t[step]
        for lm in [k for k, s in f.pending.items() if now - data.t[s["last"]] > cfg.drop_after]:
            f.drop(lm)
    return Association(track, kind, n_tracks)


RANGES = np.array([1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 64.0, 1e6])


def _ray_distance(seen: tuple[float, np.ndarray], pose: np.ndarray, bearings: np.ndarray) -> np.ndarray:
    """How far (rad) each bearing lies outside the bearings a line on the last ray can have now."""
    b0, p0 = seen
    a = p0[2] + b0
    pts = p0[:2] + RANGES[:, None] * np.array([math.cos(a), math.sin(a)])
    pred = np.arctan2(pts[:, 1] - pose[1], pts[:, 0] - pose[0]) - pose[2]
    far = pred[-1]
    rel = wrap(pred - far)
    lo, hi = rel.min(), rel.max()
    d = wrap(bearings - far)
    return np.where(d < lo, lo - d, np.where(d > hi, d - hi, 0.0))


def _mahalanobis(f: ekf.BearingEkf, lms: np.ndarray, bearings: np.ndarray) -> np.ndarray:
    """``nu^2 / S`` for every (detection, landmark) pair, ``(len(bearings), len(lms))``."""
    off = f.slot[lms]
    x = f.x
    dx, dy = x[off] - x[0], x[off + 1] - x[1]
    q = dx * dx + dy * dy
    pred = np.arctan2(dy, dx) - x[2]
    n = len(x)
    H = np.zeros((len(lms), n))
    rows = np.arange(len(lms))
    H[rows, 0], H[rows, 1], H[rows, 2] = dy / q, -dx / q, -1.0
    H[rows, off], H[rows, off + 1] = -dy / q, dx / q
    S = np.einsum("ij,jk,ik->i", H, f.P, H) + f.r
    nu = wrap(bearings[:, None] - pred[None, :])
    return nu**2 / S[None, :]


def majority(track: np.ndarray, true_lm: np.ndarray, n_tracks: int) -> np.ndarray:
    """For scoring: the true landmark most of each track's detections came from (-1: none)."""
    out = np.full(n_tracks, -1)
    ok = (track >= 0) & (true_lm >= 0)
    for t in range(n_tracks):
        ids = true_lm[ok & (track == t)]
        if len(ids):
            out[t] = np.bincount(ids).argmax()
    return out
