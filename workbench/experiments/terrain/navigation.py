"""Navigation-system errors: the paper's error state, its two modes, and the measured orientation.

The paper's error vector is ``X = (dX, dVx, dH, dtheta, dY, dVy, dpsi, dgamma)``. Two modes
(``spec/terrain.md``):

* ``common``: one error process for both exposures. The state is the errors at image I; image
  II's position errors are grown by the velocity errors over the time between the exposures
  (the dynamics A: ``dX_II = dX_I + dVx * T``, ``dY_II = dY_I + dVy * T``), its height and
  attitude errors are the same. Reading taken: along the node recursion (2)-(4) the state does
  not move (A is the identity from node to node); A acts once, between the exposures, inside
  the measurement function.
* ``ii-only``: image I's orientation is exact; the state is image II's six errors
  ``(dX, dH, dtheta, dY, dpsi, dgamma)`` (the paper's order without the velocities).

An error is ``measured - true`` (the paper corrects ``X^ = X* - dX^``). Pose errors per
exposure are laid out ``(dX, dY, dH, dpsi, dtheta, dgamma)``, like the poses.
"""

from __future__ import annotations

import numpy as np

from workbench.experiments.terrain.config import TerrainConfig

STATE = {
    "common": ("dX", "dVx", "dH", "dtheta", "dY", "dVy", "dpsi", "dgamma"),
    "ii-only": ("dX", "dH", "dtheta", "dY", "dpsi", "dgamma"),
}
POSE = ("dX", "dY", "dH", "dpsi", "dtheta", "dgamma")
LINEAR = ("dX", "dY", "dH")
ANGULAR = ("dpsi", "dtheta", "dgamma")
VELOCITY = ("dVx", "dVy")


def error_map(mode: str, interval: float) -> np.ndarray:
    """``M (2, 6, n)``: the pose errors of both exposures are ``M @ state``."""
    names = STATE[mode]
    m = np.zeros((2, 6, len(names)))
    col = {n: i for i, n in enumerate(names)}
    for r, p in enumerate(POSE):
        if mode == "common":
            m[0, r, col[p]] = 1.0
        m[1, r, col[p]] = 1.0
    if mode == "common":
        m[1, 0, col["dVx"]] = interval
        m[1, 1, col["dVy"]] = interval
    return m


def maxima(cfg: TerrainConfig) -> np.ndarray:
    """Each state component's maximum error (m, m/s, rad) in the mode's order."""
    return np.array([cfg.max_velocity if n in VELOCITY else cfg.max_angular if n in ANGULAR
                     else cfg.max_linear for n in STATE[cfg.mode]])


def draw_state(cfg: TerrainConfig, rng: np.random.Generator) -> np.ndarray:
    """The true error state: uniform up to the maxima; ``gaussian``, sigma = maximum / 3; or
    ``maximum``, every component at its maximum with a random sign (the paper's "maximum errors
    ... taken as constant", read as the errors its experiment applied)."""
    top = maxima(cfg)
    if cfg.distribution == "uniform":
        return rng.uniform(-top, top)
    if cfg.distribution == "maximum":
        return top * rng.choice([-1.0, 1.0], size=top.shape)
    return rng.normal(0.0, top / 3.0)


def sigma_fraction(cfg: TerrainConfig) -> float:
    """Each error's standard deviation as a fraction of its maximum under the chosen distribution."""
    return {"uniform": 1.0 / np.sqrt(3.0), "gaussian": 1.0 / 3.0, "maximum": 1.0}[cfg.distribution]


def prior_covariance(cfg: TerrainConfig) -> np.ndarray:
    """The navigation system's own prior on the error state: ``diag((sigma_fraction * max)^2)``,
    the errors' spread under the chosen distribution (a Gaussian of that spread for uniform
    and maximum errors, which have no Gaussian form), mean 0."""
    return np.diag((sigma_fraction(cfg) * maxima(cfg)) ** 2)


def measured(position: np.ndarray, angles: np.ndarray, pose_errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the navigation system reports: true pose plus its errors, per exposure."""
    return position + pose_errors[..., :3], angles + pose_errors[..., 3:]


def corrected(position: np.ndarray, angles: np.ndarray, pose_errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's correction ``X^ = X* - dX^`` for estimated pose errors."""
    return position - pose_errors[..., :3], angles - pose_errors[..., 3:]
