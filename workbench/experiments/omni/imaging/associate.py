"""Data association without simulation ids: image bearings to landmarks through the filter.

``spec/omni.md`` (Images): associate bearings to landmarks by the filter's predicted bearings
with a chi-square gate. The front end runs the cloned-pose EKF (:mod:`ekf`) over the
detections and manages tracks: a detection starts a *tentative* track, which becomes a
landmark (is *confirmed*) only when the initialiser (1)-(5) accepts it and it is then seen
where the filter predicts it, and which is otherwise merged into a landmark it agrees with
or rejected. At every epoch

1. **mapped lines.** Each landmark's predicted bearing (9) and innovation variance
   ``S = H P H' + R`` give a Mahalanobis cost ``nu^2 / S`` to every detection, gated at the
   ``nis_gate`` quantile of chi2(1) (0.99 when the config has none). Pairs that are
   unambiguous (the detection in this one gate, no other detection in it) update the filter
   at once, and the rest are gated again with the updated covariance (sequential gating:
   the first updates pin the heading that all predictions share, and the gates shrink).
   A detection still inside several gates, with no other detection in them, is where the
   lines are predicted to overlap in the image (a near line hides a far one behind it: the
   extractor sees one line); it goes to the nearest of them. Other ambiguous detections
   are not used (a wrong pairing costs a filter far more than a missed one);
2. **tentative tracks.** A pending line's range is unknown, so its last ray, seen from the
   current pose, predicts an interval of bearings (from a line 1 m away to one at
   infinity); a detection's cost is its distance outside that interval, and matches within
   ``track_gate`` (3 sigma + 0.5 deg) feed the landmark initialiser (1)-(5). The landmark it
   proposes must also fit all the track's rays (the rays' test below; two lines' rays can
   meet at a point that fits neither, e.g. on the route). It then enters the filter;
   **merging**: whenever two mapped landmarks pass the 2-dof chi-square test of their
   difference over the filter's joint covariance, ``d' (P_aa + P_bb - P_ab - P_ba)^-1 d``, at
   the same probability, the younger is merged into the older: the filter is conditioned on
   their equality and the younger marginalised out. This catches a line triangulated anew
   next to its own landmark, at once or later: after a loop the drifted pose can put a line
   outside its landmark's gate, and only once other lines have corrected the pose do the
   two agree;
3. what is left starts a new tentative track;
4. **confirmation** (M-of-N): a landmark new in the filter is *provisional*; each later epoch
   it is predicted inside the camera's range and field of view counts a hit if a detection
   went to it, a miss if none did. ``CONFIRM_M`` hits of ``CONFIRM_N`` confirm it; more misses
   take it out of the filter (marginalised) and retire its track (a phantom: nothing is
   seen where it should be);
5. **retiring.** A tentative track unseen for ``drop_after`` seconds leaves the filter. Its
   rays (pose estimate and covariance at each sighting, bearing) are tested against every
   landmark: the summed ``nu_k^2 / S_k`` with ``S_k = H_k diag(P_pose,k, P_LL) H_k' + R`` below
   the chi2(n) quantile. A track whose rays agree with exactly one landmark is merged into
   it; the others wait, and are tested again against every landmark confirmed later (a line
   glimpsed at the start, out of range before it could be triangulated, and confirmed on
   the next lap). What is never confirmed nor merged is rejected: its detections get no
   track.

The confirmed tracks then stand for landmarks: every estimator runs on the same associated
bearings. For scoring only, each track is given the true landmark that most of its
detections came from (its "majority" landmark).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import partial

import numpy as np
from scipy.optimize import linear_sum_assignment

from workbench.estimation.angles import wrap
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms import ekf
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.scenario import OmniData

BIG = 1e9
MAPPED, PENDING, NEW = 0, 1, 2  # how a detection got its track (``Association.kind``)
# M-of-N confirmation of a new landmark: the common 3-of-5 track-confirmation logic (M/N
# logic, e.g. Blackman & Popoli, Design and Analysis of Modern Tracking Systems, 1999); a line
# detected with probability 0.9 passes with probability 0.99, a phantom seen one epoch in five
# with 0.06 (binomial tails)
CONFIRM_M, CONFIRM_N = 3, 5


@dataclass
class Association:
    """Track id per detection (``-1``: none), how it was made (``kind``: 0 a mapped line's
    gate, 1 a pending line's ray, 2 a new line), the number of (confirmed) tracks, and how
    many tentative tracks were merged into a landmark or rejected."""

    track: np.ndarray
    kind: np.ndarray
    n_tracks: int
    merged: int = 0
    rejected: int = 0


@dataclass
class Ray:
    """One sighting of a tentative track: the filter's pose and its covariance then, the bearing."""

    pose: np.ndarray
    cov: np.ndarray
    bearing: float


@dataclass
class Tracks:
    """The front end's bookkeeping: the track of every detection and each tentative track's rays."""

    track: np.ndarray
    kind: np.ndarray
    rays: dict[int, list[Ray]] = field(default_factory=dict)
    retired: list[int] = field(default_factory=list)
    confirmed: set[int] = field(default_factory=set)
    provisional: dict[int, list[int]] = field(default_factory=dict)  # landmark -> [hits, misses]
    born: int = 0
    merged: int = 0

    def relabel(self, old: int, new: int) -> None:
        """``old``'s detections become ``new``'s (a merge)."""
        self.track[self.track == old] = new
        self.rays.pop(old, None)
        self.merged += 1


def associate(data: OmniData, cfg: OmniConfig, track_gate: float | None = None) -> Association:
    """Run the association front end over ``data``'s bearings (their ``meas_lm`` is ignored)."""
    m = len(data.meas_bearing)
    if track_gate is None:
        track_gate = 3.0 * data.sigma_bearing + math.radians(0.5)
    shell = replace(data, landmarks=np.zeros((max(m, 1), 2)), landmark_ids=np.arange(max(m, 1)))
    f = ekf.BearingEkf(shell, cfg, "clone")
    p_gate = cfg.nis_gate if cfg.nis_gate > 0 else 0.99
    gate = chi2_quantile(p_gate, 1)
    tr = Tracks(np.full(m, -1), np.full(m, -1))
    last_seen: dict[int, tuple[float, np.ndarray]] = {}  # pending line -> (bearing, pose) when last seen
    last = 0
    for step, idx in data.epochs():
        if step > last:
            f.predict(last, step)
            last = step
        b = data.meas_bearing[idx]
        free = _match_mapped(f, tr, idx, b, gate)
        free = _match_pending(f, tr, idx, b, free, last_seen, track_gate, step, p_gate)
        _merge_duplicates(f, tr, p_gate)
        for det in np.flatnonzero(free):  # step 3
            lm = tr.born
            tr.born += 1
            _sighting(f, tr, lm, idx[det], float(b[det]), NEW)
            f.first_seen[lm] = step
            f.start(lm, float(b[det]), step)
            last_seen[lm] = (float(b[det]), f.x[:3].copy())
        _score_provisional(f, tr, idx, data.max_range, data.fov, p_gate)
        now = data.t[step]
        for lm in [k for k, s in f.pending.items() if now - data.t[s["last"]] > cfg.drop_after]:
            f.drop(lm)
            _retire(f, tr, lm, p_gate)
    for lm in list(f.pending):
        f.drop(lm)
        _retire(f, tr, lm, p_gate)
    for lm in list(tr.provisional):  # not confirmed by the end
        del tr.provisional[lm]
        f.forget(lm)
        _retire(f, tr, lm, p_gate)
    return _result(tr)


def _sighting(f: ekf.BearingEkf, tr: Tracks, lm: int, det: int, bearing: float, kind: int) -> None:
    """Give detection ``det`` to tentative track ``lm`` and keep its ray."""
    tr.track[det], tr.kind[det] = lm, kind
    tr.rays.setdefault(lm, []).append(Ray(f.x[:3].copy(), f.P[:3, :3].copy(), bearing))


def _match_mapped(f: ekf.BearingEkf, tr: Tracks, idx: np.ndarray, b: np.ndarray, gate: float) -> np.ndarray:
    """Step 1: detections to mapped lines by sequential chi-square gating, the filter updated
    as pairs are made; returns which detections are left free (in no line's gate)."""
    free = np.ones(len(idx), bool)
    todo = np.arange(len(idx))
    used = np.zeros(0, int)
    inside = np.zeros((0, 0), bool)
    lms = used
    while len(todo):
        lms = np.setdiff1d(np.flatnonzero(f.slot >= 0), used)
        if not len(lms):
            return free
        inside = _mahalanobis(f, lms, b[todo]) < gate
        pair = inside & (inside.sum(axis=1, keepdims=True) == 1) & (inside.sum(axis=0, keepdims=True) == 1)
        rows, cols = np.nonzero(pair)
        if not len(rows):
            break
        _assign_mapped(f, tr, idx[todo[rows]], lms[cols], b[todo[rows]])
        free[todo[rows]] = False
        used = np.concatenate([used, lms[cols]])
        todo = np.delete(todo, rows)
    if not len(todo):
        return free
    free[todo[inside.any(axis=1)]] = False
    rows, cols = _overlapping(f, lms, inside)
    if len(rows):
        _assign_mapped(f, tr, idx[todo[rows]], lms[cols], b[todo[rows]])
    return free


def _match_pending(f: ekf.BearingEkf, tr: Tracks, idx: np.ndarray, b: np.ndarray, free: np.ndarray,
                   last_seen: dict[int, tuple[float, np.ndarray]], track_gate: float, step: int,
                   p: float) -> np.ndarray:
    """Step 2: free detections to pending lines by their last rays (Hungarian within
    ``track_gate``), each match tried with the initialiser (1)-(5) and the rays' fit to the
    triangulated point; returns which detections are still free."""
    pending = list(f.pending)
    rest = np.flatnonzero(free)
    if not pending or not len(rest):
        return free
    free = free.copy()
    cost = np.stack([_ray_distance(last_seen[lm], f.x[:3], b[rest]) for lm in pending], axis=1)
    rows, cols = linear_sum_assignment(np.where(cost < track_gate, cost, BIG))
    ok = cost[rows, cols] < track_gate
    for r, c in zip(rows[ok], cols[ok], strict=True):
        lm, det = pending[c], rest[r]
        _sighting(f, tr, lm, idx[det], float(b[det]), PENDING)
        free[det] = False
        last_seen[lm] = (float(b[det]), f.x[:3].copy())
        if f.try_initialise(lm, float(b[det]), step, partial(_rays_fit, tr.rays[lm], r=f.r, p=p)):
            _confirm(f, tr, lm)
    return free


def _assign_mapped(f: ekf.BearingEkf, tr: Tracks, dets: np.ndarray, lms: np.ndarray, bearings: np.ndarray) -> None:
    tr.track[dets], tr.kind[dets] = lms, MAPPED
    f.update(lms, bearings)


def _overlapping(f: ekf.BearingEkf, lms: np.ndarray, inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Detections inside several gates whose lines have no other detection in their gates:
    the lines overlap in the image, and the nearest of them (by the filter's estimate) hides
    the others. Returns (detection rows, landmark columns)."""
    rows, cols = [], []
    taken: set[int] = set()
    for r in np.flatnonzero(inside.sum(axis=1) > 1):
        cand = np.flatnonzero(inside[r])
        if inside[:, cand].sum() != len(cand) or taken & set(cand.tolist()):
            continue  # another detection shares a gate: a real ambiguity
        off = f.slot[lms[cand]]
        rng = np.hypot(f.x[off] - f.x[0], f.x[off + 1] - f.x[1])
        c = int(cand[np.argmin(rng)])
        rows.append(int(r))
        cols.append(c)
        taken.update(cand.tolist())
    return np.array(rows, int), np.array(cols, int)


def _confirm(f: ekf.BearingEkf, tr: Tracks, lm: int) -> None:
    """Step 2's end: a landmark the initialiser accepted becomes provisional (step 4)."""
    tr.provisional[lm] = [-1, 0]  # its own sighting this epoch (scored as a hit) is not evidence


def _merge_duplicates(f: ekf.BearingEkf, tr: Tracks, p: float) -> None:
    """Step 2b: while two mapped landmarks pass the 2-dof test of being one, the younger track
    is merged into the older (the filter conditioned on their equality, the younger
    marginalised out, its detections relabelled; a confirmed one confirms the other)."""
    while (pair := _most_alike(f, p)) is not None:
        keep, drop = pair
        f.merge(keep, drop)
        tr.relabel(drop, keep)
        was_confirmed = drop in tr.confirmed
        tr.confirmed.discard(drop)
        tr.provisional.pop(drop, None)
        if was_confirmed and keep in tr.provisional:
            del tr.provisional[keep]
            _confirmed(f, tr, keep, p)


def _most_alike(f: ekf.BearingEkf, p: float) -> tuple[int, int] | None:
    """The pair of mapped landmarks (older, younger) most likely one line by the 2-dof
    chi-square test of their difference ``d = x_a - x_b`` over the joint covariance,
    ``d' (P_aa + P_bb - P_ab - P_ba)^-1 d < chi2_2(p)``; ``None`` if no pair passes."""
    lms = np.flatnonzero(f.slot >= 0)
    if len(lms) < 2:
        return None
    i, j = np.triu_indices(len(lms), 1)
    a, b = f.slot[lms[i]], f.slot[lms[j]]
    d2 = _difference_nis(f, a, b)
    best = int(np.argmin(d2))
    if not d2[best] < chi2_quantile(p, 2):
        return None
    return int(lms[i[best]]), int(lms[j[best]])


def _difference_nis(f: ekf.BearingEkf, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``d' C^-1 d`` for ``d = x_a - x_b``, ``C = P_aa + P_bb - P_ab - P_ba``, for state offsets
    ``a``, ``b`` (arrays of landmarks' first rows); ``inf`` where ``C`` is singular."""
    x, P = f.x, f.P
    d = np.stack([x[a] - x[b], x[a + 1] - x[b + 1]], axis=1)
    ra, rb = np.stack([a, a + 1], axis=1), np.stack([b, b + 1], axis=1)

    def block(r: np.ndarray, c: np.ndarray) -> np.ndarray:
        return P[r[:, :, None], c[:, None, :]]

    C = block(ra, ra) + block(rb, rb) - block(ra, rb) - block(rb, ra)
    det = C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] * C[:, 1, 0]
    quad = C[:, 1, 1] * d[:, 0] ** 2 - (C[:, 0, 1] + C[:, 1, 0]) * d[:, 0] * d[:, 1] + C[:, 0, 0] * d[:, 1] ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det > 0, quad / det, np.inf)


def _score_provisional(f: ekf.BearingEkf, tr: Tracks, idx: np.ndarray, max_range: float, fov: float,
                       p: float) -> None:
    """Step 4, M-of-N confirmation: each epoch a provisional landmark is predicted in view, a
    detection associated with it is a hit, none a miss; ``CONFIRM_M`` hits confirm it, more than
    ``CONFIRM_N - CONFIRM_M`` misses take it out of the map and retire its track."""
    for lm, score in list(tr.provisional.items()):
        if not _in_view(f, lm, max_range, fov):
            continue
        score[0 if np.any(tr.track[idx] == lm) else 1] += 1
        if score[0] >= CONFIRM_M:
            del tr.provisional[lm]
            _confirmed(f, tr, lm, p)
        elif score[1] > CONFIRM_N - CONFIRM_M:
            del tr.provisional[lm]
            f.forget(lm)
            _retire(f, tr, lm, p)


def _in_view(f: ekf.BearingEkf, lm: int, max_range: float, fov: float) -> bool:
    """Is mapped landmark ``lm`` predicted inside the camera's range and field of view?"""
    (x, y), pose = _landmark(f, lm)[0], f.x[:3]
    dx, dy = x - pose[0], y - pose[1]
    return bool(math.hypot(dx, dy) <= max_range and abs(wrap(math.atan2(dy, dx) - pose[2])) <= fov / 2)


def _confirmed(f: ekf.BearingEkf, tr: Tracks, lm: int, p: float) -> None:
    """A landmark passed M-of-N: its track is kept; retired tracks whose rays now agree with it
    alone join it."""
    tr.confirmed.add(lm)
    tr.rays.pop(lm, None)
    for old in list(tr.retired):
        if _agreeing(f, tr.rays[old], p) == lm:
            tr.relabel(old, lm)
            tr.retired.remove(old)


def _retire(f: ekf.BearingEkf, tr: Tracks, lm: int, p: float) -> None:
    """Step 5: a tentative track left the filter: merged into the one landmark its rays agree
    with, or kept aside for landmarks confirmed later."""
    target = _agreeing(f, tr.rays[lm], p)
    if target >= 0:
        tr.relabel(lm, target)
    else:
        tr.retired.append(lm)


def _landmark(f: ekf.BearingEkf, lm: int) -> tuple[np.ndarray, np.ndarray]:
    """A mapped landmark's mean and covariance in the filter."""
    o = int(f.slot[lm])
    return f.x[o:o + 2], f.P[o:o + 2, o:o + 2]


def _agreeing(f: ekf.BearingEkf, rays: list[Ray], p: float) -> int:
    """The one mapped landmark all ``rays`` agree with (-1: none, or more than one)."""
    lms = np.flatnonzero(f.slot >= 0)
    if not len(lms) or not rays:
        return -1
    ok = [lm for lm in lms if _rays_fit(rays, *_landmark(f, int(lm)), f.r, p)]
    return int(ok[0]) if len(ok) == 1 else -1


def rays_nis(rays: list[Ray], xl: np.ndarray, pl: np.ndarray, r: float) -> float:
    """Summed ``nu_k^2 / S_k`` of ``rays`` against a landmark at ``xl`` with covariance ``pl``:
    the bearing (9) each pose would have seen it at, ``S_k = H_k diag(P_pose,k, P_LL) H_k' + R``
    (the sighting's pose and the landmark taken as independent). chi2(len(rays)) if the rays
    saw that landmark."""
    pose = np.array([ray.pose for ray in rays])
    cov = np.array([ray.cov for ray in rays])
    dx, dy = xl[0] - pose[:, 0], xl[1] - pose[:, 1]
    q = dx * dx + dy * dy
    hp = np.stack([dy / q, -dx / q, -np.ones_like(q)], axis=1)
    hl = np.stack([-dy / q, dx / q], axis=1)
    s = np.einsum("ki,kij,kj->k", hp, cov, hp) + np.einsum("ki,ij,kj->k", hl, pl, hl) + r
    nu = wrap(np.array([ray.bearing for ray in rays]) - (np.arctan2(dy, dx) - pose[:, 2]))
    return float(np.sum(nu * nu / s))


def _rays_fit(rays: list[Ray], xl: np.ndarray, pl: np.ndarray, r: float, p: float) -> bool:
    """Do all of a track's rays agree with a landmark at ``xl`` (covariance ``pl``)?"""
    return rays_nis(rays, xl, pl, r) < chi2_quantile(p, len(rays))


def _result(tr: Tracks) -> Association:
    """Confirmed tracks renumbered 0.. in the order they were born; the rest get none (-1)."""
    keep = sorted(tr.confirmed)
    new_id = np.full(max(tr.born, 1), -1)
    new_id[keep] = np.arange(len(keep))
    track = np.where(tr.track >= 0, new_id[np.maximum(tr.track, 0)], -1)
    kind = np.where(track >= 0, tr.kind, -1)
    return Association(track, kind, len(keep), tr.merged, len(tr.retired))


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
    """``nu^2 / S`` for every (detection, landmark) pair, ``(len(bearings), len(lms))``.

    ``S = H P H' + R`` with the bearing's Jacobian (9) ``H`` nonzero only on the pose and the
    landmark: each ``S`` is a 5 x 5 block of ``P`` (pose, landmark) between two 5-vectors."""
    off = f.slot[lms]
    x = f.x
    dx, dy = x[off] - x[0], x[off + 1] - x[1]
    q = dx * dx + dy * dy
    pred = np.arctan2(dy, dx) - x[2]
    J = np.stack([dy / q, -dx / q, -np.ones_like(q), -dy / q, dx / q], axis=1)  # (k, 5)
    at = np.concatenate([np.broadcast_to([0, 1, 2], (len(off), 3)), np.stack([off, off + 1], axis=1)], axis=1)
    block = f.P[at[:, :, None], at[:, None, :]]  # (k, 5, 5)
    S = np.einsum("ki,kij,kj->k", J, block, J) + f.r
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
