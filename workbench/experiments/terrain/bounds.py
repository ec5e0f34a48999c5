"""The terrain experiment's Cramér-Rao bound: how well any estimator could know image II's
exterior orientation from the image pair and the navigation prior
(:mod:`workbench.estimation.bounds`).

The images' Fisher information is that of the search's own measurement model (:mod:`.search`:
image II's irradiance at the nodes of image I, through the DEM), at the true navigation errors:
``sum_nodes H H' / R`` with ``H = grad f_II . d(u, v)/dX`` (``search.sums`` at the true state).
``R`` is the residual variance the data have there (image II against image I at the true
orientation, over the nodes), not the filter's tuning. The prior is the navigation errors' own
spread (``sigma_fraction`` of each maximum), as a Gaussian. The state is the error mode's
(``common``: both exposures' errors; ``ii-only``: image II's six). The bound is one run's; the
variances are averaged over the runs like the squared errors.

Readings taken: ``H`` is the model's, the one the filters use: image II's gradient by central
differences, interpolated; central differences of the residual itself (the bilinear image's own
slopes) give 1.9-3 times the information on a synthetic 100 x 100 pair. The nodes' residuals are
taken independent; neighbouring pixels' are not quite
(the texture and the rendering blur them), so the information is somewhat overstated and the
bound a little low: still a bound, but a loose one. A uniform error distribution (the default)
has no prior Fisher information of its own; its Gaussian of the same spread stands in.
"""

from __future__ import annotations

import numpy as np

from workbench.experiments.terrain import navigation, search
from workbench.experiments.terrain.config import TerrainConfig


def state_bound(problem: search.Problem, state: np.ndarray, cfg: TerrainConfig) -> tuple[np.ndarray, float]:
    """The bound on the error state ``(n, n)`` and the residual variance R used."""
    hh, _, rr = search.sums(problem, np.asarray(state, float)[None])
    nodes = len(problem.nodes)
    r = float(rr[0] / nodes)
    prior = np.diag((navigation.sigma_fraction(cfg) * navigation.maxima(cfg)) ** 2)
    info = hh[0] / r + np.linalg.inv(prior)
    P = np.linalg.inv(info)
    return 0.5 * (P + P.T), r


def variances(P: np.ndarray, cfg: TerrainConfig, interval: float) -> dict[str, float]:
    """Image II's bounds: ``position`` (the 3D error's ``var x + var y + var h``, m^2), ``x``, ``y``,
    ``h`` and ``attitude`` (the three angles', rad^2)."""
    m = navigation.error_map(cfg.mode, interval)[1]    # image II's pose errors from the state
    C = m @ P @ m.T                                     # (6, 6): dX, dY, dH, dpsi, dtheta, dgamma
    return {"position": float(np.trace(C[:3, :3])), "x": float(C[0, 0]), "y": float(C[1, 1]),
            "h": float(C[2, 2]), "attitude": float(np.trace(C[3:, 3:]))}
