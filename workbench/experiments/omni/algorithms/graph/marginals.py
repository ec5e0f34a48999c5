"""Reading the answer out of iSAM2: a landmark's point and marginal, a pose's marginal, and the
map as the recording draws it through time (only the landmarks seen since the last reading, all
of them every ``MAP_FULL``-th reading and at the end)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gtsam
import numpy as np
from gtsam.symbol_shorthand import L, X

from workbench.experiments.omni.algorithms.graph.keyframes import to_world

JUMP_POSITION = 2.0


CHUNK = 50
"""Keys per joint marginal in :func:`marginal_blocks`."""

MAP_FULL = 10
"""Every how many map readings :func:`read_map` reads every landmark's marginal, not only the seen ones'."""


def marginal_blocks(marginals: gtsam.Marginals, keys: list[int]) -> list[np.ndarray]:
    """Each key's marginal covariance, read off joint marginals of ``CHUNK`` keys at a time.

    One key at a time, GTSAM eliminates the clique that holds it down to that key, again for every
    key in it: where misread ids tie the map together (20 % misread on a 3,000-pose drive, where a
    landmark's marginal alone took 55 ms, the median), that was 15 s for 750 keys in the smoothing
    bound, and 0.6 s in chunks of 50; on a drive without misreads both take 0.1 s. The chunks keep
    the cost linear in the log (each joint is of at most ``CHUNK`` keys) and agree with the one-key
    marginals to about 1e-9 relative (replay tolerates 1e-5). A chunk GTSAM cannot compute raises
    its ``RuntimeError`` as one key would."""
    out = []
    for i in range(0, len(keys), CHUNK):
        part = keys[i:i + CHUNK]
        joint = marginals.jointMarginalCovariance(gtsam.KeyVector(part))
        out += [np.asarray(joint.at(k, k), float) for k in part]
    return out


def read_map(held: list[int], previous: np.ndarray, seen: np.ndarray, full: bool,
             mean_of: Callable[[int], np.ndarray], cov_of: Callable[[int], np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
    """One reading of a smoother's map ``(N, 2)``, ``(N, 2, 2)``: the mean of every landmark ``held``;
    the marginal of those ``seen`` since the last reading, of all where ``full``, and of any whose
    ``previous`` one is not finite; the others' carried from ``previous``; NaN for what is not held.
    ``seen`` is cleared. Why: landmark marginals cost more than an update (a Bayes-tree walk each);
    read for the whole map every second, they took 13 of iSAM2's 17 s on a 1,400 s log and 29 of the
    fixed-lag smoother's 30 s on a 7,000-pose drive (measured)."""
    mean = np.full((len(previous), 2), np.nan)
    cov = previous.copy()
    for lm in held:
        mean[lm] = mean_of(lm)
        if full or seen[lm] or not np.isfinite(cov[lm]).all():
            cov[lm] = cov_of(lm)
    cov[~np.isfinite(mean[:, 0])] = np.nan
    seen[:] = False
    return mean, cov


def _point_of(isam: gtsam.ISAM2, lm: int) -> np.ndarray:
    return isam.calculateEstimatePoint2(L(lm))


def _landmark_marginal(isam: gtsam.ISAM2 | None, lm: int) -> np.ndarray:
    return _marginal(isam, L(lm), 2)


def _marginal(isam: gtsam.ISAM2 | None, key: int, dim: int) -> np.ndarray:
    """A variable's marginal covariance; NaN where iSAM2 cannot give it (or has given up)."""
    if isam is None:
        return np.full((dim, dim), np.nan)
    try:
        cov = np.asarray(isam.marginalCovariance(key), float)
    except RuntimeError:
        return np.full((dim, dim), np.nan)
    # a variable the data hardly constrain (a landmark on near-parallel rays) can read inf
    return cov if np.isfinite(cov).all() else np.full((dim, dim), np.nan)


def pass_marginals(inc: Any, result: gtsam.Values, e: int) -> None:
    """The newest pose's and the landmarks' marginals at an LM pass's answer (the gate's start in
    :class:`.incremental._Incremental`); kept as they were if GTSAM cannot compute them."""
    if not math.isfinite(inc.gate):
        return
    try:
        marginals = gtsam.Marginals(inc.everything, result)
        heading = np.array([result.atPose2(X(e)).theta()])
        held = list(inc.points)
        blocks = marginal_blocks(marginals, [X(e)] + [L(lm) for lm in held])
        inc.chain_cov = to_world(blocks[0][None], heading)[0]
        for lm, block in zip(held, blocks[1:], strict=True):
            inc.point_cov[lm] = block
    except RuntimeError:
        pass
