"""Truth-free consistency of an estimator: what its innovations, its residuals and another
estimator say of it, with no ground truth (Bar-Shalom, Li, Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, Wiley 2001, sec. 5.4).

* **NIS** ``nu' S^-1 nu`` of each innovation: chi-square with ``m`` degrees of freedom (the
  measurement's dimension) for a consistent filter (5.4.2); its time average over ``N``
  measurements has the band of :func:`~workbench.estimation.metrics.chi2_band` for ``N``.
* **Whiteness** (5.4.2, (5.4.2-11)): the innovations of a consistent filter are white; the
  normalised sample autocorrelation of the whitened innovations at lag ``l``,
  ``rho(l) = sum nu_k nu_k+l / sqrt(sum nu_k^2 sum nu_k+l^2)``, is then about ``N(0, 1/N)``:
  95 % of the lags within ``+-1.96 / sqrt(N)``.
* **Likelihood**: the prediction-error decomposition of the measurements' likelihood,
  ``-log p(z) = 1/2 sum (m log 2 pi + log det S + nu' S^-1 nu)``, a filter's own figure of how
  well its model explains the data (the objective of tuning by the data, without truth).
* **Disagreement with a smoother** (the reading taken here, after Bar-Shalom's 5.4 and the
  Rauch-Tung-Striebel identity): for a consistent filter estimate ``x_f, P_f`` and a consistent
  smoother's ``x_s, P_s`` of the same state, whose data include the filter's, the smoother's
  error is uncorrelated with the difference (the smoother is the conditional mean given more
  data), so ``x_f - x_s`` has covariance ``P_f - P_s`` and ``d = (x_f - x_s)' (P_f -
  P_s)^-1 (x_f - x_s)`` is chi-square with the state's dimension. Where ``P_f - P_s`` is not
  positive definite (the smoother claims less than the filter), ``d`` is left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Innovations:
    """A filter's innovations, one row per measurement it was handed: the time ``t (M,)`` (s),
    the innovation ``nu (M, m)`` (measurement minus its prediction; angles wrapped) and its
    predicted covariance ``S (M, m, m)``. A NaN row is a measurement the filter left out with no
    innovation (a failed update).

    Optional, for the truth-free diagnosis (:mod:`workbench.metrics.diagnosis`): ``kept (M,)``,
    False for a measurement the filter left out although it had its innovation (a gate: the row
    keeps the innovation it was judged on, so what the gate dropped can be weighed too); ``R (M,
    m, m)``, the measurement noise part of each ``S`` (the rest is the state's predicted
    uncertainty, ``H P H'``: the two tell a too narrow motion noise from a too narrow measurement
    noise); ``gate``, the probability of the filter's chi-square gate (0.99: it expects to leave 1 %
    of the measurements out), None without a gate; ``outlier``, the outlier model the filter
    assumed, ``(rate, density)``: a measurement is, with probability ``rate``, drawn from a flat
    density ``density`` (``1 / (2 pi)`` for a bearing; a contaminated Gaussian), None without."""

    t: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    kept: np.ndarray | None = None
    R: np.ndarray | None = None
    gate: float | None = None
    outlier: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, float).ravel()
        nu = np.asarray(self.nu, float)
        m = nu.shape[-1] if nu.ndim == 2 else max(1, nu.size // max(len(self.t), 1))
        self.nu = nu.reshape(len(self.t), m)
        self.S = np.asarray(self.S, float).reshape(len(self.t), m, m)
        if self.kept is not None:
            self.kept = np.asarray(self.kept, bool).ravel()
        if self.R is not None:
            self.R = np.asarray(self.R, float).reshape(len(self.t), m, m)

    @classmethod
    def scalar(cls, t: np.ndarray, nu: np.ndarray, var: np.ndarray, kept: np.ndarray | None = None,
               r: np.ndarray | None = None, gate: float | None = None,
               outlier: tuple[float, float] | None = None) -> Innovations:
        """Scalar measurements (a bearing): innovations and their variances (``r``: the
        measurement noise's part of each)."""
        return cls(t, np.asarray(nu, float)[:, None], np.asarray(var, float)[:, None, None], kept,
                   None if r is None else np.asarray(r, float)[:, None, None], gate, outlier)

    @property
    def dimension(self) -> int:
        return int(self.nu.shape[1])

    @property
    def finite(self) -> np.ndarray:
        """The measurements with an innovation (used or gated)."""
        return np.isfinite(self.nu).all(axis=1) & np.isfinite(self.S).all(axis=(1, 2))

    @property
    def used(self) -> np.ndarray:
        """The measurements the filter used (not left out)."""
        ok = self.finite
        return ok if self.kept is None else ok & self.kept

    def nis_all(self) -> np.ndarray:
        """``nu' S^-1 nu`` of every measurement with an innovation, the ones a gate left out too
        (NaN where there is none or ``S`` is not positive definite)."""
        out = np.full(len(self.t), np.nan)
        ok = self.finite
        if ok.any():
            S = 0.5 * (self.S[ok] + np.swapaxes(self.S[ok], -1, -2))
            pd = np.linalg.eigvalsh(S).min(axis=-1) > 0
            idx = np.flatnonzero(ok)[pd]
            solved = np.linalg.solve(self.S[idx], self.nu[idx][..., None])[..., 0]
            out[idx] = np.einsum("ki,ki->k", self.nu[idx], solved)
        return out

    def state_share(self) -> np.ndarray | None:
        """Each measurement's share of its innovation covariance that is the state's predicted
        uncertainty, ``tr((S - R) S^-1) / m`` (0: all measurement noise, 1: all the state's), or
        None where ``R`` is not given."""
        if self.R is None:
            return None
        out = np.full(len(self.t), np.nan)
        ok = self.finite & np.isfinite(self.R).all(axis=(1, 2))
        if ok.any():
            RS = np.linalg.solve(self.S[ok], self.R[ok])  # S^-1 R: its trace over m is R's share
            out[ok] = 1.0 - np.trace(RS, axis1=1, axis2=2) / self.dimension
        return np.clip(out, 0.0, 1.0)

    @property
    def valid(self) -> np.ndarray:
        """The used measurements whose ``S`` is positive definite (a filter whose covariance turned
        indefinite can predict a negative variance: no NIS, whiteness or likelihood of those)."""
        ok = self.used
        out = np.zeros(len(self.t), bool)
        if ok.any():
            S = 0.5 * (self.S[ok] + np.swapaxes(self.S[ok], -1, -2))
            out[ok] = np.linalg.eigvalsh(S).min(axis=-1) > 0
        return out

    def nis(self) -> np.ndarray:
        """``nu' S^-1 nu`` per measurement (NaN where left out or ``S`` is not positive definite)."""
        out = np.full(len(self.t), np.nan)
        ok = self.valid
        if ok.any():
            out[ok] = np.einsum("ki,ki->k", self.nu[ok], np.linalg.solve(self.S[ok], self.nu[ok][..., None])[..., 0])
        return out

    def whitened(self) -> np.ndarray:
        """``L^-1 nu`` with ``S = L L'`` (Cholesky), rows of the used measurements: unit
        covariance where the filter is consistent."""
        ok = self.valid
        L = np.linalg.cholesky(self.S[ok])
        return np.linalg.solve(L, self.nu[ok][..., None])[..., 0]

    def nll(self) -> np.ndarray:
        """Each used measurement's term of ``-log p(z)`` (NaN where left out or ``S`` is not
        positive definite)."""
        out = np.full(len(self.t), np.nan)
        ok = self.valid
        if ok.any():
            _, logdet = np.linalg.slogdet(self.S[ok])
            out[ok] = 0.5 * (self.dimension * np.log(2.0 * np.pi) + logdet + self.nis()[ok])
        return out

    def mixture_nll(self) -> np.ndarray:
        """Each measurement's term of ``-log p(z)`` under the outlier model the filter assumed,
        ``-log((1 - rate) N(nu; 0, S) + rate density)``, for every measurement with an innovation,
        the ones the filter left out too: under a contaminated model a measurement left out is
        still one the model explains, as an outlier, and is charged what the model says of it (no
        gate can win the likelihood). :meth:`nll` without an outlier model."""
        if not self.outlier or self.outlier[0] <= 0.0:
            return self.nll()
        rate, density = self.outlier
        out = np.full(len(self.t), np.nan)
        q = self.nis_all()
        ok = np.isfinite(q)
        if ok.any():
            _, logdet = np.linalg.slogdet(self.S[ok])
            core = np.log1p(-rate) - 0.5 * (self.dimension * np.log(2.0 * np.pi) + logdet + q[ok])
            out[ok] = -np.logaddexp(core, math.log(rate * density))
        return out

    def charged_nll(self) -> np.ndarray:
        """:meth:`nll` with each measurement the filter left out (a gate) charged the term of the
        least likely one it kept: a gated measurement is at least that improbable under the
        filter's model. Without the charge a filter told a smaller noise gates more and its sum
        falls for that alone, so a likelihood could be won by leaving the data out."""
        out = self.nll()
        kept = out[np.isfinite(out)]
        if kept.size:
            out[~self.used] = kept.max()
        return out


def autocorrelation(white: np.ndarray, lags: int) -> np.ndarray:
    """The normalised sample autocorrelation ``rho(l)``, ``l = 1..lags``, of a whitened sequence
    ``(N, m)`` (each component's, pooled: the sums run over the components too)."""
    x = np.asarray(white, float).reshape(len(white), -1)
    out = np.full(lags, np.nan)
    for lag in range(1, min(lags, len(x) - 1) + 1):
        a, b = x[:-lag], x[lag:]
        den = np.sqrt(np.sum(a * a) * np.sum(b * b))
        out[lag - 1] = np.sum(a * b) / den if den > 0 else np.nan
    return out


def whiteness(innovations: Innovations, lags: int = 20) -> tuple[np.ndarray, float]:
    """The autocorrelation of the innovations at lags ``1..lags`` and its 95 % band half-width
    ``1.96 / sqrt(N)`` (``N`` measurements used)."""
    white = innovations.whitened()
    return autocorrelation(white, lags), 1.96 / np.sqrt(max(len(white), 1))


def disagreement(x_f: np.ndarray, P_f: np.ndarray, x_s: np.ndarray, P_s: np.ndarray,
                 angles: tuple[int, ...] = ()) -> np.ndarray:
    """``(x_f - x_s)' (P_f - P_s)^-1 (x_f - x_s)`` per row (``(K, n)``, ``(K, n, n)``); the
    components ``angles`` wrapped; NaN where either is missing or ``P_f - P_s`` is not positive
    definite."""
    d = np.asarray(x_f, float) - np.asarray(x_s, float)
    for i in angles:
        d[:, i] = (d[:, i] + np.pi) % (2 * np.pi) - np.pi
    C = np.asarray(P_f, float) - np.asarray(P_s, float)
    out = np.full(len(d), np.nan)
    ok = np.isfinite(d).all(axis=1) & np.isfinite(C).all(axis=(1, 2))
    if ok.any():
        C = 0.5 * (C + np.swapaxes(C, -1, -2))
        pd = np.zeros(len(d), bool)
        pd[ok] = np.linalg.eigvalsh(C[ok]).min(axis=-1) > 1e-12 * np.abs(C[ok]).max(axis=(-1, -2))
        if pd.any():
            out[pd] = np.einsum("ki,ki->k", d[pd], np.linalg.solve(C[pd], d[pd][..., None])[..., 0])
    return out


def residual(r: np.ndarray, R: np.ndarray, HPH: np.ndarray | None = None) -> np.ndarray:
    """Each measurement's normalised squared residual at an estimate that used it, ``r' (R - H P
    H')^-1 r`` per row (``r (K, m)``, ``R, HPH (K, m, m)``; NaN where a term is missing or ``R -
    H P H'`` is not positive definite). With the estimate's own covariance ``P`` (a filter's after
    the update, a smoother's) the residual ``z - h(x^)`` of a consistent estimator has covariance
    ``R - H P H'`` (the estimate moved towards the measurement: the post-fit residual of linear least
    squares, Bar-Shalom, Li, Kirubarajan, sec. 3.4, which a smoother is; a filter's update, with
    ``P = (I - K H) P^-``, gives ``R - H P H' = R S^-1 R`` by the same algebra), so the figure is
    chi-square with ``m`` degrees of freedom.
    Without ``HPH`` it is ``r' R^-1 r``: for an estimate that says nothing of its uncertainty, a
    figure to compare, not a test (its expectation lies between ``m - tr(R^-1 H P H')`` and ``m``)."""
    r = np.asarray(r, float)
    return disagreement(r, R, np.zeros_like(r), np.zeros_like(R) if HPH is None else HPH)


def below(P_f: np.ndarray, P_s: np.ndarray, tolerance: float = 1e-6) -> np.ndarray:
    """1 where a causal estimator's covariance ``P_f`` is below the smoother's ``P_s`` in some
    direction (``P_f - P_s`` has an eigenvalue under ``-tolerance`` times the larger covariance's
    largest), 0 where it is not, NaN where either is missing. The smoother uses all the data the
    filter used and more, so with both consistent ``P_f >= P_s`` (the difference is the covariance of
    the filter's estimate about the smoother's, Rauch, Tung, Striebel 1965): a filter below it
    claims a certainty the data do not give, and its :func:`disagreement` has no weight there."""
    P_f, P_s = np.asarray(P_f, float), np.asarray(P_s, float)
    out = np.full(len(P_f), np.nan)
    ok = np.isfinite(P_f).all(axis=(1, 2)) & np.isfinite(P_s).all(axis=(1, 2))
    if ok.any():
        C = P_f[ok] - P_s[ok]
        C = 0.5 * (C + np.swapaxes(C, -1, -2))
        scale = np.maximum(np.abs(P_f[ok]).max(axis=(1, 2)), np.abs(P_s[ok]).max(axis=(1, 2)))
        out[ok] = (np.linalg.eigvalsh(C).min(axis=-1) < -tolerance * scale).astype(float)
    return out


MISS_SIGMAS = 3.0   # a row this many (robust) sigmas off its landmark's place misses it
MISS_LEAST = 5      # a landmark with fewer rows than this has no median to read


@dataclass
class Residuals:
    """A least-squares smoother's residuals at its answer, one row per measurement or constraint
    it was handed, by group (``"odometry"``, ``"bearing"``): ``group (M,)`` its name, ``r2 (M,)``
    the squared whitened residual ``r' R^-1 r`` at the answer (NaN where it has none: a bearing of a
    landmark not in the map), ``dof (M,)`` its dimension, ``used (M,)`` whether the fit counted it
    (False: a gate left it out; its ``r2`` is still the answer's residual), ``redundancy``: each
    group's redundancy number over the rows used, ``sum (1 - h_ii)`` with ``h_ii`` the hat matrix's
    diagonal (Förstner 1979: the expectation of the group's ``sum r2`` at a consistent answer; the
    groups' redundancies add up to the residuals less the unknowns), and ``gate``: the probability
    of the smoother's chi-square gate, None without one; ``measurement``: the group whose rows are
    the measurements (the ones a gate judges, whose tails the diagnosis weighs); ``landmark (M,)``,
    optional: the landmark (map index) a row measures, -1 for the rest."""

    group: np.ndarray
    r2: np.ndarray
    dof: np.ndarray
    used: np.ndarray
    redundancy: dict[str, float]
    gate: float | None = None
    measurement: str = "bearing"
    landmark: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.group = np.asarray(self.group).astype(str).ravel()
        self.r2 = np.asarray(self.r2, float).ravel()
        self.dof = np.asarray(self.dof, int).ravel()
        self.used = np.asarray(self.used, bool).ravel()
        self.redundancy = {str(k): float(v) for k, v in self.redundancy.items()}
        if self.landmark is not None:
            self.landmark = np.asarray(self.landmark, int).ravel()

    def contradicted(self, sigmas: float = MISS_SIGMAS, least: int = MISS_LEAST) -> list[int]:
        """The landmarks over half of whose rows miss them (:meth:`missed`): their own measurements
        reject the place they were given."""
        return [lm for lm, share in self.missed(sigmas, least).items() if share > 0.5]

    def missed(self, sigmas: float = MISS_SIGMAS, least: int = MISS_LEAST) -> dict[int, float]:
        """Each landmark's share of its rows beyond ``sigmas`` at the answer (landmark -> share),
        for the landmarks with at least ``least`` rows (none without ``landmark``): over a half, the
        landmark's own measurements reject the place it was given (their median misses it). The
        sigmas are the rows' own robust scale (their median ``r2`` over chi-square's median for
        their dimension), so a noise told too narrow does not make every landmark missed, nor one
        told too wide none (MRCLAM 6 robot 1 told a bearing sigma 0.58 deg: 12 of 12 read at the
        told sigma)."""
        from scipy.stats import chi2

        if self.landmark is None:
            return {}
        rows = (self.landmark >= 0) & np.isfinite(self.r2)
        if not rows.any():
            return {}
        scale = float(np.median(self.r2[rows] / chi2.median(self.dof[rows])))
        if not scale > 0:
            return {}
        lm, miss = self.landmark[rows], (self.r2[rows] / scale > sigmas**2 * self.dof[rows]).astype(float)
        seen = np.bincount(lm)
        share = np.bincount(lm, weights=miss) / np.maximum(seen, 1)
        return {int(i): float(share[i]) for i in np.flatnonzero(seen >= least)}
