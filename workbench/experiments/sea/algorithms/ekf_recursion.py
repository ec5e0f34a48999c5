"""The sea EKF's recursion (:func:`.ekf.estimate`), compiled: the prediction, the angles (1)-(2) and
their Jacobian, the chi-square gate and the Joseph-form update, written out in scalars over the
4-state constant-velocity model with the 2x2 innovation covariance inverted in closed form.

Why: the filter is the likelihood that ``--tune-noise``, ``workbench tune`` and the bootstrap's
noise search evaluate about a hundred times a run (``sea.resample.factors``); in array operations
a 720-step run took 38 ms, all of it call overhead on 4x4 matrices (measured, cProfile: 8.7 of the
11.4 s of two bootstrapped paper runs). Explicit loops, no ``fastmath`` and no BLAS call: every
product is summed in the same order on every processor (a replay's numbers do not depend on the
BLAS kernel picked; ``workbench.recording.machine``). The cost: compiling it takes about 9 s, once
per machine and processor (numba's cache, ``__pycache__`` beside this file).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_PI, _TWO_PI = math.pi, 2.0 * math.pi


@numba.njit(cache=True)
def _product(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A B`` for 4x4 ``A`` and ``B``, each entry summed over ``k`` in order."""
    M = np.zeros((4, 4))
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for k in range(4):
                acc += A[i, k] * B[k, j]
            M[i, j] = acc
    return M


@numba.njit(cache=True)
def _sandwich(A: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``A P A'`` for 4x4 ``A`` and ``P``."""
    return _product(_product(A, P), A.T)


@numba.njit(cache=True)
def recursion(x0: np.ndarray, P0: np.ndarray, first: int, F: np.ndarray, Q: np.ndarray, path: np.ndarray,
              course: np.ndarray, height: float, alpha: np.ndarray, beta: np.ndarray, seen: np.ndarray,
              sigma_alpha2: float, sigma_beta2: float, fold: float, gated: bool, gate: float
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The filter from ``(x0, P0)`` at step ``first`` (the first seen step, initialised by the caller)
    to the run's end: ``(X (T, 4), P (T, 4, 4), updated (T,), nu (T, 2), S (T, 2, 2), R (T, 2, 2),
    kept (T,))``, NaN before ``first``; ``updated[k]`` where step ``k`` was measured after ``first``
    (its innovation ``nu``, covariance ``S``, angle noise ``R`` with the camera's folded variance
    ``fold J J'``, and ``kept`` False where the gate left it out)."""
    T = len(seen)
    X = np.full((T, 4), np.nan)
    Ps = np.full((T, 4, 4), np.nan)
    updated = np.zeros(T, np.bool_)
    kept = np.zeros(T, np.bool_)
    nus = np.zeros((T, 2))
    Ss = np.zeros((T, 2, 2))
    Rs = np.zeros((T, 2, 2))
    x = x0.copy()
    P = P0.copy()
    X[first], Ps[first] = x, P
    for k in range(first + 1, T):
        xp = np.zeros(4)
        for i in range(4):
            acc = 0.0
            for j in range(4):
                acc += F[i, j] * x[j]
            xp[i] = acc
        x = xp
        M = _sandwich(F, P)
        for i in range(4):
            for j in range(4):
                M[i, j] += Q[i, j]
        P = np.zeros((4, 4))
        for i in range(4):
            for j in range(4):
                P[i, j] = 0.5 * (M[i, j] + M[j, i])
        if seen[k]:
            ex, ey = x[0] - path[k, 0], x[1] - path[k, 1]
            c, s = math.cos(course[k]), math.sin(course[k])
            k2 = ex * ex + ey * ey
            kk = math.sqrt(k2)
            g = -height / ((k2 + height * height) * kk)
            J = np.empty((2, 2))
            J[0, 0], J[0, 1], J[1, 0], J[1, 1] = -ey / k2, ex / k2, g * ex, g * ey
            ha = math.atan2(-ex * s + ey * c, ex * c + ey * s)
            hb = math.atan2(height, kk)
            R = np.zeros((2, 2))
            R[0, 0], R[1, 1] = sigma_alpha2, sigma_beta2
            if fold != 0.0:
                for i in range(2):
                    for j in range(2):
                        R[i, j] += fold * (J[i, 0] * J[j, 0] + J[i, 1] * J[j, 1])
            nu0 = _PI - (_PI - (alpha[k] - ha)) % _TWO_PI   # wrapped as angles.wrap
            nu1 = beta[k] - hb
            PHt = np.zeros((4, 2))                           # P H' with H = [J, 0]
            for i in range(4):
                for j in range(2):
                    PHt[i, j] = P[i, 0] * J[j, 0] + P[i, 1] * J[j, 1]
            S = np.zeros((2, 2))
            for i in range(2):
                for j in range(2):
                    S[i, j] = J[i, 0] * PHt[0, j] + J[i, 1] * PHt[1, j] + R[i, j]
            det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
            Si = np.empty((2, 2))
            Si[0, 0], Si[0, 1], Si[1, 0], Si[1, 1] = S[1, 1] / det, -S[0, 1] / det, -S[1, 0] / det, S[0, 0] / det
            d = (nu0 * (Si[0, 0] * nu0 + Si[0, 1] * nu1) + nu1 * (Si[1, 0] * nu0 + Si[1, 1] * nu1))
            updated[k] = True
            nus[k, 0], nus[k, 1] = nu0, nu1
            Ss[k], Rs[k] = S, R
            if not gated or d <= gate:
                kept[k] = True
                K = np.zeros((4, 2))
                for i in range(4):
                    for j in range(2):
                        K[i, j] = PHt[i, 0] * Si[0, j] + PHt[i, 1] * Si[1, j]
                ikh = np.eye(4)
                for i in range(4):
                    for j in range(2):
                        ikh[i, j] -= K[i, 0] * J[0, j] + K[i, 1] * J[1, j]
                for i in range(4):
                    x[i] += K[i, 0] * nu0 + K[i, 1] * nu1
                M = _sandwich(ikh, P)
                for i in range(4):
                    for j in range(4):
                        acc = 0.0
                        for a in range(2):
                            acc += K[i, a] * (R[a, 0] * K[j, 0] + R[a, 1] * K[j, 1])
                        M[i, j] += acc
                for i in range(4):
                    for j in range(4):
                        P[i, j] = 0.5 * (M[i, j] + M[j, i])
        X[k], Ps[k] = x, P
    return X, Ps, updated, nus, Ss, Rs, kept
