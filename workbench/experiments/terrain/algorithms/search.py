"""Recurrent-search estimation (the paper's (2)-(4)): a bank of Kalman filters, one per
hypothesis D_pq about the mean of the navigation errors, run over the node points of image I;
the hypothesis with the least functional I_pq wins.

Measurement model (the paper's observation equation, read per ``spec/terrain.md``): for a
node ``(u, v)`` of image I (every ``node_step``-th pixel), the orientation corrected by the
state gives its ground point on the DEM (1, inverse), which projects into image II (1,
forward); image II is read there bilinearly. ``Z_k`` is image I's irradiance, ``F`` image
II's, and ``H_k = grad f_II . d(u, v)/dX`` (the projection's derivative, through the ground
point's dependence on image I's orientation in the common-error mode).

Readings taken:

* The linearisation is held per hypothesis at its cell centre ``m_pq`` (the spec's "with the
  linearisation held per hypothesis"), so the innovation (2) is
  ``Delta_k = Z_k - F(m_pq) - H_k (X^_k|k-1 - m_pq)``.
* The state does not move from node to node (A = I inside the bank; the dynamics between the
  exposures are in the measurement function, see ``navigation``).
* In (4) the log-determinant term is read ``eps_k = ln(|Gamma_k|k-1| |R| / |Gamma_k|)`` with the
  *posterior* at node k in the denominator: that is ``ln |HGH' + R|``, the Gaussian likelihood's
  term. Read literally (``Gamma_{k-1}``, which equals ``Gamma_k|k-1`` when A = I) it would be
  ``ln |R|`` for every hypothesis and carry no information.
* The prior probabilities P_pq are equal, so their term is left out (it would add a constant).
* Nodes: those of image I that land inside image II, with a margin for the largest error, under
  the measured orientation; the same node set for every hypothesis, so functionals compare.
* Radiometry: (2) compares irradiances as if both exposures recorded the same one; real
  frames do not, so image II is first put on image I's scale (``--radiometry``, default
  ``local`` on the real frames; :mod:`.radiometry`, which gives the measurements). Without it, on ngi 0251/0253
  (common mode) the offset drove the refinement 60-110 m off in height.

The batch form: with the linearisation fixed, the sequential filter's functional equals
``r'r/R - b'(G^-1 + H'H/R)^-1 b + N ln R + ln|G| - ln|Gamma_N|`` with ``b = H'r/R`` (the
information form and Woodbury's identity), and the refined state is ``m + Gamma_N b``. It needs
only the node sums ``H'H``, ``H'r``, ``r'r``: the compiled kernel (``fused``) accumulates them
node block by node block for each hypothesis, in parallel over the hypotheses of a chunk, so
memory does not grow with hypotheses x nodes. :func:`linearise` is the NumPy reference of the
same measurement model (it keeps every node's terms, for the literal recursion and the tests).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from workbench.errors import require
from workbench.experiments.terrain import camera
from workbench.experiments.terrain.algorithms.searchspace import (
    Hypotheses,
    Problem,
    bilinear,
    gradient_stack,
    hypotheses,
    make_problem,
)

__all__ = ["ARRAYS_PER_NODE", "CHUNK", "Hypotheses", "Problem", "SearchResult", "batch", "batch_from_sums",
           "bilinear", "chunk_size", "gradient_stack", "hypotheses", "iterate", "linearise", "literal",
           "make_problem", "rows", "run", "sums"]
"""The search, with the search space it is set up from (:mod:`.searchspace`, its names kept here)."""

ARRAYS_PER_NODE = 60  # float64 temporaries per node and hypothesis in ``linearise`` (the literal bank's budget)
CHUNK = 125  # hypotheses per chunk of the compiled batch bank (one step of the recording's search timeline)


# --- the measurement model, linearised at each hypothesis -----------------------------------

def _cross(a: list, b: list) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dem_read(p: Problem, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    s = bilinear(p.dem_stack, (x - p.dem.x0) / p.dem.dx, (y - p.dem.y0) / p.dem.dy)
    return s[..., 0], s[..., 1] / p.dem.dx, s[..., 2] / p.dem.dy


def linearise(p: Problem, centres: np.ndarray, newton: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """``r0 = Z - F(m)`` ``(c, N)`` and ``H = dF/dX`` at ``m`` ``(c, n, N)`` for centres ``(c, n)``,
    computed component by component (derivatives of the rotation as cross products:
    ``dR/da = [w_a]x R``). In the common-error mode the ground point of every node is found
    again for each hypothesis (``newton`` Newton steps from the measured orientation's height;
    two leave a mean irradiance difference of ~3e-4 against eight, far below R's 0.05)."""
    c = len(centres)
    err = np.einsum("ern,cn->cer", p.m, centres)                         # (c, 2, 6)
    pos = p.position[None] - err[..., :3]
    ang = p.angles[None] - err[..., 3:]
    rot = camera.rotation(ang)                               # (c, 2, 3, 3)
    w = camera.axes(ang)                                     # (c, 2, 3 angles, 3)
    ray = p.k.rays(p.nodes[:, 0], p.nodes[:, 1])             # (N, 3)
    moves_i = bool(np.any(p.m[0]))
    ci = c if moves_i else 1

    def col(a: np.ndarray) -> np.ndarray:                                # (ci,) -> (ci, 1)
        return a[:, None]

    d = [col(rot[:ci, 0, i, 0]) * ray[:, 0] + col(rot[:ci, 0, i, 1]) * ray[:, 1] + col(rot[:ci, 0, i, 2])
         for i in range(3)]
    o = [col(pos[:ci, 0, i]) for i in range(3)]
    if moves_i:
        t = (o[2] - p.h0) / -d[2]
        for _ in range(newton):
            x, y = o[0] + t * d[0], o[1] + t * d[1]
            h, hx, hy = _dem_read(p, x, y)
            t = t - (o[2] + t * d[2] - h) / (d[2] - hx * d[0] - hy * d[1])
        g = [o[i] + t * d[i] for i in range(3)]
        corners = (np.array([g[0].min(), g[0].max(), g[0].min(), g[0].max()]),
                   np.array([g[1].min(), g[1].min(), g[1].max(), g[1].max()]))
        require(bool(np.all(p.dem.covers(*corners))), "the DEM does not cover image I's footprint under a hypothesis")
    else:
        t = p.t0[None]
        g = [o[i] + t * d[i] for i in range(3)]
    q = [g[i] - col(pos[:, 1, i]) for i in range(3)]                   # (c, N)
    r2 = rot[:, 1]
    pc = [col(r2[:, 0, j]) * q[0] + col(r2[:, 1, j]) * q[1] + col(r2[:, 2, j]) * q[2] for j in range(3)]
    inv = 1.0 / pc[2]
    u = p.k.cx + p.k.fx * pc[0] * inv
    v = p.k.cy + p.k.fy * pc[1] * inv
    s = bilinear(p.image2, u, v)
    r0 = p.z[None] - s[..., 0]
    gu, gv = s[..., 1] * p.k.fx * inv, s[..., 2] * p.k.fy * inv
    gp = [gu, gv, -(gu * pc[0] + gv * pc[1]) * inv]                      # dF/dp (camera II frame)
    dfdg = [col(r2[:, i, 0]) * gp[0] + col(r2[:, i, 1]) * gp[1] + col(r2[:, i, 2]) * gp[2] for i in range(3)]
    jac: dict[tuple[int, int], np.ndarray] = {}
    cr = _cross(dfdg, q)                                                 # dF/dangle_a = w_a . (dfdg x q)
    for i in range(3):
        jac[1, i] = -dfdg[i]
        jac[1, 3 + i] = col(w[:, 1, i, 0]) * cr[0] + col(w[:, 1, i, 1]) * cr[1] + col(w[:, 1, i, 2]) * cr[2]
    if moves_i:
        a = [hx, hy, -np.ones_like(hx)]
        ratio = (d[0] * dfdg[0] + d[1] * dfdg[1] + d[2] * dfdg[2]) / (a[0] * d[0] + a[1] * d[1] + a[2] * d[2])
        y = [dfdg[i] - a[i] * ratio for i in range(3)]                   # dF/dw, w = dC + t dR ray
        cr1 = _cross(d, y)                                               # dF/dangle_a = t w_a . (d x y)
        for i in range(3):
            jac[0, i] = y[i]
            jac[0, 3 + i] = t * (col(w[:, 0, i, 0]) * cr1[0] + col(w[:, 0, i, 1]) * cr1[1]
                                 + col(w[:, 0, i, 2]) * cr1[2])
    h_out = np.zeros((c, p.n, len(p.nodes)))
    for (e, comp), val in jac.items():                                   # H = -J M (error = measured - true)
        for kk in np.flatnonzero(p.m[e, comp]):
            coef = p.m[e, comp, kk]
            h_out[:, kk] -= coef * val
    return r0, h_out


# --- the filter bank: literal recursion and batch form -------------------------------------

def literal(r0: np.ndarray, h: np.ndarray, centre: np.ndarray, prior: np.ndarray, r: float
            ) -> tuple[float, np.ndarray, np.ndarray]:
    """The paper's (2)-(4) node by node for one hypothesis (``r0 (N,)``, ``h (n, N)``):
    functional, state, covariance.

    (2) ``X^_k = X^_k|k-1 + K_k Delta_k``, ``K_k = Gamma_k H_k' R^-1``; (3) the Riccati update;
    (4) ``I_k = I_k-1 + Delta_k' Sigma_k^-1 Delta_k + eps_k`` with the paper's
    ``Sigma_k^-1 = R^-1 - R^-1 H_k Gamma_k H_k' R^-1`` (the innovation covariance's inverse
    by the matrix inversion lemma) and ``eps_k`` as read in the module docstring.
    """
    x = np.array(centre, float)
    gam = np.array(prior, float)
    rinv = 1.0 / r
    total = 0.0
    _, logdet_prev = np.linalg.slogdet(gam)
    for k in range(len(r0)):
        hk = h[:, k][None, :]                                            # (1, n)
        delta = r0[k] - (hk @ (x - centre)).item()                         # (2), linearised at m_pq
        s = hk @ gam @ hk.T + r
        gam_post = gam - gam @ hk.T @ np.linalg.inv(s) @ hk @ gam        # (3)
        gain = gam_post @ hk.T * rinv
        x = x + gain[:, 0] * delta
        sigma_inv = rinv - rinv * (hk @ gam_post @ hk.T).item() * rinv     # (4)
        _, logdet_post = np.linalg.slogdet(gam_post)
        eps = logdet_prev + math.log(r) - logdet_post
        total += delta * sigma_inv * delta + eps
        gam, logdet_prev = gam_post, logdet_post                         # A = I: Gamma_k+1|k = Gamma_k
    return total, x, gam


def batch(r0: np.ndarray, h: np.ndarray, centres: np.ndarray, prior: np.ndarray, r: float
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same functional for a chunk of hypotheses at once (information form + Woodbury);
    ``r0 (c, N)``, ``h (c, n, N)``. Returns functionals ``(c,)``, refined states ``(c, n)``,
    posterior covariances ``(c, n, n)``."""
    return batch_from_sums(np.matmul(h, h.transpose(0, 2, 1)), np.matmul(h, r0[..., None])[..., 0],
                           np.einsum("cn,cn->c", r0, r0), r0.shape[1], centres, prior, r)


def batch_from_sums(hh: np.ndarray, hr: np.ndarray, rr: np.ndarray, n_nodes: int, centres: np.ndarray,
                    prior: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The batch form from the node sums ``hh = sum H'H (c, n, n)``, ``hr = sum H'r0 (c, n)``,
    ``rr = sum r0^2 (c,)``: ``Gamma_N = (G^-1 + hh/R)^-1``, ``b = hr/R``, the functional
    ``rr/R - b' Gamma_N b + N ln R + ln|G| - ln|Gamma_N|`` and the refined state ``m + Gamma_N b``."""
    ginv = np.linalg.inv(prior)
    info = ginv[None] + hh / r
    b = hr / r
    gam = np.linalg.inv(info)
    gam = 0.5 * (gam + gam.transpose(0, 2, 1))
    gb = np.einsum("cij,cj->ci", gam, b)
    quad = rr / r - np.einsum("ci,ci->c", b, gb)
    _, logdet_g = np.linalg.slogdet(prior)
    _, logdet_post = np.linalg.slogdet(gam)
    functional = quad + n_nodes * math.log(r) + logdet_g - logdet_post
    return functional, centres + gb, gam


def _kernel_args(p: Problem, centres: np.ndarray) -> tuple:
    """The compiled kernel's inputs for a chunk: rotations, axes and positions per hypothesis,
    the node rays, and ``M``'s nonzeros (row of the 12 pose-error partials, state column, value)."""
    err = np.einsum("ern,cn->cer", p.m, centres)
    pos = np.ascontiguousarray(p.position[None] - err[..., :3])
    ang = p.angles[None] - err[..., 3:]
    e, comp, col = np.nonzero(p.m)
    geo = np.array([p.dem.x0, p.dem.y0, p.dem.dx, p.dem.dy])
    kv = np.array([p.k.fx, p.k.fy, p.k.cx, p.k.cy])
    return (np.ascontiguousarray(camera.rotation(ang)), np.ascontiguousarray(camera.axes(ang)), pos,
            p.node_table, p.image2, p.dem_stack,
            geo, kv, int(np.any(p.m[0])), (e * 6 + comp).astype(np.int64), col.astype(np.int64),
            p.m[e, comp, col].astype(float), p.n)


def sums(p: Problem, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``sum H'H``, ``sum H'r0``, ``sum r0^2`` over the nodes for every centre, by the compiled
    kernel (``fused.sums``): what :func:`linearise` gives, never stored per node."""
    from workbench.experiments.terrain.algorithms import fused

    c = len(centres)
    hh, hr, rr = np.empty((c, p.n, p.n)), np.empty((c, p.n)), np.empty(c)
    bounds = np.empty((c, 4))
    args = _kernel_args(p, centres)
    fused.sums(*args, hh, hr, rr, bounds)
    if args[8]:
        corners = (bounds[:, [0, 1, 0, 1]].ravel(), bounds[:, [2, 2, 3, 3]].ravel())
        require(bool(np.all(p.dem.covers(*corners))), "the DEM does not cover image I's footprint under a hypothesis")
    return hh, hr, rr


def rows(p: Problem, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``r0 (c, N)`` and ``H (c, n, N)`` by the compiled kernel (``fused.rows``), as
    :func:`linearise` gives them."""
    from workbench.experiments.terrain.algorithms import fused

    r0, h = np.empty((len(centres), len(p.nodes))), np.empty((len(centres), p.n, len(p.nodes)))
    fused.rows(*_kernel_args(p, centres), r0, h)
    return r0, h


@dataclass
class SearchResult:
    centres: np.ndarray       # (n_h, n)
    functional: np.ndarray    # (n_h,)
    refined: np.ndarray       # (n_h, n) the filters' final states
    covariance: np.ndarray    # (n_h, n, n) their final covariances Gamma_N
    winner: int
    nodes: int
    chunk: int
    kind: str = "grid"

    @property
    def centre(self) -> np.ndarray:
        """The paper's estimate: the winning cell's centre.

        Its attitude need not beat the navigation system's though its position does. The
        functional judges how well image II is registered on the ground, and at ~5 km up a
        pitch or roll of one angular cell (2 mrad at the default 3 levels of 0.003 rad) moves
        the ground about 10 m, a quarter of a linear cell (40 m at 5 levels of 100 m): the
        winning angles are those that take up the position cell's own quantisation error. ngi
        0182/0184, ii-only, 10 runs (seed 0): the winner's linear cells right in 97 % of the
        axes, its angular cells in 37 % (chance: 33 %; the best hypothesis with every angular
        cell right scores a median 1550 worse), so image II's attitude error is 3.45 mrad
        against the navigation system's 2.82 while its position error is 21 m against 97 and
        its ground error 12.5 m against 90 (synthetic 200 x 200, common mode, seed 4, 5 runs:
        3.65 against 2.86 mrad). The estimator ``recurrent-search`` therefore keeps this
        centre's position and takes its angles from the search's posterior
        (:mod:`.posterior`: 0.48 mrad there)."""
        return self.centres[self.winner]

    @property
    def refinement(self) -> np.ndarray:
        """The winning filter's state: the in-cell refinement."""
        return self.refined[self.winner]


def iterate(p: Problem, centre: np.ndarray, prior: np.ndarray, start: np.ndarray, iterations: int = 10,
            tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray, int]:
    """The winning filter iterated: its update (2)-(3) with the measurement model re-linearised
    at its own estimate until the estimate stops moving (the iterated Kalman filter, Gauss-Newton
    on the cell's prior plus the nodes). With the model linearised at ``x_i`` and the prior
    ``N(centre, G)``: ``x_i+1 = centre + Gamma_i (H_i r0(x_i) + H_i H_i'(x_i - centre)) / R``,
    ``Gamma_i = (G^-1 + H_i H_i'/R)^-1``. Stops when every component moves less than ``tol`` of
    its prior sigma. Returns the state, ``Gamma`` at it, and the iterations taken.

    Not in the paper, whose refinement is one step from the cell centre (:attr:`SearchResult.
    refinement`): a yaw or position error a good part of a cell wide is past the reach of a
    linearisation at the centre, and one step leaves much of it."""
    ginv = np.linalg.inv(prior)
    sigma = np.sqrt(np.diag(prior))
    x = np.array(start, float)
    gam = prior
    for i in range(1, iterations + 1):
        hh, hr, _ = sums(p, x[None])
        gam = np.linalg.inv(ginv + hh[0] / p.r)
        new = centre + gam @ (hr[0] + hh[0] @ (x - centre)) / p.r
        done = bool(np.all(np.abs(new - x) < tol * sigma))
        x = new
        if done:
            return x, 0.5 * (gam + gam.T), i
    return x, 0.5 * (gam + gam.T), iterations


def chunk_size(p: Problem, budget_mb: float, bank: str = "batch") -> int:
    """Hypotheses per chunk. The compiled batch bank holds only ``n x n`` sums per hypothesis, so
    its chunk is ``CHUNK`` (a step of the search's progress); the literal bank stores every
    node's terms, so its chunk is sized to the memory budget."""
    if bank == "batch":
        return CHUNK
    return max(1, int(budget_mb * 1e6 // (len(p.nodes) * ARRAYS_PER_NODE * 8)))


def run(p: Problem, hyp: Hypotheses, bank: str = "batch", budget_mb: float = 256.0,
        progress: Callable[[int], None] | None = None, threads: int = 1) -> SearchResult:
    """Every hypothesis's functional; ``bank='literal'`` runs (2)-(4) node by node on
    :func:`linearise`'s terms (slow; the reference), ``'batch'`` the closed form on the compiled
    kernel's node sums, chunk by chunk, the hypotheses of a chunk shared among ``threads``
    threads."""
    import numba

    from workbench.experiments.terrain.algorithms import fused  # noqa: F401 (sets the threading layer before threads start)

    n_h = len(hyp.centres)
    functional = np.empty(n_h)
    refined = np.empty_like(hyp.centres)
    cov = np.empty((n_h, hyp.centres.shape[1], hyp.centres.shape[1]))
    step = chunk_size(p, budget_mb, bank)
    numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    for lo in range(0, n_h, step):
        sl = slice(lo, min(lo + step, n_h))
        if bank == "literal":
            r0, h = linearise(p, hyp.centres[sl])
            for i, j in enumerate(range(sl.start, sl.stop)):
                functional[j], refined[j], cov[j] = literal(r0[i], h[i], hyp.centres[j], hyp.prior, p.r)
        else:
            hh, hr, rr = sums(p, hyp.centres[sl])
            functional[sl], refined[sl], cov[sl] = batch_from_sums(hh, hr, rr, len(p.nodes), hyp.centres[sl],
                                                                   hyp.prior, p.r)
        if progress:
            progress(sl.stop - sl.start)
    return SearchResult(hyp.centres, functional, refined, cov, int(np.argmin(functional)), len(p.nodes), step,
                        hyp.kind)
