"""Tuning studies: noise parameters (any number setting) estimated from the data.

``workbench tune EXPERIMENT --param NAME=LOW:HIGH[:log] --objective likelihood|nees|rmse|METRIC``
(or :func:`workbench.tuning.study.tune`): Optuna proposes (:mod:`.study`), each trial's Monte
Carlo runs are a sweep's task on a local pool or a Dask cluster, its rows a Parquet file; the
objective (:mod:`.objective`) is read from the runs' figures; the search space (:mod:`.space`)
tunes a noise as what the estimators assume, so the data stay fixed. The report (:mod:`.report`):
``best.toml``, ``summary.md``, PNGs and ``study.rrd``.
"""
