"""Metrics: the interface (a function of a dataset and an estimate returning its
:class:`~workbench.metrics.base.Values`, :mod:`.base`), what is derived from it over runs
(:mod:`.statistics`), the truth-free metrics and the diagnosis per estimator (:mod:`.truthfree`,
:mod:`.diagnosis`, :mod:`.bootstrap`), the results tables (:mod:`.tables`) and the metrics'
Rerun curves (:mod:`.curves`)."""
