"""Odometry motion models: the paper's bicycle (7)-(8) and a unicycle for wheeled robots.

Poses are ``(x, y, phi)``; a control ``u`` acts over one step ``dt``.

* ``bicycle`` (7), ``u = (V, gamma)``: ``x += dt V cos(phi + gamma)``,
  ``y += dt V sin(phi + gamma)``, ``phi += dt V sin(gamma) / L``.
* ``unicycle``, ``u = (v, w)`` (MRCLAM's odometry): ``x += dt v cos phi``,
  ``y += dt v sin phi``, ``phi += dt w``.
* ``increments``, ``u = (dx, dy, dphi)``: the relative pose from one step to the next in the body
  frame at the step's start, the graph-SLAM convention (g2o's ``EDGE_SE2``, a wheel-odometry
  node's integrated output): ``x += dx cos phi - dy sin phi``, ``y += dx sin phi + dy cos phi``,
  ``phi += dphi``; its noise is each step's own covariance of ``u`` (``U`` per step, from the log)
  or ``diag(sigma_u^2)`` (three sigmas) where the log gives none; never a density.

The covariance (8): ``P' = F_R P F_R' + F_U U F_U' + Q`` with ``F_R = df/dx_R``, ``F_U = df/du``.
The noise is white per step by default (the paper's reading, ``U = diag(sigma_u^2)`` and ``Q``
whatever the step). With ``per_second`` the sigmas are densities instead, ``U_k = diag(sigma_u^2) /
dt_k`` and ``Q_k = diag(sigma_q^2) dt_k``, so that the variance a stretch of odometry adds grows
with its duration and not with how many rows the log happens to have in it: MRCLAM's odometry
arrives at irregular steps (0.01 s mostly, 0.02-0.04 s often, gaps up to 1 s).
Everything here is vectorised over steps: headings are a cumulative sum, positions too,
given a start pose, so a stretch of dead reckoning costs no Python loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from workbench.estimation.angles import wrap

MODELS = ("bicycle", "unicycle", "increments")


@dataclass(frozen=True)
class Motion:
    """A motion model with its noise: ``sigma_u`` per control, ``sigma_q`` (Q); white per step,
    or densities (per square-root second) with ``per_second``."""

    model: str
    wheelbase: float
    sigma_u: tuple[float, ...]  # per control: two, three for ``increments``
    sigma_q: tuple[float, float, float] = (0.0, 0.0, 0.0)
    per_second: bool = False

    def heading_rates(self, controls: np.ndarray) -> np.ndarray:
        """``dphi/dt`` per step."""
        if self.model == "bicycle":
            return controls[:, 0] * np.sin(controls[:, 1]) / self.wheelbase
        return controls[:, 1]

    def integrate(self, start: np.ndarray, controls: np.ndarray, dt: np.ndarray) -> np.ndarray:
        """Poses ``(K+1, 3)`` from ``start`` through ``controls (K, 2)`` over steps ``dt (K,)``."""
        if self.model == "increments":
            phi = start[2] + np.concatenate([[0.0], np.cumsum(controls[:, 2])])
            c, s = np.cos(phi[:-1]), np.sin(phi[:-1])
            x = start[0] + np.concatenate([[0.0], np.cumsum(controls[:, 0] * c - controls[:, 1] * s)])
            y = start[1] + np.concatenate([[0.0], np.cumsum(controls[:, 0] * s + controls[:, 1] * c)])
            return np.stack([x, y, wrap(phi)], axis=1)
        dt = np.broadcast_to(np.asarray(dt, float), (len(controls),))
        phi = start[2] + np.concatenate([[0.0], np.cumsum(dt * self.heading_rates(controls))])
        course = phi[:-1] + (controls[:, 1] if self.model == "bicycle" else 0.0)
        speed = controls[:, 0] * dt
        x = start[0] + np.concatenate([[0.0], np.cumsum(speed * np.cos(course))])
        y = start[1] + np.concatenate([[0.0], np.cumsum(speed * np.sin(course))])
        return np.stack([x, y, wrap(phi)], axis=1)

    def jacobians(self, poses: np.ndarray, controls: np.ndarray, dt: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
        """``F_R (K, 3, 3)`` and ``F_U (K, 3, 2)`` of (8) at ``poses (K, 3)`` (the step's start);
        ``F_U (K, 3, 3)``, the step's rotation, for ``increments``."""
        k = len(controls)
        if self.model == "increments":
            c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
            dx, dy = controls[:, 0], controls[:, 1]
            fr = np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
            fr[:, 0, 2] = -s * dx - c * dy
            fr[:, 1, 2] = c * dx - s * dy
            fu = np.zeros((k, 3, 3))
            fu[:, 0, 0], fu[:, 0, 1], fu[:, 1, 0], fu[:, 1, 1], fu[:, 2, 2] = c, -s, s, c, 1.0
            return fr, fu
        dt = np.broadcast_to(np.asarray(dt, float), (k,))
        v = controls[:, 0]
        course = poses[:, 2] + (controls[:, 1] if self.model == "bicycle" else 0.0)
        c, s = np.cos(course), np.sin(course)
        fr = np.broadcast_to(np.eye(3), (k, 3, 3)).copy()
        fr[:, 0, 2] = -dt * v * s
        fr[:, 1, 2] = dt * v * c
        fu = np.zeros((k, 3, 2))
        fu[:, 0, 0] = dt * c
        fu[:, 1, 0] = dt * s
        if self.model == "bicycle":
            g = controls[:, 1]
            fu[:, 0, 1] = -dt * v * s
            fu[:, 1, 1] = dt * v * c
            fu[:, 2, 0] = dt * np.sin(g) / self.wheelbase
            fu[:, 2, 1] = dt * v * np.cos(g) / self.wheelbase
        else:
            fu[:, 2, 1] = dt
        return fr, fu

    def step_noise(self, fu: np.ndarray, dt: np.ndarray | float | None = None,
                   control_var: np.ndarray | None = None) -> np.ndarray:
        """``F_U U F_U' + Q`` per step, ``(K, 3, 3)`` (``dt`` is needed only ``per_second``).

        ``control_var (K, 2)``, if given, is each step's own extra variance of its control (not a
        density: the variance of the step's mean control, as :attr:`.scenario.OmniData.control_var`
        holds it), added to ``U`` as ``F_U diag(control_var) F_U'``. For ``increments``,
        ``control_var (K, 3, 3)`` is each step's whole covariance of its increment (NaN rows: the
        sigmas' ``diag(sigma_u^2)``), ``F_U U_k F_U'``.
        """
        return self.control_noise(fu, dt, control_var) + self.q_noise(len(fu), dt)

    def control_noise(self, fu: np.ndarray, dt: np.ndarray | float | None = None,
                      control_var: np.ndarray | None = None) -> np.ndarray:
        """The controls' part of :meth:`step_noise`, ``F_U U F_U'`` (its ``control_var`` too): what
        turns with the frame ``F_U`` is taken in."""
        u = np.diag(np.square(self.sigma_u))
        if self.model == "increments":
            U = np.broadcast_to(u, (len(fu), 3, 3)).copy()
            if control_var is not None:
                cv = np.asarray(control_var, float)
                own = np.isfinite(cv).all(axis=(1, 2))
                U[own] = cv[own]
            return fu @ U @ fu.transpose(0, 2, 1)
        noise = fu @ u @ fu.transpose(0, 2, 1)
        if self.per_second:
            dt = np.broadcast_to(np.asarray(dt, float), (len(fu),))
            with np.errstate(divide="ignore", invalid="ignore"):
                scale = np.where(dt > 0, 1.0 / dt, 0.0)
            noise = scale[:, None, None] * noise
        if control_var is not None:
            noise = noise + (fu * np.asarray(control_var, float)[:, None, :]) @ fu.transpose(0, 2, 1)
        return noise

    def q_noise(self, k: int, dt: np.ndarray | float | None = None) -> np.ndarray:
        """``Q`` per step, ``(k, 3, 3)`` (world frame, whatever the heading)."""
        q = np.diag(np.square(self.sigma_q))
        if self.model == "increments" or not self.per_second:
            return np.broadcast_to(q, (k, 3, 3))
        return np.broadcast_to(np.asarray(dt, float), (k,))[:, None, None] * q

    def frame(self, controls: np.ndarray, dt: np.ndarray, control_var: np.ndarray | None = None) -> Stretches:
        """The whole log's dead reckoning in its own frame, for :meth:`Stretches.propagate`."""
        poses = self.integrate(np.zeros(3), controls, dt)
        fr, fu = self.jacobians(poses[:-1], controls, dt)
        return Stretches(poses, fr[:, :2, 2].copy(), self.control_noise(fu, dt, control_var),
                         self.q_noise(len(controls), dt))

    def propagate(self, start: np.ndarray, cov: np.ndarray, controls: np.ndarray, dt: np.ndarray,
                  control_var: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Dead reckoning with (8): poses ``(K+1, 3)``, covariances ``(K+1, 3, 3)`` and the
        product ``Phi = F_R[K-1] ... F_R[0]`` (what the cross-covariances need); ``control_var``
        as in :meth:`step_noise`."""
        poses = self.integrate(start, controls, dt)
        fr, fu = self.jacobians(poses[:-1], controls, dt)
        noise = self.step_noise(fu, dt, control_var)
        covs = _recursion(np.asarray(cov, float), fr[:, :2, 2], noise)
        # every F_R is I plus a heading column, so their product adds those columns up
        phi = np.eye(3)
        phi[:2, 2] = fr[:, :2, 2].sum(axis=0)
        return poses, covs, phi


@dataclass
class Stretches:
    """A log's dead reckoning from the origin at heading 0 (its odometry frame): ``poses (K+1, 3)``,
    each step's heading column of ``F_R`` (``a (K, 2)``) and its controls' noise (``control
    (K, 3, 3)``), and ``q`` (``Q``, world frame). A filter propagates over one stretch of the log at a
    time from wherever it is (:meth:`propagate`): (7)-(8) commute with a rigid motion of the start, so
    a stretch's poses are its frame's moved onto the filter's pose, and ``F_R``'s heading columns and
    ``F_U U F_U'`` turn with the start's heading; ``Q`` does not. Read once per run, this is
    :meth:`Motion.propagate`'s answer without integrating and differentiating each stretch again (a
    SLAM filter propagates between each pair of bearing epochs: 2,000 stretches on a MRCLAM robot)."""

    poses: np.ndarray
    a: np.ndarray
    control: np.ndarray
    q: np.ndarray

    def propagate(self, i: int, j: int, start: np.ndarray, cov: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`Motion.propagate` from ``start`` / ``cov`` over steps ``i`` to ``j`` of the log
        (:func:`_moved`: compiled, a stretch being a few steps and a run thousands of stretches)."""
        return _moved(self.poses[i:j + 1], self.a[i:j], self.control[i:j], self.q[i:j],
                      np.asarray(start, float), np.asarray(cov, float))


@numba.njit(cache=True)
def _moved(o: np.ndarray, a: np.ndarray, control: np.ndarray, q: np.ndarray, start: np.ndarray,
           p0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A stretch of the log's own frame (``o``, its poses; ``a``, ``control``, ``q`` per step as in
    :class:`Stretches`) moved onto ``start`` by the rotation ``R`` of its heading: the poses turned
    and shifted, ``a`` turned by ``R``, the controls' noise by ``T = diag(R, 1)`` (``T U T' + Q``),
    then :func:`_recursion` and ``Phi = I + (sum a) e3'``."""
    k = len(a)
    turn = start[2] - o[0, 2]
    c, s = math.cos(turn), math.sin(turn)
    poses = np.empty((k + 1, 3))
    for n in range(k + 1):
        dx, dy = o[n, 0] - o[0, 0], o[n, 1] - o[0, 1]
        poses[n, 0] = start[0] + (c * dx - s * dy)
        poses[n, 1] = start[1] + (s * dx + c * dy)
        poses[n, 2] = wrap_one(start[2] + (o[n, 2] - o[0, 2]))
    turned = np.empty((k, 2))
    noise = np.empty((k, 3, 3))
    T = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    phi = np.eye(3)
    for n in range(k):
        turned[n, 0] = c * a[n, 0] - s * a[n, 1]
        turned[n, 1] = s * a[n, 0] + c * a[n, 1]
        phi[0, 2] += turned[n, 0]
        phi[1, 2] += turned[n, 1]
        for r in range(3):
            for m in range(3):
                acc = 0.0
                for u in range(3):
                    for v in range(3):
                        acc += T[r, u] * control[n, u, v] * T[m, v]
                noise[n, r, m] = acc + q[n, r, m]
    return poses, _recursion(p0, turned, noise), phi


@numba.njit(cache=True)
def _recursion(p0: np.ndarray, a: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """``P[k+1] = F[k] P[k] F[k]' + N[k]`` a step at a time, ``(K+1, 3, 3)``, where each
    ``F[k] = I + a[k] e3'`` (``a (K, 2)``: the heading column of (8)'s ``F_R``, zero in its third
    entry), so that ``F P F' = P + a p' + p a' + P33 a a'`` with ``p = P e3``; each step
    symmetrised. Compiled: a SLAM filter propagates over thousands of short stretches a run, where
    array operations spent their time in call overhead (the prefix-sum unrolling this replaced, at
    34 us a stretch, against under 1 us here; it also lost digits over long stretches by
    cancellation)."""
    k = len(a)
    out = np.empty((k + 1, 3, 3))
    for r in range(3):
        for m in range(3):
            out[0, r, m] = 0.5 * (p0[r, m] + p0[m, r])
    av = np.zeros(3)
    col = np.empty(3)
    for n in range(k):
        P = out[n]
        av[0], av[1] = a[n, 0], a[n, 1]
        for r in range(3):
            col[r] = P[r, 2]
        c33 = P[2, 2]
        for r in range(3):
            for m in range(r, 3):
                v = (P[r, m] + av[r] * col[m] + col[r] * av[m] + c33 * av[r] * av[m]
                     + 0.5 * (noise[n, r, m] + noise[n, m, r]))
                out[n + 1, r, m] = v
                out[n + 1, m, r] = v
    return out


@numba.njit(cache=True)
def wrap_one(a: float) -> float:
    """One angle wrapped to (-pi, pi], compiled (:func:`~workbench.estimation.angles.wrap`'s formula)."""
    return math.pi - (math.pi - a) % (2.0 * math.pi)
