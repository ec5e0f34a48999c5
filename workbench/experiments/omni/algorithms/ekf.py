"""Bearing-only EKF-SLAM (6)-(15) with the UT-gated landmark initialisation (1)-(5).

State ``[x_r, y_r, phi_r, x_L1, y_L1, ...]`` (6), plus (in the ``clone`` augmentation) a
copy of the vehicle pose per pending landmark. Prediction (7)-(8) touches only the pose
rows: between two bearing epochs the pose block is propagated step by step and the
cross-covariances once with the product of the F_R (:meth:`Motion.propagate`). The update
(9)-(13) processes an epoch's bearings together, ``P+ = P- - K S K'`` symmetrised.

Augmentation (14)-(15), two readings (``spec/omni.md``):

* ``paper`` (``ekf-paper``): the nearest runnable reading of (15). The UT of (2)-(5) runs on
  the diagonal covariance (3) (the first sighting's pose variances, stored then; the
  current pose's variances; the two bearing variances). The cross-covariance block that (15)
  writes ``F_R P_rr``, ``F_R P_rl`` (its dimensions do not fit a 2-D landmark) becomes
  ``G_j [P_rr P_rl]`` with ``G_j`` the triangulation's Jacobian with respect to the current
  pose; the first sighting's pose and its correlations are lost.
* ``clone`` (``ekf``): when a line is first seen the current pose is cloned into the state,
  so its correlations with everything stay exact. The UT runs on the joint covariance of
  the clone and the current pose; the landmark's cross-covariance is
  ``G_i P_{clone,.} + G_j P_{r,.}``; the clone is then dropped. A pending clone unseen for
  ``drop_after`` seconds is dropped too.

Sparse real data (MRCLAM: a forward camera of about 66 deg, a robot at 7 cm/s, landmarks a
few metres away seen at a few Hz with gaps, odometry heading drifting about 2 deg per
square-root second) needs two options, both off in the paper's simulation:

* ``ekf_init = "linear"``: the UT gate cannot pass there. Parallax accrues at about a degree
  per second while the heading of the current pose relative to the clone grows uncertain
  as ``2 deg * sqrt(t)``; the UT's sigma points sit 3 sigma out (``n + kappa = 9``), so some
  of them meet behind a view until the parallax exceeds about three times that
  uncertainty, and the skewness gate asks for ten times. Measured: no landmark initialised
  on robot 1 in 760 s, however long the first sighting is kept. This option initialises
  at ``min_parallax`` (with the rays meeting in front) instead, with first-order moments:
  the landmark at the two mean rays' intersection, ``P_ll = G P_8 G'`` (``P_8`` the joint
  covariance of the two poses and the two bearings), cross-covariances as above. Such a
  landmark is poorly known in depth; the next option keeps the updates that use it sane.
* ``ekf_second_order``: the update's second-order terms (see :meth:`BearingEkf.update`).

The NIS gate (``nis_gate``) drops bearings whose innovation is improbable (outlier bursts).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from workbench.estimation import outliers
from workbench.estimation.angles import wrap
from workbench.estimation.consistency import Innovations
from workbench.estimation.metrics import chi2_quantile
from workbench.experiments.omni.algorithms import bearing_update, triangulation
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.motion import Stretches
from workbench.experiments.omni.scenario import OmniData

AUGMENTATIONS = ("paper", "clone")

_HELD: np.ndarray | None = None
"""Per landmark, the step at which :func:`run` initialises it (-1: never), whatever its gates say,
while a :class:`HeldInit` is entered; None: the gates decide."""


class HeldInit:
    """:func:`run`'s landmarks initialised at the steps ``init_step`` (another run's: its
    ``SlamEstimate.init_step``) and at no other, while entered (reusable; a module global, not a
    context variable, so that a thread an estimator timeout starts and a forked process see it too).

    Why: ``--tune-noise`` compares the filter's likelihood at many noises, and a SLAM filter's rows
    change with the noise it is told (a landmark the UT's gate passes a step sooner or later; the
    bearings spent on it have no innovation), so its likelihood jumps by about a unit and the
    search and the curvature read the jumps as slopes (:mod:`workbench.core.selftune`). With the
    initialisations held, the likelihood is that of the same rows at every noise, conditional on
    where the landmarks entered, as a likelihood conditional on a data association is: smooth in the
    noise. Run with the steps it made itself, the filter gives the same estimate bit for bit."""

    def __init__(self, init_step: np.ndarray):
        self.init_step = np.asarray(init_step, int).copy()
        self._before: list[np.ndarray | None] = []

    def __eq__(self, other: object) -> bool:
        return isinstance(other, HeldInit) and np.array_equal(self.init_step, other.init_step)

    __hash__ = None  # type: ignore[assignment]

    def __enter__(self) -> HeldInit:
        global _HELD
        self._before.append(_HELD)
        _HELD = self.init_step
        return self

    def __exit__(self, *exc: object) -> None:
        global _HELD
        _HELD = self._before.pop()


class BearingEkf:
    """The filter's state and its four operations: predict, update, start, initialise."""

    def __init__(self, data: OmniData, cfg: OmniConfig, augmentation: str, trace: bool = False):
        if augmentation not in AUGMENTATIONS:
            raise ValueError(f"augmentation must be one of {AUGMENTATIONS}")
        self.data, self.cfg, self.mode, self.trace = data, cfg, augmentation, trace
        self.x = data.start.astype(float).copy()
        self.P = data.start_cov.astype(float).copy()
        n_lm = len(data.landmarks)
        self.slot = np.full(n_lm, -1)          # state offset of each initialised landmark
        self.pending: dict[int, dict] = {}     # landmark -> first sighting
        self.first_seen = np.full(n_lm, -1)
        self.init_step = np.full(n_lm, -1)
        self.r = data.sigma_bearing**2
        self.gate = chi2_quantile(cfg.nis_gate, 1) if cfg.nis_gate > 0 else math.inf
        self.outlier = float(cfg.assume_outlier_rate or 0.0)   # (the config holds it below 0.5)
        self.linear = cfg.ekf_init == "linear"
        self.second_order = cfg.ekf_second_order
        self.failures = 0
        self.gated: list[int] = []  # the bearings (dataset indices) the NIS gate left out
        # (t, innovation, variance, its bearing noise's part, kept): a gated bearing keeps the innovation it was
        # judged on (kept 0), for the truth-free diagnosis; NaN: none
        self.innovations: list[tuple[float, float, float, float, float]] = []
        self.attempts: list = []
        self.stretches: Stretches | None = None   # the log's odometry in its own frame (:meth:`predict`)

    def threshold(self, s: np.ndarray) -> np.ndarray:
        """The NIS beyond which a bearing of innovation variance ``s`` is left out: the chi-square
        gate's (``nis_gate``), or with an outlier model (``assume_outlier_rate``, an outlier
        uniform over the circle) where it is more likely an outlier than not
        (:func:`workbench.estimation.outliers.even_odds`: the gate then widens in sigmas as the
        prediction sharpens)."""
        return outliers.gate(s, self.outlier, self.gate)

    # --- (7)-(8) ---------------------------------------------------------------------------
    def predict(self, i: int, j: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Propagate over the log's steps ``i`` to ``j`` (the end: None); returns the poses and pose
        covariances after each step. The log's odometry is read once, in its own frame
        (:meth:`.motion.Motion.frame`), and each stretch moved onto the filter's pose."""
        if self.stretches is None:
            self.stretches = self.data.motion.frame(*self.data.odometry())
        j = self.data.steps if j is None else j
        poses, covs, phi = self.stretches.propagate(i, j, self.x[:3], self.P[:3, :3])
        self.x[:3] = poses[-1]
        self.P[:3, :3] = covs[-1]
        if len(self.x) > 3:
            cross = phi @ self.P[:3, 3:]
            self.P[:3, 3:] = cross
            self.P[3:, :3] = cross.T
        return poses[1:], covs[1:]

    # --- (9)-(13) --------------------------------------------------------------------------
    def update(self, lms: np.ndarray, bearings: np.ndarray, index: np.ndarray | None = None,
               t: float = float("nan")) -> None:
        """Update with bearings of initialised landmarks, all at once (``index``: their indices in
        the dataset, to note those the NIS gate leaves out; ``t``: their time, for the innovations).

        The innovations are noted one bearing at a time, as a sequential update would see them:
        with ``S = L L'`` (Cholesky), bearing ``i``'s innovation given the epoch's earlier ones is
        ``L_ii w_i`` with variance ``L_ii^2``, ``w = L^-1 nu``; their NIS are independent chi-square
        of one degree each and their log-likelihoods sum to the joint one (:mod:`.truthfree`).

        With ``ekf_second_order`` each bearing's innovation gets the second-order terms of
        (9): its mean shifts by ``tr(B C) / 2`` and its variance grows by ``tr(B C B C) / 2``
        (``B`` the Hessian of the bearing in the vehicle-to-landmark vector, ``C`` that
        vector's covariance). They are negligible where the geometry is known to a fraction of
        the range (the paper's simulation) and large where it is not: on MRCLAM, a landmark
        a few metres away seen again after a blind stretch of a minute (vehicle 2 m and 25 deg
        uncertain), where the first-order update collapses the covariance onto a wrong pose.

        The arithmetic is :mod:`.bearing_update`'s compiled kernels (the gate between them here)."""
        if len(lms) == 0:
            return
        index = np.full(len(lms), -1) if index is None else np.asarray(index)
        off = self.slot[lms]
        own = index >= 0
        r = np.full(len(lms), self.r)
        if self.data.meas_sigma is not None and own.any():
            r[own] = self.data.bearing_sigma(index[own]) ** 2
        nu, S, PH = bearing_update.innovations(self.x, self.P, off, np.asarray(bearings, float), r,
                                               bool(self.second_order))
        if math.isfinite(self.gate) or self.outlier > 0:
            s = np.diag(S)
            keep = nu**2 / s <= self.threshold(s)
            if not keep.all():
                self.gated.extend(int(i) for i in index[~keep])
                self.innovations.extend((t, float(v), float(q), float(w), 0.0)
                                        for v, q, w in zip(nu[~keep], s[~keep], r[~keep], strict=True))
                nu, PH, r = nu[keep], np.ascontiguousarray(PH[:, keep]), r[keep]
                S = np.ascontiguousarray(S[np.ix_(keep, keep)])
                if len(nu) == 0:
                    return
        ok, x, P, seq, w = bearing_update.corrected(self.x, self.P, nu, S, PH)
        if ok:
            self.innovations.extend((t, float(a * b), float(a * a), float(q), 1.0)
                                    for a, b, q in zip(seq, w, r, strict=True))
        else:   # S not positive definite: solved by LU, each bearing noted with its own S_ii
            try:
                K = np.linalg.solve(S, PH.T).T
            except np.linalg.LinAlgError:
                self.failures += 1
                return
            self.innovations.extend((t, float(v), float(q), float(w), 1.0)
                                    for v, q, w in zip(nu, np.diag(S), r, strict=True))
            x = self.x + K @ nu
            P = self.P - K @ S @ K.T
            P = 0.5 * (P + P.T)
        if not (np.isfinite(x).all() and np.isfinite(P).all()):
            self.failures += 1
            return
        self.x = x
        self.x[2] = wrap(self.x[2])
        self.P = P

    # --- (1)-(5), (14)-(15) ----------------------------------------------------------------
    def start(self, lm: int, bearing: float, step: int, r2: float | None = None) -> None:
        """Keep a first sighting: clone the pose into the state, or store it (paper); ``r2``: the
        bearing's own variance (default the log's one)."""
        sight = {"bearing": bearing, "step": step, "last": step, "r2": self.r if r2 is None else r2}
        if self.mode == "clone":
            n = len(self.x)
            self.x = np.concatenate([self.x, self.x[:3]])
            P = np.empty((n + 3, n + 3))
            P[:n, :n] = self.P
            P[:n, n:] = self.P[:, :3]
            P[n:, :n] = self.P[:3, :]
            P[n:, n:] = self.P[:3, :3]
            self.P = P
            sight["offset"] = n
        else:
            sight["pose"] = self.x[:3].copy()
            sight["var"] = np.diag(self.P[:3, :3]).copy()
        self.pending[lm] = sight

    def _delete(self, offset: int, size: int) -> None:
        """Marginalise the ``size`` state rows from ``offset`` out (a Gaussian's marginal: drop
        them from the mean and the covariance) and shift the offsets behind them."""
        keep = np.r_[0:offset, offset + size:len(self.x)]
        self.x = self.x[keep]
        self.P = self.P[np.ix_(keep, keep)]
        self.slot[self.slot > offset] -= size
        for other in self.pending.values():
            if other.get("offset", -1) > offset:
                other["offset"] -= size

    def _drop_clone(self, offset: int) -> None:
        self._delete(offset, 3)

    def merge(self, keep: int, drop: int) -> None:
        """Two initialised landmarks found to be one line: condition the state on
        ``x_keep = x_drop`` (the update (10)-(13) with ``H = [.. I .. -I ..]`` and no noise: an
        exact linear constraint) and marginalise ``drop`` out."""
        a, b = int(self.slot[keep]), int(self.slot[drop])
        H = np.zeros((2, len(self.x)))
        H[:, a:a + 2] = np.eye(2)
        H[:, b:b + 2] = -np.eye(2)
        PH = self.P @ H.T
        try:
            K = np.linalg.solve(H @ PH, PH.T).T
        except np.linalg.LinAlgError:
            self.failures += 1
        else:
            x = self.x - K @ (H @ self.x)
            P = self.P - K @ PH.T
            if np.isfinite(x).all() and np.isfinite(P).all():
                self.x, self.P = x, 0.5 * (P + P.T)
                self.x[2] = wrap(self.x[2])
        self.forget(drop)

    def forget(self, lm: int) -> None:
        """Take an initialised landmark out of the map (marginalised; e.g. a duplicate)."""
        offset = int(self.slot[lm])
        self.slot[lm] = -1
        self._delete(offset, 2)

    def drop(self, lm: int) -> None:
        sight = self.pending.pop(lm)
        if "offset" in sight:
            self._drop_clone(sight["offset"])

    def try_initialise(self, lm: int, bearing: float, step: int,
                       accept: Callable[[np.ndarray, np.ndarray], bool] | None = None, r2: float | None = None,
                       force: bool | None = None) -> bool:
        """Triangulate from the first sighting and this one; augment the state if the gate passes
        (and ``accept(mean, P_ll)``, a caller's own test of the candidate landmark, if given).
        ``force``: True augments whatever the gates say (where the triangulation is finite), False
        does not try (:class:`HeldInit`)."""
        cfg, sight = self.cfg, self.pending[lm]
        sight["last"] = step
        if force is False:
            return False
        r2 = self.r if r2 is None else r2
        if self.mode == "clone":
            o = sight["offset"]
            idx = np.r_[o:o + 3, 0:3]
            mu = np.concatenate([self.x[idx], [sight["bearing"], bearing]])
            cov = np.zeros((8, 8))
            cov[:6, :6] = self.P[np.ix_(idx, idx)]
        else:
            mu = np.concatenate([sight["pose"], self.x[:3], [sight["bearing"], bearing]])
            cov = np.diag(np.concatenate([sight["var"], np.diag(self.P[:3, :3]), [0.0, 0.0]]))
        cov[6, 6], cov[7, 7] = sight.get("r2", r2), r2
        if not self.trace and not force and triangulation.parallax(mu) < math.radians(cfg.min_parallax_deg):
            return False   # rejected whatever the UT says (both gates need the parallax): not pushed through it
        att = triangulation.attempt(mu, cov, cfg.skew_gate, math.radians(cfg.min_parallax_deg), cfg.kappa)
        accepted, mean = att.accepted, att.mean
        G = triangulation.jacobian(mu)
        if self.linear:
            point, s_i, s_j = triangulation.rays(mu)
            accepted = bool(att.parallax >= math.radians(cfg.min_parallax_deg) and s_i[0] > 0 and s_j[0] > 0)
            mean = point[0]
        if self.trace:
            self.attempts.append((step, lm, att.points, accepted))
        if force:
            accepted = bool(np.isfinite(mean).all())
        if not accepted:
            return False
        if self.mode == "clone":
            cross = G[:, :3] @ self.P[o:o + 3, :] + G[:, 3:6] @ self.P[:3, :]
            linear = G[:, :6] @ cov[:6, :6] @ G[:, :6].T
            if self.linear:
                p_ll = linear + G[:, 6:] @ cov[6:, 6:] @ G[:, 6:].T
            else:
                p_ll = att.cov
                # keep the joint covariance PSD: the UT's P_ll must exceed its pose-driven part
                low = np.linalg.eigvalsh(p_ll - linear).min()
                if low < 0.0:
                    p_ll = p_ll + (1e-9 - low) * np.eye(2)
        else:
            cross = G[:, 3:6] @ self.P[:3, :]
            p_ll = G @ cov @ G.T if self.linear else att.cov
        if accept is not None and not accept(mean, p_ll):
            return False
        if force and not np.isfinite(p_ll).all():
            return False
        self._augment(lm, step, mean, cross, p_ll)
        return True

    def _augment(self, lm: int, step: int, mean: np.ndarray, cross: np.ndarray, p_ll: np.ndarray) -> None:
        """Append the landmark (14)-(15) and drop its pending sighting."""
        n = len(self.x)
        self.x = np.concatenate([self.x, mean])
        P = np.empty((n + 2, n + 2))
        P[:n, :n] = self.P
        P[n:, :n] = cross
        P[:n, n:] = cross.T
        P[n:, n:] = p_ll
        self.P = P
        self.slot[lm] = n
        self.init_step[lm] = step
        self.drop(lm)


def run(data: OmniData, cfg: OmniConfig, augmentation: str, name: str, trace: bool = False) -> SlamEstimate:
    """Filter the whole dataset: a pose estimate at every step, the map at every bearing epoch."""
    f = BearingEkf(data, cfg, augmentation, trace)
    K, N = data.steps, len(data.landmarks)
    poses = np.empty((K + 1, 3))
    covs = np.empty((K + 1, 3, 3))
    poses[0], covs[0] = f.x[:3], f.P[:3, :3]
    epochs = data.epochs()
    map_steps = np.array([s for s, _ in epochs], int)
    map_mean = np.full((len(epochs), N, 2), np.nan)
    map_cov = np.full((len(epochs), N, 2, 2), np.nan)
    drop_steps = cfg.drop_after
    held = _HELD
    last = 0
    for e, (step, idx) in enumerate(epochs):
        if step > last:
            poses[last + 1:step + 1], covs[last + 1:step + 1] = f.predict(last, step)
            last = step
        lms, bearings = data.meas_lm[idx], data.meas_bearing[idx]
        known = f.slot[lms] >= 0
        f.update(lms[known], bearings[known], idx[known], float(data.t[step]))
        now = data.t[step]
        var = data.bearing_sigma(idx[~known]) ** 2 if data.meas_sigma is not None else [None] * int((~known).sum())
        for lm, b, r2 in zip(lms[~known], bearings[~known], var, strict=True):
            lm = int(lm)
            if f.first_seen[lm] < 0:
                f.first_seen[lm] = step
            own = {} if r2 is None else {"r2": float(r2)}  # (each bearing's own variance, where the log gives it)
            if lm in f.pending:
                if held is not None:   # (the keyword only where held: a wrapper of the method's own needs no new one)
                    own["force"] = bool(held[lm] == step)
                f.try_initialise(lm, float(b), step, **own)
            else:
                f.start(lm, float(b), step, **own)
        for lm in [k for k, s in f.pending.items() if now - data.t[s["last"]] > drop_steps]:
            f.drop(lm)
        poses[step], covs[step] = f.x[:3], f.P[:3, :3]
        on = f.slot >= 0
        if on.any():
            o = f.slot[on]
            map_mean[e, on] = np.stack([f.x[o], f.x[o + 1]], axis=1)
            for a in range(2):
                for b in range(2):
                    map_cov[e, on, a, b] = f.P[o + a, o + b]
    if K > last:
        poses[last + 1:], covs[last + 1:] = f.predict(last)
    innov = np.array(f.innovations, float).reshape(-1, 5)
    return SlamEstimate(name, np.arange(K + 1), poses, covs, map_steps, map_mean, map_cov,
                        f.first_seen, f.init_step, failures=f.failures, gated_bearings=np.array(f.gated, int),
                        attempts=f.attempts, innovations=Innovations.scalar(*innov[:, :3].T, kept=innov[:, 4] > 0,
                                                                       r=innov[:, 3], gate=cfg.nis_gate or None,
                                                                       outlier=(f.outlier, 1.0 / (2.0 * math.pi))
                                                                       if f.outlier > 0 else None))


def odometry(data: OmniData, name: str = "odometry") -> SlamEstimate:
    """Dead reckoning (7)-(8) alone: no map."""
    poses, covs, _ = data.motion.propagate(data.start, data.start_cov, *data.odometry())
    n = len(data.landmarks)
    return SlamEstimate(name, np.arange(len(poses)), poses, covs, np.zeros(0, int), np.zeros((0, n, 2)),
                        None, np.full(n, -1), np.full(n, -1))
