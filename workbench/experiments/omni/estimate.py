"""What every omni estimator returns: poses at some steps, their covariances, and the map.

A researcher's estimator ``my_slam(data: OmniData, cfg: OmniConfig) -> SlamEstimate`` needs
``pose`` only: at every step (``len(data.t)`` rows) or at the scoring grid ``data.grid``
(``steps`` may then be left out), or at any increasing steps it names. Poses are world-frame
``(x, y, phi)`` in metres and radians; ``cov`` their ``(3, 3)`` covariances (world frame,
symmetric positive semi-definite); a NaN row is "no estimate at this step". The map is
optional: landmark estimates ``(S, N, 2)`` at ``map_steps`` (NaN while not initialised).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.estimation.consistency import Innovations, Residuals


@dataclass
class SlamEstimate:
    """An estimator's answer on one dataset.

    ``steps`` are the dataset's pose indices where the estimate exists (every step for a
    filter, keyframes for a graph); ``pose (E, 3)`` and ``cov (E, 3, 3)`` (world-frame
    ``x, y, phi`` covariance; NaN where unknown). ``map_steps`` are the steps where the map
    was snapshotted, ``map_mean (S, N, 2)`` / ``map_cov (S, N, 2, 2)`` the landmarks then (NaN
    while a landmark is not initialised). ``first_seen`` / ``init_step`` per landmark (-1:
    never). ``gated_bearings``: the bearings (indices into the dataset's) a chi-square gate
    left out (misreads, outliers; -1 for a bearing not the dataset's, the image stage's). ``attempts``
    (recorded run only): ``(step, landmark, sigma images (2n+1, 2), accepted)`` of every
    initialisation try. ``innovations``: a filter's bearing innovations and their variances
    (:class:`~workbench.estimation.consistency.Innovations`, one row a bearing it was handed: the
    truth-free NIS, whiteness and likelihood read them). ``smoothed (E, 3)``: a smoother's whole
    trajectory as it holds it at the end (iSAM2's final estimate, at ``steps``), beside ``pose``,
    what it knew at each step. ``start``: where an estimator that can start from more than one
    place started (the batch's winner by its cost on the data), ``start_costs`` the cost of each it
    solved (the batch solves the next start only while the last fit fails its test).
    ``residuals``: a smoother's residuals at its answer by group with their redundancies
    (:class:`~workbench.estimation.consistency.Residuals`: its truth-free diagnosis reads them).
    ``remarks``: what went wrong that the numbers do not show (iSAM2 given up), which leads its
    diagnosis's reason. ``undecided``: where two of its answers fit the data alike and lie far apart
    (:func:`.algorithms.graph.undecided.between`): its diagnosis is then "undecided".
    """

    name: str = ""
    steps: np.ndarray | None = None
    pose: np.ndarray | None = None
    cov: np.ndarray | None = None
    map_steps: np.ndarray | None = None
    map_mean: np.ndarray | None = None
    map_cov: np.ndarray | None = None
    first_seen: np.ndarray | None = None
    init_step: np.ndarray | None = None
    seconds: float = 0.0
    failures: int = 0
    lm_passes: int = 0  # iSAM2's damped whole-graph LM passes (run-aways; every ``lm_every`` s where set)
    gated_bearings: np.ndarray | None = None  # indices of the bearings a gate left out
    attempts: list = field(default_factory=list)
    smoothed: np.ndarray | None = None  # (E, 3) the whole trajectory as held at the end
    innovations: Innovations | None = None  # a filter's innovations of the bearings, for its truth-free checks
    start: str = ""  # where it started, if it chose among starts (by its cost on the data)
    start_costs: dict[str, float] = field(default_factory=dict)  # each start's cost
    fit: tuple[float, int] | None = None  # a least-squares smoother's residual chi-square and its dof
    residuals: Residuals | None = None  # a smoother's residuals at its answer by group, for its diagnosis
    remarks: list[str] = field(default_factory=list)  # what went wrong, in its own words (leads its diagnosis)
    undecided: dict | None = None  # where the data did not choose among its answers (graph.undecided)

    @property
    def gated(self) -> int:
        """How many bearings a gate left out."""
        return 0 if self.gated_bearings is None else len(self.gated_bearings)

    @property
    def final_map(self) -> np.ndarray:
        return self.map_mean[-1] if len(self.map_mean) else np.full((len(self.first_seen), 2), np.nan)

    @property
    def final_map_cov(self) -> np.ndarray | None:
        return None if self.map_cov is None or not len(self.map_cov) else self.map_cov[-1]


def check(est: SlamEstimate, data, cfg, estimator) -> SlamEstimate:
    """An estimator's answer against this type's contract; the optional parts filled (no map,
    ``steps`` from the pose's length); the name set. Raises
    :class:`~workbench.core.estimator.EstimateError` naming what is wrong."""
    from workbench.core.estimator import EstimateError, as_array, psd, whole_rows

    if not isinstance(est, SlamEstimate):
        raise EstimateError(f"returned {type(est).__name__}, not an omni SlamEstimate")
    if est.pose is None:
        raise EstimateError("the estimate has no pose")
    pose = as_array(est.pose, "pose", (None, 3))
    K, N = len(data.t), len(data.landmarks)
    if est.steps is None:
        if len(pose) == K:
            est.steps = np.arange(K)
        elif data.grid is not None and len(pose) == len(data.grid):
            est.steps = data.grid.copy()
        else:
            raise EstimateError(f"pose has {len(pose)} rows: give steps, or a pose per step ({K}) "
                                f"or per grid step ({len(data.grid)})")
    steps = np.asarray(est.steps)
    if steps.shape != (len(pose),) or steps.dtype.kind not in "iu":
        raise EstimateError(f"steps must be {len(pose)} integer step indices, got {steps.dtype} {steps.shape}")
    if len(steps) and (steps.min() < 0 or steps.max() >= K or np.any(np.diff(steps) <= 0)):
        raise EstimateError(f"steps must increase strictly within 0..{K - 1}")
    whole_rows(pose, "pose", allow_empty=False)
    if est.cov is not None:
        psd(as_array(est.cov, "cov", (len(pose), 3, 3)), "cov", None, estimator)
    if est.smoothed is not None:
        est.smoothed = as_array(est.smoothed, "smoothed", (len(pose), 3))
    if est.map_steps is None:
        est.map_steps, est.map_mean, est.map_cov = np.zeros(0, int), np.zeros((0, N, 2)), None
    else:
        S = len(est.map_steps)
        est.map_mean = as_array(est.map_mean, "map_mean", (S, N, 2))
        if est.map_cov is not None:
            psd(as_array(est.map_cov, "map_cov", (S, N, 2, 2)), "map_cov", None, estimator)
    for what in ("first_seen", "init_step"):
        if getattr(est, what) is None:
            setattr(est, what, np.full(N, -1))
        elif np.shape(getattr(est, what)) != (N,):
            raise EstimateError(f"{what} must have one entry per landmark ({N})")
    est.name, est.steps, est.pose = estimator.name, steps, pose
    return est
