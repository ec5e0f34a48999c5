"""Algorithm 1: the geometric estimate (3)-(5) from each step's measured angles."""

from __future__ import annotations

from workbench.experiments.sea.estimate import Estimate, from_angles
from workbench.experiments.sea.scenario import SeaData


def estimate(data: SeaData) -> Estimate:
    """Positions by (3)-(5) from the measured angles and observer position; none when unseen."""
    return from_angles("geometric", data, data.alpha_meas.copy(), data.beta_meas.copy())
