"""What an estimator's normalised squared innovations or residuals say of the noise it assumed,
with no truth: maximum likelihood of a noise scale, of a heavy tail and of each group's scale,
over every measurement it was handed, the ones its gate left out included.

**The model.** A consistent estimator's normalised squared innovation ``q = nu' S^-1 nu`` of an
``m``-dimensional measurement is chi-square with ``m`` degrees of freedom (Bar-Shalom, Li,
Kirubarajan, *Estimation with Applications to Tracking and Navigation*, sec. 5.4.2). Where the
noise it assumed is ``k`` times too small in variance, ``q / k`` is. Its whole distribution is
fitted, not only its mean (Chen et al., "Weak in the NEES?: Auto-tuning Kalman filters with
Bayesian optimization", FUSION 2018, and arXiv 2306.07225 on testing the NIS's distribution):

    q ~ (1 - eps) k chi2_m + eps c k chi2_m,     c >= 9

a scale mixture of the chi-square: ``k`` the noise's variance factor, ``eps`` the share of a
heavy tail (outliers, misreads, a heavier-tailed noise) ``c`` times wider, at most half (the core
is the measurements the model explains) (a Gaussian scale
mixture, the form of the Student-t and the contaminated Gaussian). With ``share`` (each
measurement's share of ``S`` that is the state's predicted uncertainty ``H P H'``, the rest the
measurement noise ``R``), the scale is split, ``k = a share + b (1 - share)``: ``a`` the factor of
the state's (the motion noise's) and ``b`` of the measurement noise's variance, apart wherever
the shares vary over the log.

**Censoring.** A measurement left out with no innovation (a gate that does not say what it
judged) enters as ``P(q > g)``, ``g`` its gate: a fit over the measurements kept alone would be
the gate's truncated distribution, which gating fools (a filter that dropped 87 % of a log can
show a NIS of 1 over the rest).

The intervals are the inverse of the negative log-likelihood's Hessian in the log-parameters
(the Fisher information, as LowLevelParticleFilters.jl's ``autotune_covariances`` gives). They
treat the innovations as independent, which a misfit filter's are not (its whiteness test says
so), so they are narrow; the diagnosis that reads them asks a practical size of a factor too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, special, stats

TAIL_MIN = 9.0
"""The heavy tail's variance is at least this times the core's (three times the sigma: what lies
beyond three sigma is the outliers' usual reading; a narrower one is the core's own spread, as
uneven leverage or a nonlinearity widens it, not a tail)."""
MAX_ROWS = 20000
"""A fit reads at most this many rows, drawn at random (seeded: the same rows every time) where
there are more: the factors' intervals are then about 1 %, far inside the 25 % a diagnosis reads,
and a 1,000-run sweep's statistics stay fast. Not every n-th: rows in a periodic order (the
steps of each run, each run's first steps the ones that tell the state's share) alias."""


@dataclass
class ScaleFit:
    """A fitted noise model: the variance factors (``k``, or ``a`` of the state and ``b`` of the
    measurement noise where split), the heavy tail's share ``eps`` and width ``c``, each factor's
    95 % interval, the negative log-likelihood and the rows read."""

    k: float
    eps: float = 0.0
    c: float = 1.0
    a: float | None = None
    b: float | None = None
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    nll: float = 0.0
    rows: int = 0


def _logpdf(q: np.ndarray, m: np.ndarray, s: np.ndarray) -> np.ndarray:
    """log density of ``q`` where ``q / s`` is chi-square with ``m`` degrees of freedom."""
    x = q / s
    return (0.5 * m - 1.0) * np.log(np.maximum(x, 1e-300)) - 0.5 * x - 0.5 * m * math.log(2.0) \
        - special.gammaln(0.5 * m) - np.log(s)


class _Data:
    def __init__(self, q, dof, share, censored_at):
        q = np.asarray(q, float)
        dof = np.broadcast_to(np.asarray(dof, float), q.shape)
        share = None if share is None else np.broadcast_to(np.asarray(share, float), q.shape)
        g = np.broadcast_to(np.asarray(np.inf if censored_at is None else censored_at, float), q.shape)
        seen = np.isfinite(q) & (dof > 0)
        cens = ~np.isfinite(q) & np.isfinite(g) & (dof > 0)
        if share is not None:
            seen &= np.isfinite(share)
            cens &= np.isfinite(share)
        keep = seen | cens
        idx = np.flatnonzero(keep)
        if len(idx) > MAX_ROWS:
            idx = np.sort(np.random.default_rng(0).choice(idx, MAX_ROWS, replace=False))
        self.q, self.m, self.g = q[idx], dof[idx], g[idx]
        self.seen = seen[idx]
        self.share = None if share is None else share[idx]
        self.rows = len(idx)

    def scale(self, a: float, b: float) -> np.ndarray:
        return np.full(self.rows, a) if self.share is None else a * self.share + b * (1.0 - self.share)

    def nll(self, a: float, b: float, eps: float, c: float) -> float:
        """The negative log-likelihood (:meth:`nll_grad`'s value)."""
        return self.nll_grad(a, b, eps, c)[0]

    def nll_grad(self, a: float, b: float, eps: float, c: float) -> tuple[float, np.ndarray]:
        """:meth:`nll` and its gradient in ``(a, b, eps, c)`` (``b`` is ``a``'s where not split: its
        part then adds to ``a``'s by the caller's chain rule): the score of each row's mixture,
        ``d log p / d s`` of a chi-square scale, ``(q / 2s - m / 2) / s``, and of its tail beyond a
        gate, ``x^(m/2) e^-x / (Gamma(m/2) Q s)``, ``x = g / 2s``."""
        s = self.scale(a, b)
        value, ds, de, dc = 0.0, np.zeros(self.rows), 0.0, 0.0
        for mask, seen in ((self.seen, True), (~self.seen, False)):
            if not mask.any():
                continue
            m, sm = self.m[mask], s[mask]
            x = self.q[mask] if seen else self.g[mask]
            scales = [(sm, 1.0)] + ([(c * sm, c)] if eps > 0.0 else [])
            logs, dlogs = [], []
            for sc, _ in scales:
                if seen:
                    logs.append(_logpdf(x, m, sc))
                    dlogs.append((0.5 * x / sc - 0.5 * m) / sc)  # d log p / d sc
                else:
                    h = 0.5 * x / sc
                    Q = np.maximum(special.gammaincc(0.5 * m, h), 1e-300)
                    logs.append(np.log(Q))
                    dlogs.append(np.exp(0.5 * m * np.log(np.maximum(h, 1e-300)) - h - special.gammaln(0.5 * m))
                                 / (Q * sc))
            if eps > 0.0:
                lc, lt = math.log1p(-eps) + logs[0], math.log(eps) + logs[1]
                both = np.logaddexp(lc, lt)
                wc, wt = np.exp(lc - both), np.exp(lt - both)
                ds[mask] = wc * dlogs[0] + wt * dlogs[1] * c
                de += float(np.sum(wt / eps - wc / (1.0 - eps)))
                dc += float(np.sum(wt * dlogs[1] * sm))
            else:
                both = logs[0]
                ds[mask] = dlogs[0]
            value -= float(np.sum(both))
        if self.share is None:
            da, db = float(np.sum(ds)), 0.0
        else:
            da, db = float(np.sum(ds * self.share)), float(np.sum(ds * (1.0 - self.share)))
        return value, -np.array([da, db, de, dc])


def _hessian(f, x: np.ndarray, h: float = 1e-3) -> np.ndarray:
    n = len(x)
    H = np.zeros((n, n))
    f0 = f(x)
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.eye(n)[i] * h, np.eye(n)[j] * h
            if i == j:
                H[i, i] = (f(x + ei) - 2 * f0 + f(x - ei)) / h**2
            else:
                H[i, j] = H[j, i] = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej) + f(x - ei - ej)) / (4 * h * h)
    return H


def fit(q: np.ndarray, dof: np.ndarray | int, share: np.ndarray | None = None, censored_at: np.ndarray | None = None,
        tail: bool = True) -> ScaleFit | None:
    """Maximum likelihood of the noise's variance factor(s) and heavy tail from normalised squared
    innovations ``q`` (NaN: left out with none, censored at ``censored_at``), their degrees of
    freedom ``dof``; ``share`` splits the factor into the state's and the measurement noise's
    (:mod:`module text <.noisefit>`); ``tail=False`` fits the Gaussian alone. None with no rows."""
    d = _Data(q, dof, share, censored_at)
    if d.rows == 0 or not d.seen.any():
        return None
    split = d.share is not None and float(np.std(d.share)) > 0.02
    k0 = float(np.median(d.q[d.seen] / d.m[d.seen]) / (1.0 - 2.0 / (9.0 * np.median(d.m))) ** 3)  # robust start
    k0 = max(k0, 1e-12)

    def unpack(x):
        a = math.exp(x[0])
        b = math.exp(x[1]) if split else a
        rest = x[2:] if split else x[1:]
        eps = special.expit(rest[0]) if tail else 0.0
        c = TAIL_MIN + math.exp(rest[1]) if tail else 1.0
        return a, b, eps, c

    def f(x):
        return d.nll(*unpack(x))

    def f_and_grad(x):  # the gradient in the log-parameters, by the chain rule
        a, b, eps, c = unpack(x)
        value, (ga, gb, ge, gc) = d.nll_grad(a, b, eps, c)
        g = [ga * a] + ([gb * b] if split else [])
        if not split:
            g[0] += gb * a
        if tail:
            g += [ge * eps * (1.0 - eps), gc * (c - TAIL_MIN)]
        return value, np.array(g)

    x0 = [math.log(k0)] + ([math.log(k0)] if split else []) + ([special.logit(0.05), math.log(20.0)] if tail else [])
    best = None
    starts = [np.array(x0)]
    if tail:  # a start where the tail is most of the data too (the core then the few that fit)
        starts.append(np.array([math.log(k0) - 1.0] * (2 if split else 1) + [special.logit(0.45), math.log(20.0)]))
    for s in starts:
        # converged far below the figures' last printed digit: a replay on another processor, whose
        # arithmetic moves the data in their last bits, then finds the same optimum to 1e-9
        r = optimize.minimize(f_and_grad, s, jac=True, method="L-BFGS-B",
                              options={"ftol": 1e-15, "gtol": 1e-9, "maxiter": 500},
                              bounds=[(-30, 30)] * (2 if split else 1) + ([(-12, 0.0), (-8, 14)] if tail else []))
        if best is None or r.fun < best.fun:
            best = r
    a, b, eps, c = unpack(best.x)
    out = ScaleFit(k=float(np.mean(d.scale(a, b))), eps=float(eps), c=float(c),  # split: the mean factor
                   a=a if split else None, b=b if split else None, nll=float(best.fun), rows=d.rows)
    try:
        H = _hessian(f, best.x)
        names = ["a", "b"] if split else ["k"]
        # a factor the likelihood no longer feels (driven to its bound, 0: its share of every row
        # nought) is held there, and the others' intervals are the rest's information alone: the
        # profile at the boundary (inverting with it in, its near-zero curvature swamps the others'
        # in rounding, whose last bits differ from one processor's kernels to another's)
        d_h = np.abs(np.diag(H))
        free = np.flatnonzero(d_h > 1e-9 * max(float(d_h.max()), 1e-300))
        var = np.full(len(H), np.inf)
        try:
            var[free] = np.diag(np.linalg.inv(H[np.ix_(free, free)]))
        except np.linalg.LinAlgError:
            var[free] = -1.0
        for i, name in enumerate(names):
            if not var[i] > 0:  # a singular information (a factor at its bound: 0): its own curvature, the others held
                var[i] = 1.0 / H[i, i] if H[i, i] > 0 else np.inf
            sd = min(math.sqrt(var[i]), 50.0)  # (an unidentified factor's: any width says so)
            v = math.exp(best.x[i])
            out.intervals[name] = (v * math.exp(-1.96 * sd), v * math.exp(1.96 * sd))
    except ValueError:
        pass
    return out


def tail_test(q: np.ndarray, dof: np.ndarray | int, share: np.ndarray | None = None,
              censored_at: np.ndarray | None = None) -> tuple[ScaleFit | None, ScaleFit | None, float]:
    """The Gaussian fit, the fit with a heavy tail, and the likelihood ratio's p-value of the tail
    (chi-square with 2 degrees of freedom: conservative at the boundary ``eps = 0``)."""
    plain = fit(q, dof, share, censored_at, tail=False)
    heavy = fit(q, dof, share, censored_at, tail=True)
    if plain is None or heavy is None:
        return plain, heavy, 1.0
    lr = max(0.0, 2.0 * (plain.nll - heavy.nll))
    return plain, heavy, float(stats.chi2.sf(lr, 2))


def variance_components(r2: np.ndarray, redundancy: float) -> tuple[float, tuple[float, float]] | None:
    """A group's variance factor from a least-squares adjustment's residuals (Förstner 1979;
    Koch, *Parameter Estimation and Hypothesis Testing in Linear Models*, sec. 3.6): ``sum r2 /
    redundancy``, whose expectation is 1 where the group's noise is what the model says; its 95 %
    interval from ``redundancy * factor`` being chi-square with ``redundancy`` degrees of freedom.
    None where the group has no redundancy."""
    r2 = np.asarray(r2, float)
    r2 = r2[np.isfinite(r2)]
    if redundancy <= 1.0 or not len(r2):
        return None
    s = float(np.sum(r2)) / redundancy
    lo, hi = stats.chi2.ppf([0.975, 0.025], redundancy)
    return s, (s * redundancy / lo, s * redundancy / hi)


GOF_ROWS = 5000
"""The goodness-of-fit tests read at most this many rows (drawn at random, seeded): their p-values are figures
to read beside the verdict, which the likelihood decides."""


def goodness_of_fit(q: np.ndarray, dof: np.ndarray, k: float) -> dict:
    """The Cramér-von Mises test of the normalised squared innovations of every measurement with
    one (those a gate left out too) against chi-square with their dimension (``gof_p``: the
    whole distribution, not its mean: Chen et al. 2018), and against it scaled by the Gaussian fit's
    factor ``k`` (``gof_scaled_p``: whether a scale alone explains the shape); none where the
    dimensions differ or a left-out measurement has no figure."""
    seen = np.isfinite(q)
    if not seen.any() or (~seen).any() or len(np.unique(dof[seen])) != 1:
        return {}
    x = q[seen]
    if len(x) > GOF_ROWS:  # drawn at random, seeded (every n-th would alias with the runs' steps)
        x = x[np.sort(np.random.default_rng(0).choice(len(x), GOF_ROWS, replace=False))]
    m = float(dof[seen][0])
    return {"gof_p": float(stats.cramervonmises(x, stats.chi2(m).cdf).pvalue),
            "gof_scaled_p": float(stats.cramervonmises(x / k, stats.chi2(m).cdf).pvalue)}
