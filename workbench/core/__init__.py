"""The experiment contract and what runs it: the :class:`~workbench.core.experiment.Experiment`
facade and its declared :class:`~workbench.core.parts.Parts`, a run's results, the estimator row
and how a selection names one, the registry, the estimators' time limit, Monte Carlo runs over
processes, and ``--tune-noise`` (a run's own noise found from its data)."""
