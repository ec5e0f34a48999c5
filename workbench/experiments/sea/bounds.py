"""The sea experiment's Cramér-Rao bounds: how well any estimator could know the object's x, y,
range and angles from the same measurements (:mod:`workbench.estimation.bounds`).

The model is the simulation's own. The state is the object's ``[x, y, vx, vy]`` (the
nearly-constant-velocity target: ``F``, ``Q`` of the discrete white-noise acceleration
``sigma_acc``) and the camera's true position ``[ox, oy]``, which moves by the platform's known
velocity (the scenario says so: ``observer_velocity``), so only where it is must be learnt.
Each step measures the azimuth and elevation (1)-(2) of the object from the true camera
(``sigma_alpha``, ``sigma_beta``; the impulse scenario's extra noise on its disturbed steps;
nothing where the object is not seen) and the camera's position (``sigma_observer``). The prior
is what every estimator shares: no knowledge of where the object or the camera start
(``DIFFUSE``) and the EKF's velocity prior (``prior_speed`` per axis).

Each run's bound is taken along its own true trajectory and the variances are averaged over
the runs, like the squared errors. (Averaging the runs' information first, as the posterior
bound's expectation reads, gives a valid but looser limit here: the runs' geometries differ
enough that their mean information is better conditioned than any run's, 1.35 m against each
run's 1.81-1.85 m for the smoothed position on 20 paper runs.)

Reading taken: the issue that asked for the bound put the observer's noise into each step's
measurement noise, ``R = diag(sa^2, sb^2) + sigma_o^2 J J'``, as the estimators then did. That
model forgets that the platform's path is known up to its start, and with it the bound is not
one: the AR filters, whose models of the angles use that the true angles are smooth, beat its
azimuth bound (0.74' against 0.88' on 20 paper runs). With the camera in the state the bound
holds for every estimator; the position bounds are the same to 1 % (the range, from the
elevation, dominates them) and the azimuth's falls to 0.36': the camera is known to 4 cm after
the run. The model-based estimators now hold the same model (:mod:`.observer`: the camera's start
as one offset learnt from every fix) and meet this bound: on 100 paper runs (seed 0) the
smoother's position efficiency is 0.95 +- 0.05 (1.70 +- 0.09 when they folded each fix in), the
EKF's and iSAM2's 0.99 and 0.98 (1.13, 1.10), the fixed-lag smoother's 0.91 +- 0.03 (1.24), and
every one's azimuth 1.00 (2.47-4.85). Algorithms 1-3 keep the measured positions, as the paper.

Under 1 is possible, and is no error of the bound's recursion (the fixed lag's equals the RTS
smoother run on the data up to each step's lag): this bound, each run's own averaged, lies above
the posterior bound proper, whose information is averaged first (Jensen), and an estimator may
fall between the two. On 40 paper runs that one is 8.41 / 3.62 / 1.40 m (filtering / 5 s lag /
smoothing) against 8.83 / 4.03 / 1.82 m here; the estimators are 1.04, 1.02 and 1.23 times it.

A causal estimator is held to the filtering bound, a smoother of the whole run to the
smoothing bound, a fixed-lag smoother to the bound of the data up to its lag
(:attr:`Estimator.delay`). The range and the angles are functions of the object and the camera:
their bounds are ``g' P g`` with their gradients at the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from workbench.estimation import bounds, kalman
from workbench.experiments.sea import geometry

DIFFUSE = 1.0e4
"""The bound's prior standard deviation of the start position, m: none to speak of."""
QUANTITIES = ("x", "y", "position", "range", "alpha", "beta")


@dataclass(frozen=True)
class Model:
    """What the bound needs of a run's configuration (small; it travels in each run's summary)."""

    dt: float
    height: float
    sigma_acc: float
    sigma_alpha: float        # rad
    sigma_beta: float         # rad
    sigma_observer: float     # m
    prior_speed: float        # m/s per axis
    impulse_sigma: float = 0.0  # rad, on the disturbed steps


@dataclass
class Truth:
    """A run's true geometry: the object ``(T, 4)``, the camera ``(T, 2)``, the steps where the
    object is seen and those the impulse disturbs."""

    target: np.ndarray
    observer: np.ndarray
    seen: np.ndarray
    disturbed: np.ndarray


def information(truth: Truth, m: Model) -> np.ndarray:
    """The run's measurement information ``H' R^-1 H`` per step ``(T, 6, 6)`` at the truth: the
    angles (where the object is seen) and the camera's measured position; ``(T, 4, 4)``, the
    object's alone, where the camera is known exactly (``sigma_observer`` 0: its exact model)."""
    T = len(truth.target)
    J = geometry.angle_jacobian(truth.target[:, :2], truth.observer, m.height)
    if m.sigma_observer == 0.0:  # the camera known exactly: it leaves the state, the angles alone inform
        H = np.zeros((T, 2, 4))
        H[:, :, :2] = J
        R = np.zeros((T, 2, 2))
        R[:, 0, 0] = m.sigma_alpha**2 + truth.disturbed * m.impulse_sigma**2
        R[:, 1, 1] = m.sigma_beta**2 + truth.disturbed * m.impulse_sigma**2
        H[~truth.seen] = 0.0
        return bounds.measurement_information(H, R)
    H = np.zeros((T, 4, 6))
    H[:, :2, :2], H[:, :2, 4:] = J, -J
    H[:, 2:, 4:] = np.eye(2)
    R = np.zeros((T, 4, 4))
    R[:, 0, 0] = m.sigma_alpha**2 + truth.disturbed * m.impulse_sigma**2
    R[:, 1, 1] = m.sigma_beta**2 + truth.disturbed * m.impulse_sigma**2
    R[:, 2, 2] = R[:, 3, 3] = m.sigma_observer**2
    H[~truth.seen, :2] = 0.0  # no angles: only the camera's position that step
    return bounds.measurement_information(H, R)


def fixed_lag(filtered: np.ndarray, F: np.ndarray, Q: np.ndarray, steps: int) -> np.ndarray:
    """The bound of each step from the data up to ``steps`` after it: the RTS recursion run back
    from step ``min(k + steps, T - 1)`` to k, for every k at once."""
    P = np.asarray(filtered, float)
    T = len(P)
    if steps <= 0:
        return P.copy()
    pred = F @ P @ F.T + Q                                 # (T, n, n): step m predicted to m + 1
    C = P @ F.T @ np.linalg.inv(pred)
    k = np.arange(T)
    end = np.minimum(k + steps, T - 1)
    S = P[end].copy()
    for i in range(steps):
        m = end - 1 - i
        act = m >= k
        if not act.any():
            break
        mm = m[act]
        S[act] = P[mm] + C[mm] @ (S[act] - pred[mm]) @ np.swapaxes(C[mm], -1, -2)
    return 0.5 * (S + np.swapaxes(S, -1, -2))


@dataclass
class Bounds:
    """The bounds of a run (or of several, their information averaged: see the module's note)."""

    model: Model
    truths: list[Truth]
    _cache: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        m = self.model
        n = 4 if m.sigma_observer == 0.0 else 6  # (a camera known exactly is not in the state)
        self.F, self.Q = np.eye(n), np.zeros((n, n))
        self.F[:4, :4] = kalman.cv_transition(m.dt)
        self.Q[:4, :4] = kalman.cv_noise_discrete(m.dt, m.sigma_acc)
        self.info = np.mean([information(t, m) for t in self.truths], axis=0)
        P0 = np.diag([DIFFUSE**2, DIFFUSE**2, m.prior_speed**2, m.prior_speed**2, DIFFUSE**2, DIFFUSE**2][:n])
        self.filtered, self._predicted = bounds.filtering_and_prediction(P0, self.F, self.Q, self.info)

    def covariance(self, delay: float) -> np.ndarray:
        """The state bound ``(T, 6, 6)`` of an estimator using the data up to ``delay`` s after each step."""
        steps = len(self.info) if math.isinf(delay) else max(0, int(round(delay / self.model.dt)))
        if steps not in self._cache:
            if steps == 0:
                self._cache[steps] = self.filtered
            elif steps >= len(self.info) - 1:
                self._cache[steps] = bounds.smoothing(self.filtered, self.F, self.Q, self._predicted)
            else:
                self._cache[steps] = fixed_lag(self.filtered, self.F, self.Q, steps)
        return self._cache[steps]

    def variances(self, delay: float) -> dict[str, np.ndarray]:
        """Each quantity's bound (variance; rad^2 for the angles) per run and step ``(runs, T)``."""
        key = ("variances", delay)
        if key in self._cache:
            return self._cache[key]
        P = self.covariance(delay)
        runs = len(self.truths)
        out = {"x": np.broadcast_to(P[:, 0, 0], (runs, len(P))),
               "y": np.broadcast_to(P[:, 1, 1], (runs, len(P))),
               "position": np.broadcast_to(P[:, 0, 0] + P[:, 1, 1], (runs, len(P)))}
        for q in ("range", "alpha", "beta"):
            out[q] = np.stack([_quadratic(P, self._gradient(q, t)) for t in self.truths])
        self._cache[key] = out
        return out

    def _gradient(self, quantity: str, truth: Truth) -> np.ndarray:
        """d quantity / d(object state, camera) at the truth, ``(T, 6)``."""
        e = truth.target[:, :2] - truth.observer
        g = np.zeros((len(e), 6))
        if quantity == "range":
            u = e / np.linalg.norm(e, axis=1, keepdims=True)
            g[:, :2], g[:, 4:] = u, -u
            return g[:, :len(self.F)]
        row = 0 if quantity == "alpha" else 1
        J = geometry.angle_jacobian(truth.target[:, :2], truth.observer, self.model.height)[:, row]
        g[:, :2], g[:, 4:] = J, -J
        return g[:, :len(self.F)]


def _quadratic(A: np.ndarray, g: np.ndarray) -> np.ndarray:
    return np.einsum("ti,tij,tj->t", g, A, g)


def summary(variances: dict[str, np.ndarray], errors: np.ndarray, scale: dict[str, float]
            ) -> tuple[dict, dict, dict]:
    """An estimator's bound (the root of its variance bound averaged over the runs and the steps
    it estimates), its efficiency (its RMSE over the same steps over that bound) and the
    efficiency's Monte Carlo standard error (from the spread of the runs' mean squared errors),
    per quantity. ``variances``: quantity -> ``(runs, T)`` (:meth:`Bounds.variances` of each
    run); ``errors (runs, T, 5)``: x, y, alpha, beta, range as :func:`evaluate.errors` gives them."""
    columns = {"x": (0,), "y": (1,), "position": (0, 1), "range": (4,), "alpha": (2,), "beta": (3,)}
    bound, eff, se = {}, {}, {}
    for q in QUANTITIES:
        E = errors[..., list(columns[q])]
        ok = np.isfinite(E).all(axis=-1) & np.isfinite(variances[q])
        if not ok.any():
            continue
        b = float(np.sqrt(np.mean(variances[q][ok]))) * scale.get(q, 1.0)
        sq = np.where(ok, np.sum(np.nan_to_num(E) ** 2, axis=-1), 0.0)
        rmse = float(np.sqrt(sq.sum() / ok.sum())) * scale.get(q, 1.0)
        bound[q], eff[q] = b, bounds.efficiency(rmse, b**2)
        runs = ok.any(axis=1)
        per_run = sq[runs].sum(axis=1) / ok[runs].sum(axis=1)
        if len(per_run) > 1 and per_run.mean() > 0:
            se[q] = float(eff[q] * 0.5 * per_run.std(ddof=1) / (np.sqrt(len(per_run)) * per_run.mean()))
    return bound, eff, se
