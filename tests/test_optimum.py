"""The likelihood ratio's side of ``--tune-noise``'s intervals (:mod:`workbench.core.optimum`)
against a Gaussian's exact bounds in its log-sigma."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from workbench.core import optimum, selftune


def _nll(n: int, ss: float):
    """A Gaussian's NLL in its log-sigma ``z[0]`` from ``n`` measurements whose squares sum to
    ``ss``, and a second value (``z[1]``) a quadratic of its own, independent of the first."""
    return lambda z: n * z[0] + 0.5 * ss * math.exp(-2 * z[0]) + 0.5 * 400.0 * z[1] ** 2


def test_the_upper_side_reaches_the_likelihood_ratios_bound_and_the_lower_keeps_walds():
    n, ss = 20, 20 * 0.3 ** 2
    f = _nll(n, ss)
    x = np.array([math.log(0.3), 0.0])                   # the optimum: sigma^2 = ss / n
    H = np.diag([2.0 * n, 400.0])                         # the exact curvature there
    wald, ok = selftune.intervals(H, x)
    assert ok.all()
    out = optimum.widened(f, x, H, wald, ok)
    # the exact likelihood-ratio bounds: n t + n (exp(-2t) - 1) / 2 = 1.92
    rise = lambda t: n * t + 0.5 * n * (math.exp(-2 * t) - 1) - optimum.RISE  # noqa: E731
    up, down = brentq(rise, 1e-6, 2.0), brentq(rise, -2.0, -1e-6)
    s = 1 / math.sqrt(2 * n)
    assert up > 1.959964 * s > -down                     # the skew: farther up, nearer down
    assert math.log(out[0, 1] / 0.3) == pytest.approx(up, rel=0.02)
    assert out[0, 0] == wald[0, 0]                       # the Wald side was the farther one
    assert np.allclose(out[1], wald[1])                  # a quadratic's: Wald's, both sides


def test_a_flat_side_is_held_to_twice_walds_and_an_unidentified_value_untouched():
    f = lambda z: 0.5 * 100.0 * min(z[0], 0.0) ** 2 + 0.001 * max(z[0], 0.0)   # noqa: E731
    x = np.array([0.0, 1.0])
    H = np.diag([100.0, 0.0])
    wald, ok = selftune.intervals(H, x)
    assert ok.tolist() == [True, False]
    out = optimum.widened(f, x, H, wald, ok)
    s = 0.1
    assert math.log(out[0, 1]) == pytest.approx(optimum.REACH * 1.959964 * s)
    assert out[0, 0] == pytest.approx(wald[0, 0])
    assert np.isnan(out[1]).all()


def test_the_last_step_lands_on_the_optimum_where_the_wide_steps_newton_did_not():
    n, sigma = 400, 0.9
    f = _nll(n, n * sigma ** 2)                           # the optimum at (log 0.9, 0), sd 1 / sqrt(2n)
    best = np.array([math.log(sigma), 0.0])
    h = selftune.H_STEP
    H, g = selftune.hessian(f, best + [0.03, 0.01])      # a point near the optimum, the wide step's gradient
    start = best + [0.03, 0.01] - np.linalg.solve(H, g)  # its Newton step reads the skew as a slope
    sd = 1 / math.sqrt(2 * n)
    assert abs(start[0] - best[0]) > 1.5 * sd           # (0.055 in theory: f3 h^2 / 6 over f2)
    assert abs(start[0] - best[0]) == pytest.approx(h ** 2 / 3, rel=0.2)
    out = optimum.polished(f, start, H * selftune.CURVED, np.array([True, True]))
    assert abs(out[0] - best[0]) < 0.1 * sd and abs(out[1]) < 1e-3
    assert f(out) < f(start)
    # nothing identified: nothing moves
    assert np.array_equal(optimum.polished(f, start, H, np.array([False, False])), start)
