"""The bearing-only EKF's update (9)-(13), compiled: what :meth:`.ekf.BearingEkf.update` computes for
an epoch's bearings, written out over the bearing Jacobian's five non-zero columns.

A SLAM filter updates at every bearing epoch (2,000 on a MRCLAM robot, each with a few bearings and
a state of tens of rows), where array operations spend their time in call overhead, not in the
arithmetic; ``--tune-noise`` runs the filter about 200 times a tuning. The two kernels:

* :func:`innovations`: the bearings' innovations ``nu``, their covariance ``S = H P H' + R`` and
  ``P H'``, with the second-order terms of (9) where asked (the mean ``tr(B C) / 2`` and variance
  ``tr(B C B C) / 2``, ``B`` the Hessian of ``atan2(d_y, d_x)`` in the vehicle-to-landmark vector
  ``d``, ``C`` that vector's covariance);
* :func:`corrected`: the update by ``S``'s Cholesky factor ``L`` (Grewal and Andrews, *Kalman
  Filtering*, 4th ed., sec. 6.4): ``V = L^-1 (P H')'``, ``w = L^-1 nu``, ``x + V' w`` and
  ``P - V' V`` (``= P - K S K'``, symmetric by construction); ``L``'s diagonal and ``w`` are the
  innovations one bearing at a time (:meth:`.ekf.BearingEkf.update`). Where ``S`` is not positive
  definite (the paper's augmentation can make it so) it says so and the caller solves as before.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from workbench.experiments.omni.motion import wrap_one


@numba.njit(cache=True)
def innovations(x: np.ndarray, P: np.ndarray, off: np.ndarray, bearings: np.ndarray, r: np.ndarray,
                second_order: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``nu (m,)``, ``S (m, m)`` and ``P H' (n, m)`` of the bearings ``bearings`` to the landmarks at
    state offsets ``off`` with noise variances ``r``. Row ``i`` of ``H`` (9): ``(d_y, -d_x, -q, -d_y,
    d_x) / q`` in the vehicle's three columns and the landmark's two, ``q = |d|^2``."""
    n, m = len(x), len(off)
    hv = np.empty((m, 5))
    nu = np.empty(m)
    PH = np.empty((n, m))
    S = np.empty((m, m))
    for i in range(m):
        o = off[i]
        dx, dy = x[o] - x[0], x[o + 1] - x[1]
        q = dx * dx + dy * dy
        hv[i, 0], hv[i, 1], hv[i, 2], hv[i, 3], hv[i, 4] = dy / q, -dx / q, -1.0, -dy / q, dx / q
        nu[i] = wrap_one(bearings[i] - (math.atan2(dy, dx) - x[2]))
        for k in range(n):
            PH[k, i] = (P[k, 0] * hv[i, 0] + P[k, 1] * hv[i, 1] + P[k, 2] * hv[i, 2]
                        + P[k, o] * hv[i, 3] + P[k, o + 1] * hv[i, 4])
    for i in range(m):
        o = off[i]
        for j in range(m):
            S[i, j] = (hv[i, 0] * PH[0, j] + hv[i, 1] * PH[1, j] + hv[i, 2] * PH[2, j]
                       + hv[i, 3] * PH[o, j] + hv[i, 4] * PH[o + 1, j])
    for i in range(m):
        for j in range(i + 1, m):
            S[i, j] = S[j, i] = 0.5 * (S[i, j] + S[j, i])
        S[i, i] += r[i]
    if second_order:
        for i in range(m):
            o = off[i]
            a, b = x[o] - x[0], x[o + 1] - x[1]
            q2 = (a * a + b * b) ** 2
            b00 = 2.0 * a * b / q2
            b01 = (b * b - a * a) / q2
            B = np.array([[b00, b01], [b01, -b00]])
            C = np.empty((2, 2))
            for u in range(2):
                for v in range(2):
                    C[u, v] = P[o + u, o + v] + P[u, v] - P[o + u, v] - P[u, o + v]
            BC = B @ C
            nu[i] = wrap_one(nu[i] - 0.5 * (BC[0, 0] + BC[1, 1]))
            S[i, i] += 0.5 * (BC[0, 0] * BC[0, 0] + 2.0 * BC[0, 1] * BC[1, 0] + BC[1, 1] * BC[1, 1])
    return nu, S, PH


@numba.njit(cache=True)
def corrected(x: np.ndarray, P: np.ndarray, nu: np.ndarray, S: np.ndarray, PH: np.ndarray
              ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(ok, x+, P+, diag(L), w)`` by ``S = L L'``; ``ok`` False (and the inputs back) where ``S`` is
    not positive definite."""
    m, n = len(nu), len(x)
    L = np.zeros((m, m))
    for j in range(m):
        acc = S[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not acc > 0.0:
            return False, x, P, nu, nu
        L[j, j] = math.sqrt(acc)
        for i in range(j + 1, m):
            acc = S[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / L[j, j]
    V = np.empty((m, n))   # L^-1 (P H')'
    w = np.empty(m)        # L^-1 nu
    for i in range(m):
        acc = nu[i]
        for k in range(i):
            acc -= L[i, k] * w[k]
        w[i] = acc / L[i, i]
        for c in range(n):
            acc = PH[c, i]
            for k in range(i):
                acc -= L[i, k] * V[k, c]
            V[i, c] = acc / L[i, i]
    xn = x.copy()
    Pn = np.empty((n, n))
    for c in range(n):
        for k in range(m):
            xn[c] += V[k, c] * w[k]
        for d in range(c, n):
            acc = 0.0
            for k in range(m):
                acc += V[k, c] * V[k, d]
            Pn[c, d] = Pn[d, c] = 0.5 * (P[c, d] + P[d, c]) - acc
    diag = np.empty(m)
    for i in range(m):
        diag[i] = L[i, i]
    return True, xn, Pn, diag, w
