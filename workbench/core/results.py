"""What a run leaves: its result (the dataset, every estimate, the failures, the shared products)
and its summary (what a Monte Carlo worker sends back). An experiment's own adds fields."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from workbench.core.estimator import Estimator
from workbench.metrics import base as metric


@dataclass
class RunResult:
    """One run: its dataset, every estimate by name, the estimators' table rows, the ones that
    failed (one line each), the products the estimators shared (:meth:`RunContext.shared`),
    ``cache``: what evaluating the run makes once for several of its figures (:meth:`shared`), and
    the run's config."""

    data: Any
    estimates: dict[str, Any]
    estimators: dict[str, Estimator] = field(default_factory=dict)
    failed: dict[str, str] = field(default_factory=dict)
    products: dict[str, Any] = field(default_factory=dict, repr=False)
    cache: dict[str, Any] = field(default_factory=dict, repr=False)
    config: Any = field(default=None, repr=False)
    record: bool = False           # the recorded run (what only the recording draws was computed)
    metrics: list = field(default_factory=list, repr=False)  # the run's metrics (:class:`~.metric.Metric` rows)
    experiment: Any = field(default=None, repr=False)  # the experiment that ran it

    def shared(self, key: str, make) -> Any:
        if key not in self.cache:
            self.cache[key] = make()
        return self.cache[key]


@dataclass
class RunSummary:
    """What a Monte Carlo worker sends back of a run (small arrays only): its number, its
    metrics' samples (estimator -> metric -> :class:`~.metric.Values`), the estimators and the
    plugin metrics that failed. An experiment's summary adds its own figures."""

    run: int
    failed: dict[str, str] = field(default_factory=dict, kw_only=True)
    metrics: dict[str, dict[str, metric.Values]] = field(default_factory=dict, kw_only=True)
    metric_failures: dict[str, str] = field(default_factory=dict, kw_only=True)
    evidence: dict[str, Any] = field(default_factory=dict, kw_only=True)  # estimator -> its truth-free evidence


def without(summary: Any, names: set[str]) -> Any:
    """A copy of a run's summary (or result) with the named estimators left out of every
    field that is a dict keyed by estimator names."""
    if not names:
        return summary
    changes = {}
    for f in dataclasses.fields(summary):
        value = getattr(summary, f.name)
        if isinstance(value, dict) and names & set(value):
            changes[f.name] = {k: v for k, v in value.items() if k not in names}
    return dataclasses.replace(summary, **changes) if changes else summary
