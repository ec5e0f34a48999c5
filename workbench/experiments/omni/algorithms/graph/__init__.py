"""The GTSAM baseline: a Pose2 / Point2 factor graph with bearing factors.

Keyframes are the bearing epochs (plus one at least every ``keyframe_every`` seconds, so
a stretch without landmarks still has poses). Between keyframes the odometry is integrated
with the same model (7)-(8) as the filter, in the earlier keyframe's frame, and enters as
a ``BetweenFactorPose2`` whose covariance is rotated into GTSAM's tangent space (Pose2's
errors live in the body frame of the later pose). Each bearing is a
``BearingFactor2D(pose, point, Rot2, sigma_theta)``, Huber-robust beyond ``huber`` sigmas
where that is set. A landmark enters the graph only once two of its rays meet with
``graph_parallax`` or more (held-back factors are added then): a landmark seen from one
place only leaves the linear system indeterminate.

* ``isam2``: iSAM2 (QR factorisation, relinearisation threshold ``relin_threshold``) updated
  at every keyframe; its newest pose at that time is what a causal estimator knows, so it
  is comparable to the filter's. A damped Levenberg-Marquardt pass over the graph so far only
  where an update runs away; with ``lm_every > 0`` also every ``lm_every`` seconds and whenever
  a landmark enters (:class:`_Incremental` says why that is no longer the default).
* ``gtsam-batch``: Levenberg-Marquardt over the whole run, marginal covariances for every
  pose. Started from the starts ``--batch-starts`` names in turn (dead reckoning with
  landmarks triangulated from it, iSAM2's or the EKF's answer, or with ``lm_every > 0`` the
  graph grown keyframe by keyframe with those LM passes) until one's fit passes its test.

Covariances are returned in the world frame (``x, y, phi``) like the filter's:
``C_world = J C_body J'``, ``J = diag(R(phi), 1)``.
"""

from __future__ import annotations

from workbench.experiments.omni.algorithms.graph.batch import (
    REGATE_ROUNDS,
    _batch_marginals,
    _drop_unseen,
    _regate,
    batch,
)
from workbench.experiments.omni.algorithms.graph.gating import (
    _bearing_test,
    gate_nis,
    gate_of,
    gated_indices,
    outlier_rate,
    robust_cost,
)
from workbench.experiments.omni.algorithms.graph.incremental import (
    JUMP_HEADING,
    JUMP_POSITION,
    PASS_BUDGET,
    _Incremental,
    _jumped,
)
from workbench.experiments.omni.algorithms.graph.isam2_estimator import _held_residuals, isam2
from workbench.experiments.omni.algorithms.graph.keyframes import (
    FLOOR,
    Keyframes,
    _lm_params,
    _noise,
    _odometry_graph,
    _pose,
    _prior,
    _to_body,
    compose_cov,
    keyframes,
    to_world,
)
from workbench.experiments.omni.algorithms.graph.landmarks import (
    _batch_graph,
    _Landmarks,
    _parallax_ok,
    _residuals,
    bearing_noise,
    consensus,
    refine,
)
from workbench.experiments.omni.algorithms.graph.marginals import (
    MAP_FULL,
    _landmark_marginal,
    _marginal,
    _point_of,
    read_map,
)
from workbench.experiments.omni.algorithms.graph.starts import (
    FIT_TEST,
    GROWN_EVERY,
    Start,
    _best_start,
    _prepare,
    fit,
    named_starts,
    own_start,
    plausible,
    start_from,
)

__all__ = [
    "FIT_TEST", "FLOOR", "GROWN_EVERY", "JUMP_HEADING", "JUMP_POSITION", "Keyframes", "MAP_FULL", "PASS_BUDGET",
    "REGATE_ROUNDS", "Start", "_Incremental", "_Landmarks", "_batch_graph", "_batch_marginals", "_bearing_test",
    "_best_start", "_drop_unseen", "_held_residuals", "_jumped", "_landmark_marginal", "_lm_params",
    "_marginal", "_noise", "_odometry_graph", "_parallax_ok", "_point_of", "_pose", "_prepare", "_prior",
    "_regate", "_residuals", "_to_body", "batch", "bearing_noise", "compose_cov", "consensus", "fit",
    "gate_nis", "gate_of", "gated_indices", "isam2", "keyframes", "named_starts", "outlier_rate", "own_start",
    "plausible", "read_map", "refine", "robust_cost", "start_from", "to_world",
]
