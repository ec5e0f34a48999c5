"""The omni experiment's estimator table: name -> how to run it, colour, what it is.

Each runner is ``(data, cfg, ctx) -> SlamEstimate`` and imports its module when first run.
The graph estimators share the run's keyframes (:func:`keyframes`).
"""

from __future__ import annotations

import math

from workbench.core.estimator import Estimator, RunContext, table
from workbench.experiments.omni.config import OmniConfig
from workbench.experiments.omni.estimate import SlamEstimate
from workbench.experiments.omni.scenario import OmniData


def odometry(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    from workbench.experiments.omni.algorithms import ekf

    return ekf.odometry(data)


def ekf_paper(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    from workbench.experiments.omni.algorithms import ekf

    return ekf.run(data, cfg, "paper", "ekf-paper", ctx.record)


def ekf_clone(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    from workbench.experiments.omni.algorithms import ekf

    return ctx.shared("ekf", lambda: ekf.run(data, cfg, "clone", "ekf", ctx.record))


def keyframes(data: OmniData, cfg: OmniConfig, ctx: RunContext):
    """The graph's keyframes, odometry between them and bearings at them, made once a run."""
    from workbench.experiments.omni.algorithms import graph

    return ctx.shared("keyframes", lambda: graph.keyframes(data, cfg))


def isam2(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    from workbench.experiments.omni.algorithms import graph

    kf = keyframes(data, cfg, ctx)
    return ctx.shared("isam2", lambda: graph.isam2(data, cfg, kf, map_every=1.0 if ctx.record else math.inf))


def batch(data: OmniData, cfg: OmniConfig, ctx: RunContext) -> SlamEstimate:
    """The batch from each start ``--batch-starts`` names (an estimator's answer is made once a
    run, shared with that estimator's row), keeping the one of lowest cost on the data."""
    from workbench.experiments.omni.algorithms import graph

    kf = keyframes(data, cfg, ctx)
    made = {"isam2": lambda: isam2(data, cfg, ctx), "ekf": lambda: ekf_clone(data, cfg, ctx)}
    return graph.batch(data, cfg, kf, graph.named_starts(data, cfg, kf, made))


TABLE: dict[str, Estimator] = table(
    "omni",
    Estimator("odometry", odometry, (150, 150, 150), "dead reckoning (7)-(8)", causal=True, covariances=True),
    Estimator("ekf-paper", ekf_paper, (255, 170, 0),
              "EKF-SLAM with the paper's augmentation (15) and the UT-gated initialisation (1)-(5)",
              causal=True, covariances=True,
              indefinite="(15) drops the first sighting's pose-landmark correlations, so P can turn indefinite"),
    Estimator("ekf", ekf_clone, (230, 70, 70), "the same EKF-SLAM with a cloned-pose augmentation",
              causal=True, covariances=True),
    Estimator("isam2", isam2, (255, 110, 200), "GTSAM iSAM2 over Pose2/Point2 bearing factors, newest pose",
              causal=True, covariances=True),
    Estimator("gtsam-batch", batch, (190, 90, 240), "GTSAM LM over the whole run (a smoother), marginals",
              causal=False, covariances=True),
)
