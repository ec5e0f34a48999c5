"""What a tuning study minimises, from a trial's runs' figures (the sweeps' rows: one figure per run
for the estimator tuned), with its Monte Carlo standard error.

* ``likelihood``: the measurements' negative log-likelihood under the estimator, the mean over
  the runs of each run's ``nll`` (:mod:`workbench.metrics.truthfree`: the prediction-error
  decomposition of a filter's innovations, sum over the run of ``(log det 2 pi S + r' S^-1 r) / 2``).
  No truth is read: it runs on a real log. It is the model's likelihood ``p(z | theta)``, which
  for a linear-Gaussian model the Kalman filter's innovations give exactly, so a smoother on the
  same model has the same one: a smoother (no innovations of its own) is tuned through the run's
  filter on the same data and noise model, which :func:`resolve` says.
* ``nees``: how far the ANEES (the ``anees`` metric: the mean of the NEES over steps and runs)
  is from its dimension ``d``, on a log scale: ``|ln(ANEES / d)|`` (Chen et al., FUSION 2018,
  "Weak in the NEES?"); needs the truth (a simulation, a log with one).
* ``rmse``: the position RMSE over every run (``position_rmse``, terrain's ``position_error``).
* any other metric of the metric interface by name (a plugin's included): the mean of its runs'
  figures, or, for a chi-square metric with a dimension, its log distance from it as for ``nees``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.errors import WorkbenchError

NAMED = ("likelihood", "nees", "rmse")


@dataclass(frozen=True)
class Objective:
    """The objective ``name`` read from the metric ``metric`` of the estimator ``estimator``."""

    name: str
    metric: str
    estimator: str
    dimension: int = 0       # a chi-square dimension: the figure's log distance from it is minimised
    rms: bool = False        # the runs' figures combine as a root mean square (an RMSE)
    truth_free: bool = False

    def value(self, runs: np.ndarray) -> tuple[float, float]:
        """The objective over a trial's runs' figures and its Monte Carlo standard error (nan for one run)."""
        v = np.asarray(runs, float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return math.nan, math.nan
        n = v.size
        if self.rms:
            value = float(np.sqrt(np.mean(v ** 2)))
            se = float(np.std(v ** 2, ddof=1) / math.sqrt(n) / (2 * value)) if n > 1 and value > 0 else math.nan
            return value, se
        mean = float(np.mean(v))
        se = float(np.std(v, ddof=1) / math.sqrt(n)) if n > 1 else math.nan
        if self.dimension:
            if mean <= 0:
                return math.inf, math.nan
            return abs(math.log(mean / self.dimension)), se / mean
        return mean, se

    @property
    def describe(self) -> str:
        what = {"likelihood": "the measurements' negative log-likelihood (mean over runs; no truth used)",
                "nees": f"|ln(ANEES / {self.dimension})|",
                "rmse": f"the RMS over runs of {self.metric}"}.get(self.name)
        if what is None:
            what = (f"|ln({self.metric} / {self.dimension})|" if self.dimension
                    else f"the mean of {self.metric} over runs")
        return f"{what} of {self.estimator}"


def resolve(name: str, estimator: str, metrics: list) -> Objective:
    """The objective ``name`` for ``estimator`` among an experiment's ``metrics`` (:class:`Metric` rows)."""
    by_name = {m.name: m for m in metrics}
    name = str(name).strip()
    if name == "likelihood":
        return Objective(name, "nll", estimator, truth_free=True)
    if name == "nees":
        m = by_name.get("anees")
        if m is None:
            raise WorkbenchError("--objective nees: this experiment has no anees metric")
        return Objective(name, "anees", estimator, dimension=int(m.dimension or 0))
    if name == "rmse":
        metric = next((n for n in ("position_rmse", "position_error") if n in by_name), None)
        if metric is None:
            raise WorkbenchError("--objective rmse: this experiment has no position_rmse metric; name one")
        return Objective(name, metric, estimator, rms=True)
    m = by_name.get(name)
    if m is None:
        raise WorkbenchError(f"--objective {name!r}: likelihood, nees, rmse or a metric of this experiment: "
                             + ", ".join(sorted(by_name)))
    return Objective(name, name, estimator, dimension=int(m.dimension or 0), truth_free=m.truth_free)
