"""What every omni estimator returns: poses at some steps, their covariances, and the map."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SlamEstimate:
    """An estimator's answer on one dataset.

    ``steps`` are the dataset's pose indices where the estimate exists (every step for a
    filter, keyframes for a graph); ``pose (E, 3)`` and ``cov (E, 3, 3)`` (world-frame
    ``x, y, phi`` covariance; NaN where unknown). ``map_steps`` are the steps where the map
    was snapshotted, ``map_mean (S, N, 2)`` / ``map_cov (S, N, 2, 2)`` the landmarks then (NaN
    while a landmark is not initialised). ``first_seen`` / ``init_step`` per landmark (-1:
    never). ``attempts`` (recorded run only): ``(step, landmark, sigma images (2n+1, 2),
    accepted)`` of every initialisation try.
    """

    name: str
    steps: np.ndarray
    pose: np.ndarray
    cov: np.ndarray | None
    map_steps: np.ndarray
    map_mean: np.ndarray
    map_cov: np.ndarray | None
    first_seen: np.ndarray
    init_step: np.ndarray
    seconds: float = 0.0
    failures: int = 0
    attempts: list = field(default_factory=list)

    @property
    def final_map(self) -> np.ndarray:
        return self.map_mean[-1] if len(self.map_mean) else np.full((len(self.first_seen), 2), np.nan)

    @property
    def final_map_cov(self) -> np.ndarray | None:
        return None if self.map_cov is None or not len(self.map_cov) else self.map_cov[-1]
