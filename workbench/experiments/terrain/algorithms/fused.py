"""The filter bank's measurement model compiled with Numba: linearisation and the batch form's sums
fused in one pass over the nodes, so nothing of size hypotheses x nodes is ever stored.

For every hypothesis ``m_pq`` and node ``k`` of image I this evaluates what
``search.linearise`` evaluates (the paper's (1) both ways and ``H_k = grad f_II . d(u, v)/dX``):
the innovation at the cell centre ``r0_k = Z_k - F_k(m_pq)`` and the row ``H_k``; and instead of
keeping them, it adds them into the three sums the batch form of (2)-(4) needs,
``sum_k H_k' H_k``, ``sum_k H_k' r0_k`` and ``sum_k r0_k^2`` (float64). The per-node arithmetic
is the reference's, term by term; image II and the DEM are read bilinearly with the edges held,
as ``search.bilinear`` does. ``search.run`` then turns the sums into functionals with
``search.batch_from_sums``.

Why Numba (a dependency added for this): the vectorised NumPy form streams some sixty
hypotheses x nodes temporaries through memory and reaches ~12 % of the machine's 2e10 flop/s;
fused, the same arithmetic stays in registers. Compiled on first use and cached on disk
(``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

# Numba's built-in work queue, not OpenMP: the Monte Carlo runs fork worker processes after the
# first run has used the kernel's threads, and GNU OpenMP aborts a process forked after use.
numba.config.THREADING_LAYER = "workqueue"

BLOCK = 256  # nodes per block: the block's terms stay in the first-level cache


@numba.njit(inline="always", fastmath=True, error_model="numpy")
def _read(stack, x, y):
    """The three channels of ``stack (rows, cols, 3)`` at column ``x``, row ``y``, bilinearly,
    edges held (as ``search.bilinear``)."""
    rows, cols = stack.shape[0], stack.shape[1]
    xc = min(max(x, 0.0), cols - 1.0)
    yc = min(max(y, 0.0), rows - 1.0)
    x0 = min(int(xc), cols - 2)
    y0 = min(int(yc), rows - 2)
    a = xc - x0
    b = yc - y0
    out0 = (1 - b) * ((1 - a) * stack[y0, x0, 0] + a * stack[y0, x0 + 1, 0]) \
        + b * ((1 - a) * stack[y0 + 1, x0, 0] + a * stack[y0 + 1, x0 + 1, 0])
    out1 = (1 - b) * ((1 - a) * stack[y0, x0, 1] + a * stack[y0, x0 + 1, 1]) \
        + b * ((1 - a) * stack[y0 + 1, x0, 1] + a * stack[y0 + 1, x0 + 1, 1])
    out2 = (1 - b) * ((1 - a) * stack[y0, x0, 2] + a * stack[y0, x0 + 1, 2]) \
        + b * ((1 - a) * stack[y0 + 1, x0, 2] + a * stack[y0 + 1, x0 + 1, 2])
    return out0, out1, out2


@numba.njit(inline="always", fastmath=True, error_model="numpy")
def _block(i, lo, hi, rot, w, pos, nd, image2, dem_stack, geo, kv, moves_i, m_rows, m_cols, m_coef, out, h, bounds):
    """Nodes ``lo:hi`` under hypothesis ``i``: ``out[0, k - lo] = r0``, the pose-error partials
    ``out[1:13, k - lo]`` (image I's six, unused when it does not move, then image II's) and the
    rows ``h[:, k - lo] = -(J M)``; ``out[13:15]`` the ground points' x and y, and ``bounds``
    grows to their extent. ``nd (N, 5)`` holds each node's ray (x, y), ``Z``, start height and ray
    parameter. Written as one straight loop over the nodes (the compiler unrolls the two Newton
    steps) reading three arrays and writing one, so the compiler vectorises it (more arrays exceed
    its budget of run-time aliasing checks)."""
    fx, fy, cx, cy = kv[0], kv[1], kv[2], kv[3]
    ci = i * moves_i
    r00, r01, r02 = rot[ci, 0, 0, 0], rot[ci, 0, 0, 1], rot[ci, 0, 0, 2]
    r10, r11, r12 = rot[ci, 0, 1, 0], rot[ci, 0, 1, 1], rot[ci, 0, 1, 2]
    r20, r21, r22 = rot[ci, 0, 2, 0], rot[ci, 0, 2, 1], rot[ci, 0, 2, 2]
    s00, s01, s02 = rot[i, 1, 0, 0], rot[i, 1, 0, 1], rot[i, 1, 0, 2]
    s10, s11, s12 = rot[i, 1, 1, 0], rot[i, 1, 1, 1], rot[i, 1, 1, 2]
    s20, s21, s22 = rot[i, 1, 2, 0], rot[i, 1, 2, 1], rot[i, 1, 2, 2]
    o0, o1, o2 = pos[ci, 0, 0], pos[ci, 0, 1], pos[ci, 0, 2]
    c0, c1, c2 = pos[i, 1, 0], pos[i, 1, 1], pos[i, 1, 2]
    gx0, gy0, gdx, gdy = geo[0], geo[1], geo[2], geo[3]
    a00, a01, a02 = w[ci, 0, 0, 0], w[ci, 0, 0, 1], w[ci, 0, 0, 2]
    a10, a11, a12 = w[ci, 0, 1, 0], w[ci, 0, 1, 1], w[ci, 0, 1, 2]
    a20, a21, a22 = w[ci, 0, 2, 0], w[ci, 0, 2, 1], w[ci, 0, 2, 2]
    b00, b01, b02 = w[i, 1, 0, 0], w[i, 1, 0, 1], w[i, 1, 0, 2]
    b10, b11, b12 = w[i, 1, 1, 0], w[i, 1, 1, 1], w[i, 1, 1, 2]
    b20, b21, b22 = w[i, 1, 2, 0], w[i, 1, 2, 1], w[i, 1, 2, 2]
    xmin, xmax, ymin, ymax = bounds[0], bounds[1], bounds[2], bounds[3]
    for k in range(lo, hi):
        j = k - lo
        d0 = r00 * nd[k, 0] + r01 * nd[k, 1] + r02
        d1 = r10 * nd[k, 0] + r11 * nd[k, 1] + r12
        d2 = r20 * nd[k, 0] + r21 * nd[k, 1] + r22
        hx = 0.0
        hy = 0.0
        if moves_i:
            t = (o2 - nd[k, 3]) / -d2
            for _ in range(2):                                        # two Newton steps on the DEM
                e0, e1, e2 = _read(dem_stack, (o0 + t * d0 - gx0) / gdx, (o1 + t * d1 - gy0) / gdy)
                hx, hy = e1 / gdx, e2 / gdy
                t = t - (o2 + t * d2 - e0) / (d2 - hx * d0 - hy * d1)
        else:
            t = nd[k, 4]
        g0 = o0 + t * d0
        g1 = o1 + t * d1
        out[13, j] = g0
        out[14, j] = g1
        q0 = g0 - c0
        q1 = g1 - c1
        q2 = o2 + t * d2 - c2
        p0 = s00 * q0 + s10 * q1 + s20 * q2
        p1 = s01 * q0 + s11 * q1 + s21 * q2
        inv = 1.0 / (s02 * q0 + s12 * q1 + s22 * q2)
        v0, v1, v2 = _read(image2, cx + fx * p0 * inv, cy + fy * p1 * inv)
        out[0, j] = nd[k, 2] - v0
        gu = v1 * fx * inv
        gv = v2 * fy * inv
        gz = -(gu * p0 + gv * p1) * inv                               # dF/dp (camera II frame)
        f0 = s00 * gu + s01 * gv + s02 * gz
        f1 = s10 * gu + s11 * gv + s12 * gz
        f2 = s20 * gu + s21 * gv + s22 * gz
        x0 = f1 * q2 - f2 * q1                                        # dF/dangle_a = w_a . (dF/dG x q)
        x1 = f2 * q0 - f0 * q2
        x2 = f0 * q1 - f1 * q0
        out[7, j] = -f0
        out[8, j] = -f1
        out[9, j] = -f2
        out[10, j] = b00 * x0 + b01 * x1 + b02 * x2
        out[11, j] = b10 * x0 + b11 * x1 + b12 * x2
        out[12, j] = b20 * x0 + b21 * x1 + b22 * x2
        ratio = (d0 * f0 + d1 * f1 + d2 * f2) / (hx * d0 + hy * d1 - d2)
        y0 = f0 - hx * ratio
        y1 = f1 - hy * ratio
        y2 = f2 + ratio
        e0 = t * (d1 * y2 - d2 * y1)                                  # dF/dangle_a = t w_a . (d x y)
        e1 = t * (d2 * y0 - d0 * y2)
        e2 = t * (d0 * y1 - d1 * y0)
        out[1, j] = y0
        out[2, j] = y1
        out[3, j] = y2
        out[4, j] = a00 * e0 + a01 * e1 + a02 * e2
        out[5, j] = a10 * e0 + a11 * e1 + a12 * e2
        out[6, j] = a20 * e0 + a21 * e1 + a22 * e2
    for j in range(hi - lo):                                          # apart: min/max stop the vectoriser
        xmin = min(xmin, out[13, j])
        xmax = max(xmax, out[13, j])
        ymin = min(ymin, out[14, j])
        ymax = max(ymax, out[14, j])
    bounds[0], bounds[1], bounds[2], bounds[3] = xmin, xmax, ymin, ymax
    n = h.shape[0]
    for a in range(n):
        for j in range(hi - lo):
            h[a, j] = 0.0
    for e in range(m_rows.shape[0]):
        ra, ca, va = m_rows[e], m_cols[e], m_coef[e]
        for j in range(hi - lo):
            h[ca, j] -= va * out[1 + ra, j]


@numba.njit(parallel=True, fastmath=True, error_model="numpy", cache=True)
def sums(rot, w, pos, nd, image2, dem_stack, geo, kv, moves_i, m_rows, m_cols, m_coef, n,
         hh, hr, rr, bounds):
    """For every hypothesis ``i`` (in parallel): ``hh[i] = sum H'H``, ``hr[i] = sum H'r0``,
    ``rr[i] = sum r0^2`` over the nodes, and ``bounds[i]`` = (min x, max x, min y, max y) of the
    ground points. ``H = -J M`` with ``M``'s nonzeros given as (row of J, state column, value)."""
    n_nodes = nd.shape[0]
    for i in numba.prange(rot.shape[0]):
        out = np.zeros((15, BLOCK))
        h = np.empty((n, BLOCK))
        acc = np.zeros((n, n))
        b = np.zeros(n)
        box = np.array([np.inf, -np.inf, np.inf, -np.inf])
        total = 0.0
        for lo in range(0, n_nodes, BLOCK):
            hi = min(lo + BLOCK, n_nodes)
            _block(i, lo, hi, rot, w, pos, nd, image2, dem_stack, geo, kv, moves_i, m_rows, m_cols, m_coef, out, h,
                   box)
            m = hi - lo
            for a in range(n):
                s = 0.0
                for j in range(m):
                    s += h[a, j] * out[0, j]
                b[a] += s
                for c in range(a, n):
                    s = 0.0
                    for j in range(m):
                        s += h[a, j] * h[c, j]
                    acc[a, c] += s
            s = 0.0
            for j in range(m):
                s += out[0, j] * out[0, j]
            total += s
        for a in range(n):
            hr[i, a] = b[a]
            for c in range(a, n):
                hh[i, a, c] = acc[a, c]
                hh[i, c, a] = acc[a, c]
        rr[i] = total
        for a in range(4):
            bounds[i, a] = box[a]


@numba.njit(parallel=True, fastmath=True, error_model="numpy", cache=True)
def rows(rot, w, pos, nd, image2, dem_stack, geo, kv, moves_i, m_rows, m_cols, m_coef, n,
         r0_out, h_out):
    """The same per-node terms stored: ``r0_out (c, N)`` and ``h_out (c, n, N)`` (for tests and the
    literal recursion)."""
    n_nodes = nd.shape[0]
    for i in numba.prange(rot.shape[0]):
        out = np.zeros((15, BLOCK))
        h = np.empty((n, BLOCK))
        box = np.array([np.inf, -np.inf, np.inf, -np.inf])
        for lo in range(0, n_nodes, BLOCK):
            hi = min(lo + BLOCK, n_nodes)
            _block(i, lo, hi, rot, w, pos, nd, image2, dem_stack, geo, kv, moves_i, m_rows, m_cols, m_coef, out, h,
                   box)
            r0_out[i, lo:hi] = out[0, :hi - lo]
            h_out[i, :, lo:hi] = h[:, :hi - lo]
